// Residency policy driven by seeded random frames and a fake producer that completes some
// requests at once, some frames later and fails some. Every frame checks the
// invariants of docs/virtual-texture.md: lookups only ever name resident pages' slots, pinned pages and
// this frame's working set are never evicted, no slot is handed out twice, and the page
// table equals the brute-force reference built from the resident set.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <set>

#include "support/page_table_reference.h"
#include "vt/residency.h"

using namespace tvt;
using tvt::test::ReferenceTable;

namespace {

VtConfig make_config(uint32_t log2_size) {
  VtConfig c;
  c.log2_size = log2_size;
  return c;
}

PageId page_at(const VtConfig& c, uint32_t x, uint32_t y, uint32_t mip) {
  return PageId{mip, x >> (c.log2_page() + mip), y >> (c.log2_page() + mip)};
}

// Completes each request now (50%), 1-3 frames later (35%) or fails it, now or later (15%).
struct FakeProducer {
  struct Job {
    PageId page;
    uint64_t due;
    bool fail;
  };
  std::mt19937 rng;
  std::vector<Job> jobs;

  void produce(const std::vector<PageRequest>& batch, uint64_t frame) {
    for (const PageRequest& r : batch) {
      const uint32_t roll = uint32_t(rng() % 100);
      const uint64_t delay = roll < 50 ? 0 : 1 + rng() % 3;
      jobs.push_back(Job{r.page, frame + delay, roll >= 85});
    }
  }
  void deliver(Residency& res, uint64_t frame) {
    std::vector<Job> later;
    for (const Job& j : jobs) {
      if (j.due > frame) {
        later.push_back(j);
      } else if (j.fail) {
        res.failed(j.page);
      } else {
        res.complete(j.page);
      }
    }
    jobs.swap(later);
  }
};

std::set<PageId> working_set(const VtConfig& c, const std::vector<PageFeedback>& fb, uint32_t pinned_mips) {
  std::set<PageId> out;
  for (const PageFeedback& f : fb)
    for (PageId p = f.page;; p = p.parent()) {
      out.insert(p);
      if (p.mip + 1 >= c.mip_count()) break;
    }
  for (uint32_t m = c.mip_count() - pinned_mips; m < c.mip_count(); ++m)
    for (uint32_t y = 0; y < c.pages_per_side(m); ++y)
      for (uint32_t x = 0; x < c.pages_per_side(m); ++x) out.insert(PageId{m, x, y});
  return out;
}

struct InvariantParams {
  uint32_t log2_size;
  uint32_t window;
  uint32_t slots;
  uint32_t pinned_mips;
  int seeds;
  int frames;
  int reference_every;  // compare with the reference model every n-th frame
};

void run_invariants(const InvariantParams& ip) {
  const VtConfig config = make_config(ip.log2_size);
  const uint32_t v = uint32_t(config.size_texels());
  uint64_t total_evicted = 0, total_failed = 0, total_produced = 0;
  for (int seed = 0; seed < ip.seeds; ++seed) {
    std::mt19937 rng(uint32_t(seed * 1000003 + int(ip.log2_size)));
    ResidencyOptions o;
    o.slot_count = ip.slots;
    o.pinned_mips = ip.pinned_mips;
    o.window_pages = ip.window;
    o.max_requests_per_frame = 1 + uint32_t(rng() % 24);
    o.retry_after_frames = uint32_t(rng() % 5);
    ASSERT_TRUE(Residency::validate(config, o, "t").ok());
    Residency res(config, o);
    FakeProducer producer{std::mt19937(uint32_t(seed)), {}};
    uint32_t cx = uint32_t(rng() % v), cy = uint32_t(rng() % v);
    std::set<PageId> pinned_seen_resident;
    for (uint64_t frame = 1; frame <= uint64_t(ip.frames); ++frame) {
      // Camera: walks, sometimes cuts.
      const int64_t step = int64_t(config.page_texels) * 3;
      auto move = [&](uint32_t c) {
        if (rng() % 40 == 0) return uint32_t(rng() % v);
        const int64_t n = int64_t(c) + std::uniform_int_distribution<int64_t>(-step, step)(rng);
        return uint32_t(std::clamp<int64_t>(n, 0, int64_t(v) - 1));
      };
      cx = move(cx);
      cy = move(cy);
      res.set_centre(cx, cy);
      // Feedback: pages around the camera, finer near it, biased by the residency's mip bias.
      std::vector<PageFeedback> fb;
      const int count = int(rng() % 40);
      for (int i = 0; i < count; ++i) {
        const int64_t r = int64_t(config.page_texels) * int64_t(1 + rng() % 8);
        const uint32_t x = uint32_t(std::clamp<int64_t>(int64_t(cx) + int64_t(rng() % (2 * r)) - r, 0, v - 1));
        const uint32_t y = uint32_t(std::clamp<int64_t>(int64_t(cy) + int64_t(rng() % (2 * r)) - r, 0, v - 1));
        const uint32_t mip = std::min(config.mip_count() - 1, uint32_t(rng() % 4) + res.mip_bias());
        fb.push_back(PageFeedback{page_at(config, x, y, mip), 1 + uint32_t(rng() % 500)});
      }
      if (rng() % 10 == 0) fb.push_back(PageFeedback{PageId{0, v, 0}, 3});  // garbage id: ignored
      const std::set<PageId> needed = working_set(config, fb, ip.pinned_mips);
      std::set<PageId> protected_pages;
      for (const PageRequest& r : res.resident_pages())
        if (needed.contains(r.page)) protected_pages.insert(r.page);

      res.begin_frame(frame, fb);
      std::vector<PageRequest> batch;
      while (auto r = res.next_request()) {
        ASSERT_TRUE(needed.contains(r->page)) << "requested a page outside the working set";
        ASSERT_FALSE(res.page_table().is_mapped(r->page));
        batch.push_back(*r);
      }
      ASSERT_LE(batch.size(), o.max_requests_per_frame);
      for (size_t i = 1; i < batch.size(); ++i) ASSERT_GE(batch[i - 1].page.mip, batch[i].page.mip);
      for (const PageId& p : protected_pages)
        ASSERT_TRUE(res.is_resident(p)) << "evicted " << to_string(p) << " needed this frame";
      producer.produce(batch, frame);
      producer.deliver(res, frame);

      // Slots: one page per slot, all allocated, counts agree.
      const auto resident = res.resident_pages();
      const auto in_flight = res.in_flight_pages();
      std::map<uint32_t, PageId> by_slot;
      for (const auto* list : {&resident, &in_flight})
        for (const PageRequest& r : *list) {
          ASSERT_TRUE(by_slot.emplace(r.slot, r.page).second) << "slot " << r.slot << " shared";
          ASSERT_TRUE(res.slots().is_allocated(r.slot));
        }
      ASSERT_EQ(res.slots().allocated_count(), by_slot.size());
      const ResidencyStats& st = res.stats();
      ASSERT_EQ(st.resident, resident.size());
      ASSERT_EQ(st.in_flight, in_flight.size());
      ASSERT_LE(st.resident + st.in_flight, ip.slots);
      total_evicted += st.evicted;
      total_failed += st.failed;
      total_produced += st.produced;

      // Pinned pages, once resident, stay resident.
      for (const PageId& p : pinned_seen_resident) ASSERT_TRUE(res.is_resident(p)) << to_string(p);
      for (const PageRequest& r : resident)
        if (res.is_pinned(r.page)) pinned_seen_resident.insert(r.page);

      // Every valid entry names a resident page's slot at the mip it claims; once the top
      // page is resident every entry is valid.
      const bool top = res.is_resident(PageId{config.mip_count() - 1, 0, 0});
      std::set<uint32_t> resident_slots;
      for (const PageRequest& r : resident) resident_slots.insert(r.slot);
      for (uint32_t e : res.page_table().all_entries()) {
        if (!entry_valid(e)) {
          ASSERT_FALSE(top) << "invalid entry while the top page is resident";
          continue;
        }
        ASSERT_TRUE(resident_slots.contains(entry_slot(e))) << "entry names a non-resident slot";
        ASSERT_EQ(by_slot.at(entry_slot(e)).mip, entry_mip(e));
      }
      for (int i = 0; i < 8; ++i) {
        const uint32_t e = res.page_table().lookup(uint32_t(rng() % v), uint32_t(rng() % v),
                                                   uint32_t(rng() % config.mip_count()));
        if (top) {
          ASSERT_TRUE(entry_valid(e) && resident_slots.contains(entry_slot(e)));
        }
      }

      if (frame % uint64_t(ip.reference_every) == 0) {
        ReferenceTable ref{config, ip.window, {}, cx, cy};
        for (const PageRequest& r : resident) ref.mapped[r.page] = r.slot;
        for (uint32_t m = 0; m < config.mip_count(); ++m) {
          const auto want = ref.expected_mip(m);
          const auto got = res.page_table().entries(m);
          ASSERT_TRUE(std::equal(want.begin(), want.end(), got.begin(), got.end())) << "mip " << m;
        }
      }
      if (ip.log2_size == 24) {
        ASSERT_LT(res.page_table().memory_bytes(), size_t(8) << 20);
      }
    }
  }
  // The streams must exercise the paths they check.
  EXPECT_GT(total_evicted, 0u);
  EXPECT_GT(total_failed, 0u);
  EXPECT_GT(total_produced, total_evicted);
}

}  // namespace

