// CPU reference compositor (docs/composition.md): double precision, written for clarity, one texel at
// a time. compose.comp implements the same maths in fp32; tests compare the two.
//
// Sources: Bloom splatting (boosted normalisation), Hardy & McRoberts blend maps, FBPB eq.
// 3.1–3.3 and Algorithm 1 (thesis §3.4), DPT eq. 4.1–4.4 and Algorithms 2–3 (thesis §4.4).
// See docs/composition.md for the exact formulas and the choices made where the papers are silent.
#pragma once
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "compose/image.h"
#include "compose/packed_scene.h"
#include "vt/vt_config.h"

namespace tvt {

// Material texels are read on first use (PackedScene::load()): the per-sample functions load
// what they touch and treat a load error as fatal (for in-memory or loaded scenes);
// compose_page_reference() loads the page's materials first and returns the error.

// One sample at a terrain position (level-0 texels in 1/256 fixed point) for a footprint of
// `footprint` level-0 texels per side. RGB albedo and A = height, each in [0,1], never NaN.
glm::dvec4 compose_sample_reference(const PackedScene& scene, int64_t x_fp, int64_t y_fp, double footprint);

// Texel (x, y) of mip `mip`: the average of s^2 samples, s = min(params.supersample, 2^mip),
// each covering 2^mip / s level-0 texels. Coordinates outside the mip are clamped to its edge.
glm::dvec4 compose_texel_reference(const PackedScene& scene, uint32_t mip, int64_t x, int64_t y);

// Box-filtered level-0 composition of mip texel (x, y): the ground truth of docs/composition.md.
glm::dvec4 ground_truth_texel(const PackedScene& scene, uint32_t mip, int64_t x, int64_t y);

// A whole page, (P+2B)^2 texels RGBA8, row-major, border included. Reads only the materials
// of the page's culling mask (compose/material_culling.h), loading them first; an error names
// the scene file, the field and the file.
Result<std::vector<uint8_t>> compose_page_reference(const PackedScene& scene, const PageId& page);

// Quantisation used for every 8-bit output: round(clamp(v, 0, 1) * 255); NaN -> 0.
uint8_t to_unorm8(double v);

}  // namespace tvt
