#include "render/vt_info.h"

#include "vt/result.h"

namespace tvt {

gpu::TvtVtInfo make_vt_info(const VtConfig& vt, const PageTable& table, float mip_bias) {
  TVT_CHECK(table.mip_count() <= uint32_t(gpu::TVT_MAX_VT_MIPS));
  gpu::TvtVtInfo info{};
  info.log2_vt = int(vt.log2_size);
  info.log2_page = int(vt.log2_page());
  info.border_texels = int(vt.border_texels);
  info.slot_texels = int(vt.slot_texels());
  info.mip_count = int(table.mip_count());
  info.mip_bias = mip_bias;
  for (uint32_t m = 0; m < table.mip_count(); ++m) {
    const MipWindow& w = table.window(m);
    info.mips[m] = gpu::TvtVtMip{int(w.origin_x), int(w.origin_y), int(w.side), w.offset};
  }
  return info;
}

}  // namespace tvt