TEST(Residency, ValidateNamesTheField) {
  const VtConfig c = make_config(16);
  ResidencyOptions o;
  o.slot_count = 4;
  o.pinned_mips = 2;  // 5 pages
  auto s = Residency::validate(c, o, "scene.json: /vt/cache");
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("scene.json: /vt/cache/pinned_mips"), std::string::npos);
  o = ResidencyOptions{};
  o.window_pages = 100;
  EXPECT_NE(Residency::validate(c, o, "x").error().message.find("/window_pages"), std::string::npos);
  EXPECT_TRUE(Residency::validate(c, ResidencyOptions{}, "x").ok());
}

TEST(Residency, FinePageRequestsItsAncestorsCoarseFirst) {
  const VtConfig c = make_config(16);  // 10 mips
  ResidencyOptions o;
  o.slot_count = 64;
  Residency res(c, o);
  res.set_centre(300 * 128, 77 * 128);  // the camera is over the page, so mip 0 has its entry
  const PageId fine{0, 300, 77};
  const std::vector<PageFeedback> fb{{fine, 10}};
  res.begin_frame(1, fb);
  const auto batch = res.take_requests();
  ASSERT_EQ(batch.size(), c.mip_count());
  PageId want = fine;
  for (uint32_t m = 0; m < c.mip_count(); ++m, want = m < c.mip_count() ? want.parent() : want)
    EXPECT_EQ(batch[c.mip_count() - 1 - m].page, want) << "mip " << m;
  for (const PageRequest& r : batch) EXPECT_TRUE(res.is_in_flight(r.page));
  // Entries fall back while in flight, then sharpen as pages arrive, coarse to fine.
  for (const PageRequest& r : batch) res.complete(r.page);
  const uint32_t e = res.page_table().lookup(300 * 128 + 5, 77 * 128, 0);
  EXPECT_EQ(e, pack_entry(batch.back().slot, 0));
  EXPECT_EQ(res.stats().produced, c.mip_count());
}

