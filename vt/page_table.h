// The VT indirection (docs/virtual-texture.md), bounded by the window size, not by V.
// Design, bit layout and limits: docs/page-table.md.
//
// Per mip m the table keeps a toroidal window of s_m x s_m entries, s_m = min(W,
// pages_per_side(m)). Windowed mips (pages_per_side(m) > W) cover the W x W pages around
// the camera's page at that mip, clamped to stay inside the mip; complete mips
// (pages_per_side(m) <= W) hold every page. Page (px, py) of mip m lives at entry
//   index = (py mod s_m) * s_m + (px mod s_m)
// and the entry names the slot of that page if it is mapped, else the slot of its nearest
// mapped ancestor, with the mip of the data it points at. An entry is invalid (0) only if
// neither the page nor any ancestor is mapped; the residency policy pins the top page, so
// after start-up every entry is valid.
//
// Units: texel coordinates are level-0 VT texels; page coordinates are pages of their mip.
// Not thread-safe: one owner (the residency policy) mutates it; a renderer reads entries()
// and take_updates() between mutations on the same thread.
#pragma once
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <unordered_map>
#include <vector>

#include "shaders/shared/page_table_entry.h"
#include "vt/vt_config.h"

namespace tvt {

// ---- Entry layout: one uint32, defined once in shaders/shared/page_table_entry.h ----
inline constexpr uint32_t kEntrySlotBits = gpu::TVT_PTE_SLOT_BITS;
inline constexpr uint32_t kEntrySlotMask = gpu::TVT_PTE_SLOT_MASK;
inline constexpr uint32_t kEntryMipShift = gpu::TVT_PTE_MIP_SHIFT;
inline constexpr uint32_t kEntryMipMask = gpu::TVT_PTE_MIP_MASK;
inline constexpr uint32_t kEntryValid = gpu::TVT_PTE_VALID;
inline constexpr uint32_t kMaxSlots = 1u << kEntrySlotBits;

constexpr uint32_t pack_entry(uint32_t slot, uint32_t data_mip) { return gpu::tvt_pte_pack(slot, data_mip); }
constexpr bool entry_valid(uint32_t e) { return gpu::tvt_pte_valid(e); }
constexpr uint32_t entry_slot(uint32_t e) { return gpu::tvt_pte_slot(e); }
constexpr uint32_t entry_mip(uint32_t e) { return gpu::tvt_pte_mip(e); }

struct PageTableOptions {
  uint32_t window_pages = 128;  // W: entries per side of each windowed mip; power of two, 4..4096
};

// Where mip m's entries sit and which pages they cover. The GPU needs origin and side of
// every mip (a small uniform array) to know whether a page is inside the window.
struct MipWindow {
  uint32_t side = 0;      // s_m = min(W, pages_per_side(m)); entries per side
  uint32_t origin_x = 0;  // first covered page (mip-m page units)
  uint32_t origin_y = 0;
  uint32_t offset = 0;    // first entry of this mip in the flat array of all mips
  bool complete = false;  // true if the window is the whole mip
};

// One changed entry for a GPU scatter: flat_index = window(mip).offset + index.
struct PageTableUpdate {
  uint32_t mip = 0;
  uint32_t index = 0;  // toroidal index inside the mip's window
  uint32_t value = 0;  // the packed entry
  friend bool operator==(const PageTableUpdate&, const PageTableUpdate&) = default;
};

struct ResolvedPage {
  uint32_t slot = 0;
  uint32_t data_mip = 0;
  friend bool operator==(const ResolvedPage&, const ResolvedPage&) = default;
};

class PageTable {
 public:
  // `config` must be valid (validate()); W a power of two in [4, 4096]. Centre starts at (0, 0).
  PageTable(const VtConfig& config, const PageTableOptions& options);

  // Recentres every windowed mip on level-0 texel (x, y) (x, y < V). Entries whose page
  // left the window are rewritten for the newly covered pages, resolved from the mapped set.
  // Cost: O(changed entries), at most sum of s_m^2.
  void set_centre(uint32_t x, uint32_t y);

  // Makes `page` resident in `slot` (< 2^20). Fatal if the page is already mapped or
  // invalid. Rewrites the page's entry and every descendant entry inside the windows that
  // pointed at a coarser ancestor. Cost: up to s_d^2 entries per finer mip d.
  void map(const PageId& page, uint32_t slot);

  // Removes `page` (fatal if it is not mapped). Entries that pointed at it now point at its
  // nearest mapped ancestor (or become invalid if there is none).
  void unmap(const PageId& page);

  bool is_mapped(const PageId& page) const;
  std::optional<uint32_t> slot_of(const PageId& page) const;  // slot if mapped
  size_t mapped_count() const { return mapped_.size(); }

  // The page itself or its nearest mapped ancestor; std::nullopt if none is mapped.
  // Independent of the windows. Cost: O(mips) hash look-ups.
  std::optional<ResolvedPage> resolve(const PageId& page) const;

  // What the GPU reads for level-0 texel (x, y) at `mip`: the entry of the page containing
  // the texel at the finest mip >= `mip` whose window covers it (complete mips always do).
  uint32_t lookup(uint32_t x, uint32_t y, uint32_t mip) const;

  // True if `page` has an entry (lies inside its mip's window).
  bool in_window(const PageId& page) const;
  uint32_t entry_index(const PageId& page) const;  // toroidal index; page must be in_window

  const MipWindow& window(uint32_t mip) const { return windows_[mip]; }
  std::span<const uint32_t> entries(uint32_t mip) const;
  std::span<const uint32_t> all_entries() const { return entries_; }  // every mip, flat
  uint32_t mip_count() const { return uint32_t(windows_.size()); }
  uint32_t window_pages() const { return w_; }

  // Entries changed since the last call, one per entry, with their current value; clears
  // the dirty set. Order: by first change.
  std::vector<PageTableUpdate> take_updates();
  size_t pending_update_count() const { return dirty_.size(); }

  // Bytes of the GPU-visible table (all mips' entries). Bounded by W^2 * 4 * mip_count,
  // independent of V once pages_per_side(0) > W.
  size_t memory_bytes() const { return entries_.size() * sizeof(uint32_t); }
  // Host bookkeeping beyond the entries: dirty flags plus the mapped-page hash map
  // (an estimate of its node and bucket storage). Grows with the mapped count, not with V.
  size_t host_memory_bytes() const;

 private:
  uint32_t& entry_ref(uint32_t mip, uint32_t index) { return entries_[windows_[mip].offset + index]; }
  void write(uint32_t mip, uint32_t index, uint32_t value);
  uint32_t resolve_entry(const PageId& page) const;  // packed entry or 0
  void recentre_mip(uint32_t mip, uint32_t new_x, uint32_t new_y);
  template <class F>
  void for_each_descendant_entry(const PageId& page, F&& f) const;

  VtConfig config_;
  uint32_t w_ = 0;
  std::vector<MipWindow> windows_;
  std::vector<uint32_t> entries_;  // all mips, flat, at windows_[m].offset
  std::vector<uint8_t> dirty_flag_;
  std::vector<PageTableUpdate> dirty_;  // value filled in by take_updates()
  std::unordered_map<uint64_t, uint32_t> mapped_;  // PageId::pack() -> slot
};

}  // namespace tvt
