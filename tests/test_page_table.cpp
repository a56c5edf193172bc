// PageTable against a brute-force reference model (integer tables match bit for
// bit): after every map / unmap / set_centre of thousands of seeded random streams, every
// entry of every mip equals what the reference derives from first principles, and a GPU
// mirror fed only with take_updates() equals the table.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>

#include "support/page_table_reference.h"
#include "vt/page_table.h"

using namespace tvt;
using tvt::test::ReferenceTable;

namespace {

VtConfig make_config(uint32_t log2_size) {
  VtConfig c;
  c.log2_size = log2_size;
  return c;  // P = 128, B = 4
}

void expect_equal_to_reference(const PageTable& table, const ReferenceTable& ref, const char* what) {
  for (uint32_t m = 0; m < table.mip_count(); ++m) {
    const auto got = table.entries(m);
    const auto want = ref.expected_mip(m);
    ASSERT_EQ(got.size(), want.size()) << what << " mip " << m;
    for (size_t i = 0; i < want.size(); ++i)
      ASSERT_EQ(got[i], want[i]) << what << " mip " << m << " index " << i;
    EXPECT_EQ(table.window(m).origin_x, ref.origin(m, ref.centre_x)) << what << " mip " << m;
    EXPECT_EQ(table.window(m).origin_y, ref.origin(m, ref.centre_y)) << what << " mip " << m;
  }
}

// A page near the window of its mip (so that streams exercise entries), sometimes anywhere.
PageId random_page(std::mt19937& rng, const VtConfig& c, const ReferenceTable& ref) {
  const uint32_t mip = std::uniform_int_distribution<uint32_t>(0, c.mip_count() - 1)(rng);
  const uint64_t pages = c.pages_per_side(mip);
  auto coord = [&](uint32_t centre) -> uint32_t {
    if (rng() % 8 == 0) return uint32_t(std::uniform_int_distribution<uint64_t>(0, pages - 1)(rng));
    const int64_t cp = int64_t(centre >> (c.log2_page() + mip));
    const int64_t span = int64_t(ref.w);
    const int64_t v = cp + std::uniform_int_distribution<int64_t>(-span, span)(rng);
    return uint32_t(std::clamp<int64_t>(v, 0, int64_t(pages) - 1));
  };
  return PageId{mip, coord(ref.centre_x), coord(ref.centre_y)};
}

struct StreamParams {
  uint32_t log2_size;
  uint32_t window;
  int streams;
  int ops;
};

void run_random_streams(const StreamParams& sp) {
  const VtConfig config = make_config(sp.log2_size);
  const uint32_t v = uint32_t(config.size_texels());
  for (int stream = 0; stream < sp.streams; ++stream) {
    std::mt19937 rng(uint32_t(stream * 7919 + int(sp.log2_size) * 131 + int(sp.window)));
    PageTable table(config, PageTableOptions{sp.window});
    ReferenceTable ref{config, sp.window, {}, 0, 0};
    std::vector<uint32_t> gpu(table.all_entries().size(), 0u);  // mirror fed by updates only
    uint32_t next_slot = 0;
    for (int op = 0; op < sp.ops; ++op) {
      const uint32_t kind = uint32_t(rng() % 100);
      if (kind < 45) {
        const PageId p = random_page(rng, config, ref);
        if (ref.mapped.contains(p)) continue;
        const uint32_t slot = (next_slot++ * 2654435761u) & kEntrySlotMask;
        table.map(p, slot);
        ref.mapped[p] = slot;
      } else if (kind < 75) {
        if (ref.mapped.empty()) continue;
        auto it = ref.mapped.begin();
        std::advance(it, rng() % ref.mapped.size());
        table.unmap(it->first);
        ref.mapped.erase(it);
      } else {
        // Mostly walking steps of up to two mip-0 pages, sometimes a camera cut.
        const bool cut = rng() % 6 == 0;
        const int64_t step = int64_t(config.page_texels) * 2;
        auto move = [&](uint32_t cur) -> uint32_t {
          if (cut) return uint32_t(std::uniform_int_distribution<uint64_t>(0, v - 1)(rng));
          const int64_t n = int64_t(cur) + std::uniform_int_distribution<int64_t>(-step, step)(rng);
          return uint32_t(std::clamp<int64_t>(n, 0, int64_t(v) - 1));
        };
        ref.centre_x = move(ref.centre_x);
        ref.centre_y = move(ref.centre_y);
        table.set_centre(ref.centre_x, ref.centre_y);
      }
      ASSERT_NO_FATAL_FAILURE(expect_equal_to_reference(table, ref, "after op"));
      ASSERT_EQ(table.mapped_count(), ref.mapped.size());
      // Dirty tracking: one update per changed entry, and applying them reproduces the table.
      if (rng() % 3 == 0 || op + 1 == sp.ops) {
        const auto updates = table.take_updates();
        std::vector<uint8_t> seen(gpu.size(), 0);
        for (const PageTableUpdate& u : updates) {
          const uint32_t flat = table.window(u.mip).offset + u.index;
          ASSERT_EQ(seen[flat], 0) << "duplicate update";
          seen[flat] = 1;
          gpu[flat] = u.value;
        }
        ASSERT_EQ(table.pending_update_count(), 0u);
        ASSERT_TRUE(std::equal(gpu.begin(), gpu.end(), table.all_entries().begin()));
      }
      // Random GPU-style lookups and resolves against brute force.
      for (int i = 0; i < 4; ++i) {
        const uint32_t x = uint32_t(rng() % v), y = uint32_t(rng() % v);
        const uint32_t mip = uint32_t(rng() % config.mip_count());
        ASSERT_EQ(table.lookup(x, y, mip), ref.expected_lookup(x, y, mip));
        const PageId p{mip, x >> (config.log2_page() + mip), y >> (config.log2_page() + mip)};
        const auto r = table.resolve(p);
        const uint32_t want = ref.expected_entry(p);
        ASSERT_EQ(r.has_value(), entry_valid(want));
        if (r) {
          ASSERT_EQ(pack_entry(r->slot, r->data_mip), want);
        }
      }
    }
  }
}

}  // namespace