TEST(Residency, PriorityIsCoverageThenAgeAndTheBudgetHolds) {
  const VtConfig c = make_config(12);  // 6 mips, 32 pages per side at mip 0
  ResidencyOptions o;
  o.slot_count = 400;
  o.pinned_mips = 5;  // mips 1..5 pinned: only mip-0 pages are ever missing after warm-up
  o.max_requests_per_frame = 2;
  Residency res(c, o);
  uint64_t frame = 1;
  for (; res.stats().resident < res.pinned_page_count(); ++frame) {
    res.begin_frame(frame, {});
    for (const PageRequest& r : res.take_requests()) res.complete(r.page);
    ASSERT_LT(frame, 1000u);
  }
  EXPECT_EQ(res.stats().resident, 1u + 4 + 16 + 64 + 256);
  // Frame A: three pages; the budget of 2 takes the two largest.
  const std::vector<PageFeedback> a{{{0, 1, 1}, 5}, {{0, 2, 2}, 50}, {{0, 3, 3}, 20}};
  res.begin_frame(frame++, a);
  auto batch = res.take_requests();
  ASSERT_EQ(batch.size(), 2u);
  EXPECT_EQ(batch[0].page, (PageId{0, 2, 2}));
  EXPECT_EQ(batch[1].page, (PageId{0, 3, 3}));
  EXPECT_FALSE(res.next_request().has_value());
  // Frame B: (1,1) has waited a frame; a new page with the same coverage comes after it.
  const std::vector<PageFeedback> b{{{0, 9, 9}, 5}, {{0, 1, 1}, 5}, {{0, 8, 8}, 1}};
  res.begin_frame(frame++, b);
  batch = res.take_requests();
  ASSERT_EQ(batch.size(), 2u);
  EXPECT_EQ(batch[0].page, (PageId{0, 1, 1}));
  EXPECT_EQ(batch[1].page, (PageId{0, 9, 9}));
}

