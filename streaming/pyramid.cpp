// FilteredPyramid: a mip-m request is answered from texel rectangles. A rectangle at mip m is
// assembled page by page: from a page that exists (cache, lookup) or is composed (level 0), or
// else from the box filter of the 2x rectangle at mip m-1. Before a request touches level 0, a
// dry pass lists the level-0 pages it will compose, so they are composed in batches.
#include "streaming/pyramid.h"

#include <algorithm>
#include <cstring>

namespace tvt {

void box_filter_rgba8(const uint8_t* src, size_t src_stride, uint32_t w, uint32_t h, uint8_t* dst, size_t dst_stride) {
  for (uint32_t j = 0; j < h; ++j) {
    const uint8_t* a = src + size_t(2 * j) * src_stride;
    const uint8_t* b = a + src_stride;
    uint8_t* o = dst + size_t(j) * dst_stride;
    for (uint32_t i = 0; i < 4 * w; ++i) {
      const uint32_t c = i & 3u, t = (i >> 2) * 8 + c;  // byte of texel 2*(i/4), channel c
      o[i] = uint8_t((uint32_t(a[t]) + a[t + 4] + b[t] + b[t + 4] + 2) >> 2);
    }
  }
}

std::vector<uint8_t> page_payload(const VtConfig& vt, std::span<const uint8_t> page) {
  const size_t P = vt.page_texels, B = vt.border_texels, slot = vt.slot_texels();
  std::vector<uint8_t> out(P * P * 4);
  for (size_t y = 0; y < P; ++y) std::copy_n(page.begin() + ptrdiff_t(((y + B) * slot + B) * 4), P * 4, out.begin() + ptrdiff_t(y * P * 4));
  return out;
}

FilteredPyramid::FilteredPyramid(const StoreDesc& desc, PageSource level0, PageLookup lookup, Options options)
    : vt_(desc.vt),
      layers_(uint32_t(desc.layers.size())),
      page_bytes_(desc.page_bytes()),
      level0_(std::move(level0)),
      lookup_(std::move(lookup)),
      options_(options) {
  options_.batch_pages = std::clamp(options_.batch_pages, 1u, 4096u);
  options_.cache_pages = std::max(options_.cache_pages, 2 * options_.batch_pages + 16);
}

const uint8_t* FilteredPyramid::cached(const PageId& page) {
  const auto it = by_page_.find(page.pack());
  if (it == by_page_.end()) return nullptr;
  lru_.splice(lru_.end(), lru_, it->second);  // most recently used last
  return it->second->second.data();
}

const uint8_t* FilteredPyramid::insert(const PageId& page, std::vector<uint8_t> bytes) {
  const uint64_t key = page.pack();
  if (const auto it = by_page_.find(key); it != by_page_.end()) {
    lru_.erase(it->second);
    by_page_.erase(it);
  }
  lru_.emplace_back(key, std::move(bytes));
  by_page_[key] = std::prev(lru_.end());
  while (lru_.size() > options_.cache_pages) {
    by_page_.erase(lru_.front().first);
    lru_.pop_front();
  }
  return lru_.back().second.data();
}

// The page's bytes, valid until the next cache change; nullptr for a mip >= 1 page that does
// not exist (the caller filters the mip below). Level-0 pages are composed when missing.
Result<const uint8_t*> FilteredPyramid::get(const PageId& page) {
  if (const uint8_t* p = cached(page)) return p;
  if (lookup_.has && lookup_.has(page)) {
    std::vector<uint8_t> bytes(page_bytes_);
    if (auto s = lookup_.read(page, bytes); !s) return s.error();
    ++read_;
    return insert(page, std::move(bytes));
  }
  if (page.mip > 0) return static_cast<const uint8_t*>(nullptr);
  // Compose this page and the next pages the request will need, up to a batch.
  std::vector<PageId> batch{page};
  if (const auto at = upcoming_at_.find(page.pack()); at != upcoming_at_.end())
    for (size_t i = at->second + 1; i < upcoming_.size() && batch.size() < options_.batch_pages; ++i)
      if (!by_page_.contains(upcoming_[i].pack())) batch.push_back(upcoming_[i]);
  std::vector<std::vector<uint8_t>> out;
  if (auto s = level0_(batch, out); !s) return make_error("composing level-0 " + to_string(page) + ": " + s.error().message);
  if (out.size() != batch.size()) return make_error("level-0 source returned " + std::to_string(out.size()) + " pages for " +
                                                    std::to_string(batch.size()));
  composed_ += batch.size();
  for (size_t i = batch.size(); i-- > 0;) {  // `page` last: the most recently used
    if (out[i].size() != page_bytes_)
      return make_error("level-0 source returned " + std::to_string(out[i].size()) + " bytes for " + to_string(batch[i]) +
                        ", expected " + std::to_string(page_bytes_));
    insert(batch[i], std::move(out[i]));
  }
  return cached(page);
}

void FilteredPyramid::collect(uint32_t mip, const Rect& r) {
  const uint64_t P = vt_.page_texels;
  for (uint64_t py = r.y0 / P; py <= (r.y0 + r.h - 1) / P; ++py)
    for (uint64_t px = r.x0 / P; px <= (r.x0 + r.w - 1) / P; ++px) {
      const PageId id{mip, uint32_t(px), uint32_t(py)};
      if (by_page_.contains(id.pack()) || coming_.contains(id.pack()) || (lookup_.has && lookup_.has(id))) continue;
      const uint64_t x0 = std::max(r.x0, px * P), x1 = std::min(r.x0 + r.w, px * P + P);
      const uint64_t y0 = std::max(r.y0, py * P), y1 = std::min(r.y0 + r.h, py * P + P);
      if (mip == 0) {
        if (upcoming_at_.emplace(id.pack(), upcoming_.size()).second) upcoming_.push_back(id);
      } else {
        collect(mip - 1, Rect{2 * x0, 2 * y0, uint32_t(2 * (x1 - x0)), uint32_t(2 * (y1 - y0))});
      }
    }
}

// Writes the texels of `r` (mip `mip`) to `out`: rows `row` bytes apart, layers `plane` apart.
Status FilteredPyramid::fill(uint32_t mip, const Rect& r, uint8_t* out, size_t row, size_t plane) {
  const uint64_t P = vt_.page_texels, B = vt_.border_texels, slot = vt_.slot_texels();
  for (uint64_t py = r.y0 / P; py <= (r.y0 + r.h - 1) / P; ++py)
    for (uint64_t px = r.x0 / P; px <= (r.x0 + r.w - 1) / P; ++px) {
      const uint64_t x0 = std::max(r.x0, px * P), x1 = std::min(r.x0 + r.w, px * P + P);
      const uint64_t y0 = std::max(r.y0, py * P), y1 = std::min(r.y0 + r.h, py * P + P);
      uint8_t* o = out + (y0 - r.y0) * row + (x0 - r.x0) * 4;
      auto got = get(PageId{mip, uint32_t(px), uint32_t(py)});
      if (!got) return got.error();
      if (const uint8_t* page = got.value()) {
        for (uint32_t l = 0; l < layers_; ++l)
          for (uint64_t y = y0; y < y1; ++y)
            std::memcpy(o + l * plane + (y - y0) * row,
                        page + l * slot * slot * 4 + ((y - py * P + B) * slot + (x0 - px * P + B)) * 4, (x1 - x0) * 4);
        continue;
      }
      const Rect fine{2 * x0, 2 * y0, uint32_t(2 * (x1 - x0)), uint32_t(2 * (y1 - y0))};
      auto t = texels(mip - 1, fine);
      if (!t) return t.error();
      const size_t fine_plane = size_t(fine.w) * fine.h * 4;
      for (uint32_t l = 0; l < layers_; ++l)
        box_filter_rgba8(t->data() + l * fine_plane, size_t(fine.w) * 4, uint32_t(x1 - x0), uint32_t(y1 - y0),
                         o + l * plane, row);
    }
  return Ok{};
}

Result<std::vector<uint8_t>> FilteredPyramid::texels(uint32_t mip, const Rect& r) {
  std::vector<uint8_t> out(size_t(layers_) * r.w * r.h * 4);
  if (auto s = fill(mip, r, out.data(), size_t(r.w) * 4, size_t(r.w) * r.h * 4); !s) return s.error();
  return out;
}

FilteredPyramid::Rect FilteredPyramid::source_rect(const PageId& page, bool border) const {
  const int64_t P = vt_.page_texels, B = border ? vt_.border_texels : 0;
  const int64_t last = int64_t(vt_.mip_texels(page.mip)) - 1;  // texels beyond it clamp to it
  const int64_t x0 = std::clamp<int64_t>(page.x * P - B, 0, last), x1 = std::clamp<int64_t>(page.x * P + P + B - 1, 0, last);
  const int64_t y0 = std::clamp<int64_t>(page.y * P - B, 0, last), y1 = std::clamp<int64_t>(page.y * P + P + B - 1, 0, last);
  return Rect{uint64_t(2 * x0), uint64_t(2 * y0), uint32_t(2 * (x1 - x0 + 1)), uint32_t(2 * (y1 - y0 + 1))};
}

void FilteredPyramid::prepare(std::span<const PageId> pages, bool border) {
  upcoming_.clear();
  upcoming_at_.clear();
  prepared_.clear();
  coming_.clear();
  for (const PageId& page : pages) {
    if (page.mip > 0 && is_valid(vt_, page)) {
      collect(page.mip - 1, source_rect(page, border));
      prepared_[page.pack()] = border;
    }
    coming_[page.pack()] = true;
  }
}

void FilteredPyramid::start(const PageId& page, bool border) {
  coming_.erase(page.pack());
  if (const auto it = prepared_.find(page.pack()); it != prepared_.end() && it->second == border) {
    prepared_.erase(it);
    return;
  }
  upcoming_.clear();
  upcoming_at_.clear();
  if (page.mip > 0) collect(page.mip - 1, source_rect(page, border));
}

Result<std::vector<uint8_t>> FilteredPyramid::payload(const PageId& page) {
  if (!is_valid(vt_, page)) return make_error(to_string(page) + ": outside the virtual texture");
  const uint32_t P = vt_.page_texels;
  start(page, false);
  if (page.mip == 0) return texels(0, Rect{uint64_t(page.x) * P, uint64_t(page.y) * P, P, P});
  const Rect fine = source_rect(page, false);
  auto t = texels(page.mip - 1, fine);
  if (!t) return t.error();
  std::vector<uint8_t> out(size_t(layers_) * P * P * 4);
  const size_t fine_plane = size_t(fine.w) * fine.h * 4;
  for (uint32_t l = 0; l < layers_; ++l)
    box_filter_rgba8(t->data() + l * fine_plane, size_t(fine.w) * 4, P, P, out.data() + size_t(l) * P * P * 4, size_t(P) * 4);
  return out;
}

Result<std::vector<uint8_t>> FilteredPyramid::page(const PageId& page) {
  if (!is_valid(vt_, page)) return make_error(to_string(page) + ": outside the virtual texture");
  const int64_t P = vt_.page_texels, B = vt_.border_texels, slot = vt_.slot_texels();
  start(page, true);
  if (page.mip == 0) {
    auto got = get(page);
    if (!got) return got.error();
    const uint8_t* p = got.value();
    return std::vector<uint8_t>(p, p + page_bytes_);
  }
  // The mip-m texels the slot shows after the edge clamp: one rectangle r inside the mip.
  const int64_t last = int64_t(vt_.mip_texels(page.mip)) - 1;
  const Rect fine = source_rect(page, true);
  const Rect r{fine.x0 / 2, fine.y0 / 2, fine.w / 2, fine.h / 2};
  const int64_t x0 = int64_t(r.x0), y0 = int64_t(r.y0);
  auto t = texels(page.mip - 1, fine);
  if (!t) return t.error();
  std::vector<uint8_t> filtered(size_t(layers_) * r.w * r.h * 4);
  const size_t fine_plane = size_t(fine.w) * fine.h * 4, plane = size_t(r.w) * r.h * 4;
  for (uint32_t l = 0; l < layers_; ++l)
    box_filter_rgba8(t->data() + l * fine_plane, size_t(fine.w) * 4, r.w, r.h, filtered.data() + l * plane, size_t(r.w) * 4);
  std::vector<uint8_t> out(page_bytes_);
  for (uint32_t l = 0; l < layers_; ++l)
    for (int64_t ty = 0; ty < slot; ++ty) {
      const int64_t y = std::clamp<int64_t>(page.y * P - B + ty, 0, last) - y0;
      for (int64_t tx = 0; tx < slot; ++tx) {
        const int64_t x = std::clamp<int64_t>(page.x * P - B + tx, 0, last) - x0;
        std::memcpy(&out[size_t(l) * slot * slot * 4 + size_t(ty * slot + tx) * 4], &filtered[l * plane + size_t(y * r.w + x) * 4], 4);
      }
    }
  return out;
}

}  // namespace tvt
