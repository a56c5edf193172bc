#include "vt/residency.h"

#include <algorithm>
#include <bit>

namespace tvt {
namespace {

// Pages of the `pinned_mips` coarsest mips: 1 + 4 + 16 + ... = (4^k - 1) / 3.
uint64_t pinned_pages(uint32_t pinned_mips) { return ((uint64_t(1) << (2 * pinned_mips)) - 1) / 3; }

}  // namespace

Status Residency::validate(const VtConfig& config, const ResidencyOptions& o, const std::string& where) {
  if (auto s = tvt::validate(config, where + "/vt"); !s.ok()) return s;
  const uint32_t mips = config.mip_count();
  if (o.slot_count < 2 || o.slot_count > kMaxSlots)
    return make_error(where + "/slot_count: must be between 2 and " + std::to_string(kMaxSlots) + ", got " +
                      std::to_string(o.slot_count));
  if (o.pinned_mips < 1 || o.pinned_mips > mips)
    return make_error(where + "/pinned_mips: must be between 1 and the mip count " + std::to_string(mips) +
                      ", got " + std::to_string(o.pinned_mips));
  if (o.pinned_mips > 15 || pinned_pages(o.pinned_mips) >= o.slot_count)
    return make_error(where + "/pinned_mips: the " + std::to_string(o.pinned_mips) +
                      " coarsest mips do not leave a free slot in a cache of " + std::to_string(o.slot_count));
  if (!std::has_single_bit(o.window_pages) || o.window_pages < 4 || o.window_pages > 4096)
    return make_error(where + "/window_pages: must be a power of two between 4 and 4096, got " +
                      std::to_string(o.window_pages));
  if (o.max_requests_per_frame < 1) return make_error(where + "/max_requests_per_frame: must be at least 1");
  if (o.bias_settle_frames < 1) return make_error(where + "/bias_settle_frames: must be at least 1");
  if (!(o.lower_bias_below >= 0.0 && o.lower_bias_below < o.raise_bias_above))
    return make_error(where + "/lower_bias_below: must be >= 0 and below raise_bias_above");
  if (o.max_mip_bias >= mips)
    return make_error(where + "/max_mip_bias: must be below the mip count " + std::to_string(mips));
  return Ok{};
}

Residency::Residency(const VtConfig& config, const ResidencyOptions& options)
    : config_(config),
      options_(options),
      mip_count_(config.mip_count()),
      table_(config, PageTableOptions{options.window_pages}),
      slots_(options.slot_count) {
  TVT_CHECK(validate(config, options, "Residency").ok());
  pinned_count_ = uint32_t(pinned_pages(options.pinned_mips));
  max_bias_ = options.max_mip_bias ? options.max_mip_bias : mip_count_ - 1;
}

bool Residency::is_resident(const PageId& page) const {
  const auto it = pages_.find(page.pack());
  return it != pages_.end() && it->second.state == State::resident;
}

bool Residency::is_in_flight(const PageId& page) const {
  const auto it = pages_.find(page.pack());
  return it != pages_.end() && it->second.state == State::in_flight;
}

void Residency::begin_frame(uint64_t frame, std::span<const PageFeedback> feedback) {
  TVT_CHECK(!started_ || frame > frame_);
  started_ = true;
  frame_ = frame;
  const ResidencyStats previous = stats_;
  stats_ = ResidencyStats{};
  stats_.frame = frame;
  stats_.mip_bias = previous.mip_bias;

  // Working set: feedback pages and all their ancestors, with the pixels of the page and of
  // all its descendants in the feedback (an ancestor serves every one of them).
  std::unordered_map<uint64_t, uint64_t> needed;  // page -> coverage in feedback pixels
  needed.reserve(feedback.size() * 2 + pinned_count_);
  for (const PageFeedback& f : feedback) {
    if (!is_valid(config_, f.page)) {
      ++stats_.invalid_feedback;
      continue;
    }
    for (PageId p = f.page;; p = p.parent()) {
      needed[p.pack()] += f.pixels;
      if (p.mip + 1 >= mip_count_) break;
    }
  }
  for (uint32_t m = mip_count_ - options_.pinned_mips; m < mip_count_; ++m) {
    const uint32_t n = uint32_t(config_.pages_per_side(m));
    for (uint32_t y = 0; y < n; ++y)
      for (uint32_t x = 0; x < n; ++x) needed.try_emplace(PageId{m, x, y}.pack(), 0);
  }
  stats_.working_set = uint32_t(needed.size());

  // Touch what is resident or in flight; queue what is missing.
  std::erase_if(retry_at_, [&](const auto& kv) { return kv.second <= frame; });
  std::unordered_map<uint64_t, uint64_t> waiting;
  queue_.clear();
  cursor_ = 0;
  for (const auto& [key, pixels] : needed) {
    const PageId page = PageId::unpack(key);
    if (const auto it = pages_.find(key); it != pages_.end()) {
      Record& r = it->second;
      r.last_seen = frame;
      if (r.state == State::resident && !is_pinned(page)) lru_.splice(lru_.end(), lru_, r.lru);
      continue;
    }
    if (retry_at_.contains(key)) continue;
    const auto w = waiting_since_.find(key);
    const uint64_t since = w == waiting_since_.end() ? frame : w->second;
    waiting.emplace(key, since);
    queue_.push_back(Candidate{page, pixels, frame - since});
  }
  waiting_since_.swap(waiting);  // pages no longer needed stop ageing
  std::sort(queue_.begin(), queue_.end(), [](const Candidate& a, const Candidate& b) {
    if (a.page.mip != b.page.mip) return a.page.mip > b.page.mip;  // coarse first
    if (a.pixels != b.pixels) return a.pixels > b.pixels;
    if (a.age != b.age) return a.age > b.age;
    return a.page.pack() < b.page.pack();
  });
  stats_.requested = uint32_t(queue_.size());
  update_bias(stats_.working_set);
}

void Residency::update_bias(uint32_t working_set) {
  // Pinned pages are a fixed reservation: compare the rest with the rest of the cache.
  const double unpinned_needed = double(working_set - std::min(working_set, pinned_count_));
  const double ratio = unpinned_needed / double(options_.slot_count - pinned_count_);
  stats_.oversubscribed = ratio > options_.raise_bias_above;
  if (frames_since_bias_change_ < UINT32_MAX) ++frames_since_bias_change_;
  const bool settled = frames_since_bias_change_ >= options_.bias_settle_frames;
  if (stats_.oversubscribed) {
    calm_ = 0;
    if (settled && bias_ < max_bias_) {
      ++bias_;
      frames_since_bias_change_ = 0;
    }
  } else if (ratio < options_.lower_bias_below) {
    ++calm_;
    if (settled && calm_ >= options_.calm_frames && bias_ > 0) {
      --bias_;
      frames_since_bias_change_ = 0;
      calm_ = 0;
    }
  } else {
    calm_ = 0;
  }
  stats_.mip_bias = bias_;
}

std::optional<uint32_t> Residency::evict_least_recent() {
  // lru_ is ordered by last_seen (every touch and every insertion uses the current frame),
  // so if the front was seen this frame, every unpinned resident page was.
  if (lru_.empty()) return std::nullopt;
  const uint64_t key = lru_.front();
  const auto it = pages_.find(key);
  TVT_CHECK(it != pages_.end() && it->second.state == State::resident);
  if (it->second.last_seen >= frame_) return std::nullopt;
  const uint32_t slot = it->second.slot;
  table_.unmap(PageId::unpack(key));
  lru_.pop_front();
  pages_.erase(it);
  ++stats_.evicted;
  return slot;  // stays allocated: handed straight to the next page
}

std::optional<PageRequest> Residency::next_request() {
  TVT_CHECK(started_);
  if (cursor_ >= queue_.size() || stats_.issued >= options_.max_requests_per_frame) return std::nullopt;
  std::optional<uint32_t> slot = slots_.allocate();
  if (!slot) slot = evict_least_recent();
  if (!slot) return std::nullopt;  // everything resident is needed this frame or pinned
  const PageId page = queue_[cursor_++].page;
  const uint64_t key = page.pack();
  waiting_since_.erase(key);
  const bool inserted = pages_.emplace(key, Record{*slot, State::in_flight, frame_, {}}).second;
  TVT_CHECK(inserted);
  ++stats_.issued;
  return PageRequest{page, *slot};
}

std::vector<PageRequest> Residency::take_requests(uint32_t max) {
  std::vector<PageRequest> out;
  while (out.size() < max) {
    auto r = next_request();
    if (!r) break;
    out.push_back(*r);
  }
  return out;
}

void Residency::complete(const PageId& page) {
  const auto it = pages_.find(page.pack());
  TVT_CHECK(it != pages_.end() && it->second.state == State::in_flight);
  Record& r = it->second;
  r.state = State::resident;
  // A page arriving now counts as seen now: it was asked for, and keeping lru_ sorted by
  // last_seen makes eviction O(1).
  r.last_seen = frame_;
  if (!is_pinned(page)) r.lru = lru_.insert(lru_.end(), it->first);
  table_.map(page, r.slot);
  ++stats_.produced;
}

void Residency::failed(const PageId& page) {
  const auto it = pages_.find(page.pack());
  TVT_CHECK(it != pages_.end() && it->second.state == State::in_flight);
  slots_.free(it->second.slot);
  pages_.erase(it);
  if (!is_pinned(page)) retry_at_[page.pack()] = frame_ + std::max<uint32_t>(options_.retry_after_frames, 1);
  ++stats_.failed;
}

void Residency::cancelled(const PageId& page) {
  const auto it = pages_.find(page.pack());
  TVT_CHECK(it != pages_.end() && it->second.state == State::in_flight);
  slots_.free(it->second.slot);
  pages_.erase(it);
  ++stats_.cancelled;
}

std::vector<PageId> Residency::stale_in_flight(uint64_t frames) const {
  std::vector<PageId> out;
  for (const auto& [key, r] : pages_)
    if (r.state == State::in_flight && r.last_seen + frames < frame_) out.push_back(PageId::unpack(key));
  std::sort(out.begin(), out.end());
  return out;
}

const ResidencyStats& Residency::stats() const {
  stats_.resident = uint32_t(table_.mapped_count());
  stats_.in_flight = uint32_t(pages_.size() - table_.mapped_count());
  stats_.occupancy = double(pages_.size()) / double(options_.slot_count);
  return stats_;
}

std::vector<PageRequest> Residency::resident_pages() const {
  std::vector<PageRequest> out;
  for (const auto& [key, r] : pages_)
    if (r.state == State::resident) out.push_back(PageRequest{PageId::unpack(key), r.slot});
  return out;
}

std::vector<PageRequest> Residency::in_flight_pages() const {
  std::vector<PageRequest> out;
  for (const auto& [key, r] : pages_)
    if (r.state == State::in_flight) out.push_back(PageRequest{PageId::unpack(key), r.slot});
  return out;
}

}  // namespace tvt