TEST(Residency, FailedPageFallsBackAndIsRetriedLater) {
  const VtConfig c = make_config(12);
  ResidencyOptions o;
  o.slot_count = 16;
  o.retry_after_frames = 3;
  Residency res(c, o);
  const std::vector<PageFeedback> fb{{{4, 1, 1}, 9}};
  res.begin_frame(1, fb);
  auto batch = res.take_requests();
  ASSERT_EQ(batch.size(), 2u);  // top (pinned), then (4,1,1)
  res.complete(batch[0].page);
  const uint32_t failed_slot = batch[1].slot;
  res.failed(batch[1].page);
  EXPECT_FALSE(res.slots().is_allocated(failed_slot));
  EXPECT_EQ(res.page_table().lookup(3000, 3000, 4), pack_entry(batch[0].slot, 5));
  for (uint64_t f = 2; f < 4; ++f) {
    res.begin_frame(f, fb);
    EXPECT_TRUE(res.take_requests().empty()) << "frame " << f;
  }
  res.begin_frame(4, fb);
  batch = res.take_requests();
  ASSERT_EQ(batch.size(), 1u);
  EXPECT_EQ(batch[0].page, (PageId{4, 1, 1}));
}

TEST(Residency, CancelledPageIsFreedAndRequeuedWithoutBackOff) {
  const VtConfig c = make_config(12);
  ResidencyOptions o;
  o.slot_count = 16;
  o.retry_after_frames = 30;
  Residency res(c, o);
  const std::vector<PageFeedback> fb{{{4, 1, 1}, 9}};
  res.begin_frame(1, fb);
  auto batch = res.take_requests();
  ASSERT_EQ(batch.size(), 2u);
  res.complete(batch[0].page);
  const uint32_t slot = batch[1].slot;
  EXPECT_TRUE(res.stale_in_flight(0).empty());  // seen this frame
  // The camera moves away: the page stays in flight but goes stale.
  res.begin_frame(2, {});
  res.begin_frame(3, {});
  EXPECT_TRUE(res.stale_in_flight(2).empty());
  EXPECT_EQ(res.stale_in_flight(1), std::vector<PageId>{batch[1].page});
  res.cancelled(batch[1].page);
  EXPECT_EQ(res.stats().cancelled, 1u);
  EXPECT_FALSE(res.slots().is_allocated(slot));
  EXPECT_FALSE(res.is_in_flight(batch[1].page));
  EXPECT_EQ(res.page_table().lookup(3000, 3000, 4), pack_entry(batch[0].slot, 5));
  res.begin_frame(4, fb);  // wanted again: queued at once, unlike a failed page
  batch = res.take_requests();
  ASSERT_EQ(batch.size(), 1u);
  EXPECT_EQ(batch[0].page, (PageId{4, 1, 1}));
}

