// Host side of vt_lookup.glsl / vt_sample.glsl: the TvtVtInfo block from the VT geometry and
// the page table's current windows.
#pragma once
#include "shaders/shared/vt_types.h"
#include "vt/page_table.h"
#include "vt/vt_config.h"

namespace tvt {

gpu::TvtVtInfo make_vt_info(const VtConfig& vt, const PageTable& table, float mip_bias);

}  // namespace tvt
