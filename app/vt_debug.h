// Debug views a VT user expects: the cache atlas, the page table per mip, the feedback buffer.
// (Mip-level colouring of the frame itself is VtSystem::set_debug_view(TVT_VT_VIEW_DATA_MIP).)
#pragma once
#include <cstdint>
#include <vector>

#include "compose/image.h"
#include "gpu/context.h"
#include "vt/page_table.h"

namespace tvt {

// Every slot of the cache (layout GENERAL) in a grid, `columns` slots per row, each slot's
// (P+2B)^2 texels shrunk by `shrink` (1, 2, 4...) with a 1-pixel gap. Blocking readback.
ImageRGBA8 cache_atlas_image(vk::Context& context, const vk::Image& cache, uint32_t columns, uint32_t shrink);

// The page table: one panel per mip (its window, one pixel per entry scaled to at least 64
// pixels wide), coloured by the mip the entry's data comes from; invalid entries black.
ImageRGBA8 page_table_image(const PageTable& table);

// The feedback buffer (feedback_types.h texels), coloured by requested mip; empty texels black.
ImageRGBA8 feedback_image(vk::Context& context, const vk::Buffer& feedback, uint32_t width, uint32_t height);

// The GPU page table (VtSystem::entry_buffer(), written by compute and transfer commands) as
// bytes: uint32 entries, little-endian, every mip's window. Blocking readback after the
// commands submitted so far.
std::vector<uint8_t> page_table_bytes(vk::Context& context, const vk::Buffer& entries);

}  // namespace tvt