TEST(Residency, OversubscriptionRaisesBiasFinishesAndRecovers) {
  const VtConfig c = make_config(16);  // 512 pages per side at mip 0
  ResidencyOptions o;
  o.slot_count = 64;
  o.max_requests_per_frame = 16;
  Residency res(c, o);
  // The renderer: wants a block of mip-0 pages; with bias b it samples their mip-b ancestors.
  auto feedback_for = [&](uint32_t side) {
    std::map<PageId, uint32_t> pages;
    for (uint32_t y = 0; y < side; ++y)
      for (uint32_t x = 0; x < side; ++x) {
        PageId p{0, 100 + x, 100 + y};
        for (uint32_t b = 0; b < res.mip_bias(); ++b) p = p.parent();
        pages[p] += 100;
      }
    std::vector<PageFeedback> fb;
    for (const auto& [p, n] : pages) fb.push_back(PageFeedback{p, n});
    return fb;
  };
  res.set_centre(100 * 128, 100 * 128);
  uint64_t frame = 1;
  bool saw_oversubscribed = false;
  uint32_t peak_bias = 0;
  int quiet = 0;
  // 16 x 16 = 256 mip-0 pages (+ ancestors): four times the cache.
  for (; frame < 200 && quiet < 30; ++frame) {
    res.begin_frame(frame, feedback_for(16));
    for (const PageRequest& r : res.take_requests()) res.complete(r.page);
    saw_oversubscribed |= res.stats().oversubscribed;
    peak_bias = std::max(peak_bias, res.mip_bias());
    quiet = res.stats().oversubscribed || res.stats().requested > 0 ? 0 : quiet + 1;
  }
  EXPECT_TRUE(saw_oversubscribed);
  EXPECT_LT(frame, 200u) << "never settled";
  EXPECT_GE(peak_bias, 1u);
  EXPECT_LE(peak_bias, 3u);
  const uint32_t settled_bias = res.mip_bias();
  EXPECT_GE(settled_bias, 1u);
  for (const PageFeedback& f : feedback_for(16)) EXPECT_TRUE(res.is_resident(f.page)) << to_string(f.page);
  // Pressure gone: a 2 x 2 block. The bias steps back down to 0 and the pages become resident.
  const uint64_t calm_start = frame;
  // Done when two frames in a row at bias 0 needed nothing new (the feedback of the frame
  // that lowered the bias was still taken at the old bias).
  for (int done = 0; frame < calm_start + 100 && done < 2; ++frame) {
    res.begin_frame(frame, feedback_for(2));
    for (const PageRequest& r : res.take_requests()) res.complete(r.page);
    EXPECT_FALSE(res.stats().oversubscribed);
    done = res.mip_bias() == 0 && res.stats().requested == 0 ? done + 1 : 0;
  }
  EXPECT_EQ(res.mip_bias(), 0u);
  EXPECT_LT(frame, calm_start + 100);
  for (uint32_t y = 0; y < 2; ++y)
    for (uint32_t x = 0; x < 2; ++x) EXPECT_TRUE(res.is_resident(PageId{0, 100 + x, 100 + y}));
}

TEST(Residency, CacheFullOfThisFramesPagesStopsWithoutEvicting) {
  const VtConfig c = make_config(16);
  ResidencyOptions o;
  o.slot_count = 8;
  o.max_requests_per_frame = 100;
  o.max_mip_bias = 0;  // cannot degrade: the frame must still finish
  Residency res(c, o);
  std::vector<PageFeedback> fb;
  for (uint32_t i = 0; i < 20; ++i) fb.push_back(PageFeedback{PageId{0, 2 * i, 0}, 1});
  for (uint64_t frame = 1; frame <= 5; ++frame) {
    res.begin_frame(frame, fb);
    for (const PageRequest& r : res.take_requests()) res.complete(r.page);
    EXPECT_TRUE(res.stats().oversubscribed);
    EXPECT_EQ(res.stats().evicted, 0u) << "every resident page is needed this frame";
    EXPECT_EQ(res.slots().free_count(), 0u);
  }
}

TEST(Residency, RandomFramesKeepInvariants_V2to10) { run_invariants({10, 8, 12, 1, 60, 120, 1}); }
TEST(Residency, RandomFramesKeepInvariants_V2to16) {
  run_invariants({16, 8, 40, 2, 40, 150, 1});
  run_invariants({16, 32, 200, 1, 20, 150, 3});
}
TEST(Residency, RandomFramesKeepInvariants_V2to24) {
  run_invariants({24, 8, 64, 2, 20, 150, 1});
  run_invariants({24, 32, 300, 3, 8, 150, 10});
}