TEST(PageTable, EntryLayoutIsSlotLow20MipNext5ValidTop) {
  constexpr uint32_t e = pack_entry(0xabcde, 17);
  static_assert(e == (0x80000000u | (17u << 20) | 0xabcdeu));
  static_assert(entry_valid(e) && entry_slot(e) == 0xabcde && entry_mip(e) == 17);
  static_assert(!entry_valid(0u));
  static_assert(pack_entry(kMaxSlots - 1, 31) == 0x81ffffffu);
}

TEST(PageTable, MapRepointsDescendantsUnmapFallsBackToNextAncestor) {
  const VtConfig c = make_config(12);  // 32 pages per side at mip 0, 6 mips
  PageTable t(c, PageTableOptions{8});
  EXPECT_EQ(t.lookup(0, 0, 0), 0u);  // nothing mapped: invalid
  t.map(PageId{5, 0, 0}, 7);         // top page
  for (uint32_t m = 0; m < t.mip_count(); ++m)
    for (uint32_t e : t.entries(m)) EXPECT_EQ(e, pack_entry(7, 5));
  t.map(PageId{0, 1, 1}, 3);
  t.map(PageId{2, 0, 0}, 9);  // ancestor of (0,1,1) at mip 2
  EXPECT_EQ(t.lookup(128, 128, 0), pack_entry(3, 0));      // the page itself
  EXPECT_EQ(t.lookup(0, 0, 0), pack_entry(9, 2));          // sibling: mip-2 ancestor
  EXPECT_EQ(t.lookup(0, 0, 1), pack_entry(9, 2));
  EXPECT_EQ(t.lookup(4095, 4095, 0), pack_entry(7, 5));    // far corner: top page
  t.unmap(PageId{2, 0, 0});
  EXPECT_EQ(t.lookup(0, 0, 0), pack_entry(7, 5));
  EXPECT_EQ(t.lookup(128, 128, 0), pack_entry(3, 0));      // finer data is untouched
  EXPECT_EQ(t.resolve(PageId{1, 0, 0}), (ResolvedPage{7, 5}));
  t.unmap(PageId{5, 0, 0});
  EXPECT_EQ(t.lookup(0, 0, 0), 0u);
  EXPECT_EQ(t.lookup(128, 128, 0), pack_entry(3, 0));
}

TEST(PageTable, LookupOutsideTheWindowUsesTheFirstCoarserMipThatCoversIt) {
  const VtConfig c = make_config(16);  // 512 pages per side at mip 0
  PageTable t(c, PageTableOptions{8});
  t.map(PageId{9, 0, 0}, 1);
  t.map(PageId{0, 500, 500}, 2);  // resident, but far outside the mip-0 window at (0, 0)
  EXPECT_FALSE(t.in_window(PageId{0, 500, 500}));
  EXPECT_EQ(t.lookup(500 * 128, 500 * 128, 0), pack_entry(1, 9));
  t.set_centre(500 * 128, 500 * 128);  // the window moves over it: now visible
  EXPECT_TRUE(t.in_window(PageId{0, 500, 500}));
  EXPECT_EQ(t.lookup(500 * 128 + 5, 500 * 128 + 7, 0), pack_entry(2, 0));
  EXPECT_EQ(t.window(0).origin_x, 500u - 4u);  // centre page minus W/2
  t.set_centre(65535, 65535);
  EXPECT_EQ(t.window(0).origin_x, 512u - 8u);  // clamped to the terrain edge
  EXPECT_EQ(t.lookup(500 * 128, 500 * 128, 0), pack_entry(1, 9));
}

TEST(PageTable, MemoryIsBoundedByTheWindowNotByV) {
  const uint32_t w = 128;
  size_t previous = 0;
  for (uint32_t k : {20u, 24u, 30u}) {
    const VtConfig c = make_config(k);
    PageTable t(c, PageTableOptions{w});
    const size_t bytes = t.memory_bytes();
    EXPECT_LE(bytes, size_t(w) * w * 4 * c.mip_count()) << "V = 2^" << k;
    // Each doubling of V adds one windowed mip: W^2 * 4 bytes, nothing proportional to V.
    if (previous) {
      EXPECT_EQ(bytes - previous, size_t(w) * w * 4 * (k == 24 ? 4 : 6)) << k;
    }
    previous = bytes;
    if (k == 24) {
      EXPECT_EQ(c.mip_count(), 18u);
      EXPECT_LT(bytes, size_t(8) << 20);
      EXPECT_LT(t.host_memory_bytes(), size_t(8) << 20);
    }
  }
}

TEST(PageTable, RandomStreamsMatchReference_V2to10) {
  run_random_streams({10, 8, 600, 40});
  run_random_streams({10, 32, 300, 40});
}

TEST(PageTable, RandomStreamsMatchReference_V2to16) {
  run_random_streams({16, 8, 600, 40});
  run_random_streams({16, 32, 200, 40});
}

TEST(PageTable, RandomStreamsMatchReference_V2to24) {
  run_random_streams({24, 8, 600, 40});
  run_random_streams({24, 32, 120, 30});
}
