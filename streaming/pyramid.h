// The filtered mip pyramid (docs/page-store.md, "Filtered pyramid"): level-0 pages as the
// compositor makes them, every coarser mip the 2x2 box filter of the mip below. One
// implementation for what `terravt bake --pyramid filtered` stores and for the ground truth of
// `terravt compare` and `terravt bench mips`.
//
// Rules (the tests check them exactly):
// - Rounding: per byte channel, dst = (a + b + c + d + 2) >> 2 (the mean, halves rounded up).
// - Every texel of a mip-m page (m >= 1), payload and border alike, at mip-m texel (X, Y) with
//   X, Y clamped to [0, (V >> m) - 1] (the clamp the compositor applies at the terrain edge), is
//   the box filter of the mip m-1 texels (2X..2X+1, 2Y..2Y+1). Those are payload texels of
//   mip m-1 pages: the four children and, for the border, the neighbouring pages' edges. So a
//   border equals the neighbour's payload, as the VT's bilinear filtering needs.
// - Level-0 pages are the compositor's pages, borders included.
// Every layer of a page is filtered the same way (RGBA8; alpha holds height).
#pragma once
#include <cstdint>
#include <functional>
#include <list>
#include <span>
#include <unordered_map>
#include <vector>

#include "streaming/bake.h"

namespace tvt {

// 2x2 box filter of RGBA8 texels: `src` holds 2w x 2h texels, `dst` gets w x h; strides in bytes.
void box_filter_rgba8(const uint8_t* src, size_t src_stride, uint32_t w, uint32_t h, uint8_t* dst, size_t dst_stride);

// The P x P payload texels of the first layer of a page ((P+2B)^2 RGBA8 texels): what error
// figures compare, since a border repeats the neighbours' payload.
std::vector<uint8_t> page_payload(const VtConfig& vt, std::span<const uint8_t> page);

// Pages that exist already (a store, a bake's output so far). `has` is cheap and must only say
// true for pages `read` can deliver (page_bytes, the filtered pyramid's bytes); `read` errors
// name the page.
struct PageLookup {
  std::function<bool(const PageId&)> has;
  std::function<Status(const PageId&, std::span<uint8_t> out)> read;
};

class FilteredPyramid {
 public:
  struct Options {
    uint32_t batch_pages = 32;   // level-0 pages asked from the source at once (1..4096)
    uint32_t cache_pages = 192;  // pages kept (composed or read), least recently used dropped;
                                 // at least 2 * batch_pages + 16 are kept whatever is asked
  };
  // `level0` composes level-0 pages (called on this thread); `lookup` supplies pages that exist.
  // Which pages exist only changes the cost, never a result: a missing page is made again.
  FilteredPyramid(const StoreDesc& desc, PageSource level0, PageLookup lookup, Options options);

  // The filtered pyramid's page: every layer, (P+2B)^2 texels each, desc.page_bytes() bytes.
  Result<std::vector<uint8_t>> page(const PageId& page);
  // Only its P x P payload texels per layer (no border): at mip m exactly the 4^m level-0
  // pages under it are needed, where page() also needs a ring of neighbours.
  Result<std::vector<uint8_t>> payload(const PageId& page);

  // Lists up front the level-0 pages that page() (border) or payload() of each of `pages`, asked
  // in this order, will compose, so that they are composed in batches across pages. Pages of
  // the list count as existing for the later ones (a bake produces them in this order).
  void prepare(std::span<const PageId> pages, bool border);

  uint64_t composed_pages() const { return composed_; }  // level-0 pages asked from the source
  uint64_t read_pages() const { return read_; }          // pages read through the lookup

 private:
  struct Rect {  // texels of one mip, inside the mip
    uint64_t x0 = 0, y0 = 0;
    uint32_t w = 0, h = 0;
  };
  Rect source_rect(const PageId& page, bool border) const;  // the mip m-1 texels a page filters
  void start(const PageId& page, bool border);              // lists its level-0 needs unless prepared
  Result<std::vector<uint8_t>> texels(uint32_t mip, const Rect& r);
  Status fill(uint32_t mip, const Rect& r, uint8_t* out, size_t row, size_t plane);
  void collect(uint32_t mip, const Rect& r);
  Result<const uint8_t*> get(const PageId& page);
  const uint8_t* cached(const PageId& page);
  const uint8_t* insert(const PageId& page, std::vector<uint8_t> bytes);

  VtConfig vt_;
  uint32_t layers_ = 1;
  uint64_t page_bytes_ = 0;
  PageSource level0_;
  PageLookup lookup_;
  Options options_;
  // Least recently used first; map from packed id into the list.
  std::list<std::pair<uint64_t, std::vector<uint8_t>>> lru_;
  std::unordered_map<uint64_t, decltype(lru_)::iterator> by_page_;
  // Level-0 pages the current request will compose, in the order it needs them: a miss composes
  // the next batch of them at once.
  std::vector<PageId> upcoming_;
  std::unordered_map<uint64_t, size_t> upcoming_at_;
  std::unordered_map<uint64_t, bool> prepared_;  // packed page -> listed by prepare(), not asked yet
  std::unordered_map<uint64_t, bool> coming_;    // packed pages of the prepare() list
  uint64_t composed_ = 0, read_ = 0;
};

}  // namespace tvt
