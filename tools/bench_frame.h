// `terravt bench frame`: the VT path against direct splatting, a plain pre-composed texture
// and an untextured pass on the same camera poses, both feedback variants, anisotropy cost,
// time-to-sharp after the camera cut and VT memory against V (docs/benchmarks.md).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace tvt::cli {

struct BenchFrameArgs {
  std::string scene;
  std::string gpu_name;
  std::string json_out;
  std::vector<std::string> methods = {"blendmap", "fbpb+dpt2"};
  uint32_t width = 320, height = 180;
  uint32_t frames = 80;       // at 5 fps: past the default flythrough's camera cut (13 s)
  double fps = 5.0;
  uint32_t cache_slots = 384;
  uint32_t page_budget = 16;
  uint32_t feedback_divisor = 8;
  uint32_t plain_log2 = 12;   // plain texture 2^12 = 4096 texels per side
  uint32_t poses = 8;         // static poses of the interleaved steady-state comparison
  uint32_t rounds = 3;        // timings per pass and pose (the fastest counts)
  uint32_t anisotropy = 4;    // taps of the anisotropic variant (<= page border B)
  float brilinear_band = 0.25f;  // band of the brilinear variant (VtMipFilter), in [0, 1]
  bool static_only = false;   // skip the flythrough loops (quick comparisons)
  std::string mip_strategy = "prefiltered";  // how the flythrough composes pages of mip >= 1 (the API default)
};

int run_bench_frame(const BenchFrameArgs& args);

}  // namespace tvt::cli
