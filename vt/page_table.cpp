#include "vt/page_table.h"

#include <algorithm>
#include <bit>

#include "vt/result.h"

namespace tvt {
namespace {

// A half-open range of page coordinates [lo, hi) at one mip.
struct Range {
  uint64_t lo = 0;
  uint64_t hi = 0;
  bool empty() const { return lo >= hi; }
};

Range intersect(Range a, Range b) { return Range{std::max(a.lo, b.lo), std::min(a.hi, b.hi)}; }

// Window origin at one mip: the centre page minus W/2, clamped so the window stays inside
// the mip (no entries are spent on pages beyond the terrain edge).
uint32_t window_origin(uint64_t centre_page, uint64_t pages, uint32_t w) {
  const int64_t lo = int64_t(centre_page) - int64_t(w / 2);
  const int64_t hi = int64_t(pages) - int64_t(w);
  return uint32_t(std::clamp<int64_t>(lo, 0, hi));
}

}  // namespace

PageTable::PageTable(const VtConfig& config, const PageTableOptions& options)
    : config_(config), w_(options.window_pages) {
  TVT_CHECK(validate(config, "PageTable").ok());
  TVT_CHECK(std::has_single_bit(w_) && w_ >= 4 && w_ <= 4096);
  TVT_CHECK(config.mip_count() <= kEntryMipMask + 1);
  const uint32_t mips = config.mip_count();
  windows_.resize(mips);
  uint32_t offset = 0;
  for (uint32_t m = 0; m < mips; ++m) {
    const uint64_t pages = config.pages_per_side(m);
    MipWindow& win = windows_[m];
    win.complete = pages <= w_;
    win.side = win.complete ? uint32_t(pages) : w_;
    win.origin_x = win.complete ? 0 : window_origin(0, pages, w_);
    win.origin_y = win.origin_x;
    win.offset = offset;
    offset += win.side * win.side;
  }
  entries_.assign(offset, 0u);
  dirty_flag_.assign(offset, 0);
}

std::span<const uint32_t> PageTable::entries(uint32_t mip) const {
  TVT_CHECK(mip < windows_.size());
  const MipWindow& win = windows_[mip];
  return std::span<const uint32_t>(entries_).subspan(win.offset, size_t(win.side) * win.side);
}

bool PageTable::in_window(const PageId& page) const {
  if (page.mip >= windows_.size()) return false;
  const MipWindow& win = windows_[page.mip];
  return page.x >= win.origin_x && page.x - win.origin_x < win.side && page.y >= win.origin_y &&
         page.y - win.origin_y < win.side;
}

uint32_t PageTable::entry_index(const PageId& page) const {
  TVT_CHECK(in_window(page));
  const uint32_t s = windows_[page.mip].side;
  // s is a power of two (W, or pages_per_side <= W), so "mod s" is a mask.
  return (page.y & (s - 1)) * s + (page.x & (s - 1));
}

void PageTable::write(uint32_t mip, uint32_t index, uint32_t value) {
  uint32_t& e = entry_ref(mip, index);
  if (e == value) return;
  e = value;
  const uint32_t flat = windows_[mip].offset + index;
  if (dirty_flag_[flat] == 0) {
    dirty_flag_[flat] = 1;
    dirty_.push_back(PageTableUpdate{mip, index, 0});
  }
}

std::vector<PageTableUpdate> PageTable::take_updates() {
  std::vector<PageTableUpdate> out;
  out.swap(dirty_);
  for (PageTableUpdate& u : out) {
    const uint32_t flat = windows_[u.mip].offset + u.index;
    u.value = entries_[flat];
    dirty_flag_[flat] = 0;
  }
  return out;
}

bool PageTable::is_mapped(const PageId& page) const { return mapped_.contains(page.pack()); }

std::optional<uint32_t> PageTable::slot_of(const PageId& page) const {
  const auto it = mapped_.find(page.pack());
  if (it == mapped_.end()) return std::nullopt;
  return it->second;
}

std::optional<ResolvedPage> PageTable::resolve(const PageId& page) const {
  TVT_CHECK(is_valid(config_, page));
  const uint32_t mips = mip_count();
  for (PageId p = page; p.mip < mips; p = p.parent()) {
    const auto it = mapped_.find(p.pack());
    if (it != mapped_.end()) return ResolvedPage{it->second, p.mip};
  }
  return std::nullopt;
}

uint32_t PageTable::resolve_entry(const PageId& page) const {
  const auto r = resolve(page);
  return r ? pack_entry(r->slot, r->data_mip) : 0u;
}

uint32_t PageTable::lookup(uint32_t x, uint32_t y, uint32_t mip) const {
  TVT_CHECK(x < config_.size_texels() && y < config_.size_texels() && mip < mip_count());
  const uint32_t lp = config_.log2_page();
  for (uint32_t m = mip; m < mip_count(); ++m) {
    const PageId page{m, x >> (lp + m), y >> (lp + m)};
    if (in_window(page)) return entries_[windows_[m].offset + entry_index(page)];
  }
  TVT_CHECK(false);  // the top mip is always complete
  return 0;
}

void PageTable::set_centre(uint32_t x, uint32_t y) {
  TVT_CHECK(x < config_.size_texels() && y < config_.size_texels());
  const uint32_t lp = config_.log2_page();
  // Coarse to fine: a newly covered page that is not mapped takes its parent's entry, which
  // is already up to date for the new centre whenever the parent is inside its own window.
  for (uint32_t m = mip_count(); m-- > 0;) {
    const MipWindow& win = windows_[m];
    if (win.complete) continue;
    const uint64_t pages = config_.pages_per_side(m);
    recentre_mip(m, window_origin(x >> (lp + m), pages, w_), window_origin(y >> (lp + m), pages, w_));
  }
}

void PageTable::recentre_mip(uint32_t mip, uint32_t new_x, uint32_t new_y) {
  MipWindow& win = windows_[mip];
  const Range old_x{win.origin_x, uint64_t(win.origin_x) + w_};
  const Range old_y{win.origin_y, uint64_t(win.origin_y) + w_};
  if (new_x == win.origin_x && new_y == win.origin_y) return;
  win.origin_x = new_x;
  win.origin_y = new_y;
  for (uint32_t py = new_y; py < new_y + w_; ++py) {
    const bool row_was_covered = py >= old_y.lo && py < old_y.hi;
    for (uint32_t px = new_x; px < new_x + w_; ++px) {
      if (row_was_covered && px >= old_x.lo && px < old_x.hi) continue;  // same page, same entry
      const PageId page{mip, px, py};
      uint32_t value = 0;
      if (const auto it = mapped_.find(page.pack()); it != mapped_.end()) {
        value = pack_entry(it->second, mip);
      } else if (mip + 1 < mip_count()) {
        const PageId parent = page.parent();
        value = in_window(parent) ? entries_[windows_[parent.mip].offset + entry_index(parent)]
                                  : resolve_entry(parent);
      }
      write(mip, entry_index(page), value);
    }
  }
}

// Calls f(mip d, index, entry) for every windowed entry of the page itself (d == page.mip)
// and of its descendants at every finer mip d: the square [px << k, (px + 1) << k)^2 with
// k = page.mip - d, clipped to mip d's window.
template <class F>
void PageTable::for_each_descendant_entry(const PageId& page, F&& f) const {
  for (uint32_t d = page.mip + 1; d-- > 0;) {
    const MipWindow& win = windows_[d];
    const uint32_t k = page.mip - d;
    const Range rx = intersect(Range{uint64_t(page.x) << k, uint64_t(page.x + 1) << k},
                               Range{win.origin_x, uint64_t(win.origin_x) + win.side});
    const Range ry = intersect(Range{uint64_t(page.y) << k, uint64_t(page.y + 1) << k},
                               Range{win.origin_y, uint64_t(win.origin_y) + win.side});
    if (rx.empty() || ry.empty()) continue;
    for (uint64_t py = ry.lo; py < ry.hi; ++py)
      for (uint64_t px = rx.lo; px < rx.hi; ++px) {
        const uint32_t index = entry_index(PageId{d, uint32_t(px), uint32_t(py)});
        f(d, index, entries_[win.offset + index]);
      }
  }
}

void PageTable::map(const PageId& page, uint32_t slot) {
  TVT_CHECK(is_valid(config_, page));
  TVT_CHECK(slot < kMaxSlots);
  const bool inserted = mapped_.emplace(page.pack(), slot).second;
  TVT_CHECK(inserted);  // mapping a page twice is a residency bug
  const uint32_t value = pack_entry(slot, page.mip);
  // The page itself (d == mip) and every descendant mip d < mip: the descendants of
  // (px, py) at mip d are the square [px << k, (px + 1) << k)^2, k = mip - d. An entry takes
  // the new page unless it already points at finer data (a mapped descendant).
  for_each_descendant_entry(page, [&](uint32_t d, uint32_t index, uint32_t e) {
    if (!entry_valid(e) || entry_mip(e) > page.mip) write(d, index, value);
  });
}

void PageTable::unmap(const PageId& page) {
  TVT_CHECK(is_valid(config_, page));
  const size_t erased = mapped_.erase(page.pack());
  TVT_CHECK(erased == 1);  // unmapping a page that is not mapped is a residency bug
  const uint32_t fallback = page.mip + 1 < mip_count() ? resolve_entry(page.parent()) : 0u;
  // Entries of the page's square at mip d that name data of `page.mip` can only name this
  // page (its only ancestor at that mip): re-point them at the nearest mapped ancestor.
  for_each_descendant_entry(page, [&](uint32_t d, uint32_t index, uint32_t e) {
    if (entry_valid(e) && entry_mip(e) == page.mip) write(d, index, fallback);
  });
}

size_t PageTable::host_memory_bytes() const {
  // unordered_map: one node per element (key, value, next pointer, cached hash) + buckets.
  const size_t node = sizeof(uint64_t) + sizeof(uint32_t) + 2 * sizeof(void*);
  return dirty_flag_.size() + dirty_.capacity() * sizeof(PageTableUpdate) + mapped_.size() * node +
         mapped_.bucket_count() * sizeof(void*);
}

}  // namespace tvt
