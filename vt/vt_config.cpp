#include "vt/vt_config.h"

#include <bit>

namespace tvt {

uint32_t VtConfig::log2_page() const { return uint32_t(std::countr_zero(page_texels)); }

Status validate(const VtConfig& c, const std::string& where) {
  if (c.log2_size < 10 || c.log2_size > 30)
    return make_error(where + "/log2_size: must be between 10 and 30, got " + std::to_string(c.log2_size));
  if (c.page_texels < 16 || c.page_texels > 1024 || !std::has_single_bit(c.page_texels))
    return make_error(where + "/page_texels: must be a power of two between 16 and 1024, got " +
                      std::to_string(c.page_texels));
  if (c.border_texels > c.page_texels / 2)
    return make_error(where + "/border_texels: must be at most half of page_texels (" +
                      std::to_string(c.page_texels / 2) + "), got " + std::to_string(c.border_texels));
  if (c.log2_page() > c.log2_size)
    return make_error(where + "/page_texels: larger than the virtual texture");
  return Ok{};
}

bool is_valid(const VtConfig& c, const PageId& id) {
  if (id.mip >= c.mip_count()) return false;
  const uint64_t n = c.pages_per_side(id.mip);
  return id.x < n && id.y < n;
}

std::string to_string(const PageId& id) {
  return "(mip " + std::to_string(id.mip) + ", " + std::to_string(id.x) + ", " + std::to_string(id.y) + ")";
}

}  // namespace tvt
