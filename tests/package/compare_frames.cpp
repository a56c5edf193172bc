// Compares the example engine client's last frame and page table with `terravt render`'s on the
// same scene and camera (check_engine_client.sh). Prints PSNR, the fraction of pixels within
// 1/255 in every channel, and whether the page tables are byte-identical (if not, how many
// entries differ and whether only their cache slots differ). Exit 0 when PSNR >= --min-psnr,
// the fraction >= --min-within and the tables are identical; 1 otherwise; 2 on bad input.
//   compare_frames CLIENT.png TERRAVT.png CLIENT_TABLE TERRAVT_TABLE [--min-psnr 50] [--min-within 0.999]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "compose/image.h"
#include "compose/image_diff.h"
#include "shared/page_table_entry.h"

namespace {

bool read_bytes(const char* path, std::vector<uint8_t>& out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  out.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 5) {
    std::fprintf(stderr, "usage: compare_frames CLIENT.png TERRAVT.png CLIENT_TABLE TERRAVT_TABLE [--min-psnr DB] [--min-within F]\n");
    return 2;
  }
  double min_psnr = 50.0, min_within = 0.999;
  for (int i = 5; i + 1 < argc; i += 2) {
    if (std::strcmp(argv[i], "--min-psnr") == 0) min_psnr = std::atof(argv[i + 1]);
    else if (std::strcmp(argv[i], "--min-within") == 0) min_within = std::atof(argv[i + 1]);
    else {
      std::fprintf(stderr, "compare_frames: unknown flag %s\n", argv[i]);
      return 2;
    }
  }
  auto a = tvt::read_image_rgba8(argv[1]);
  auto b = tvt::read_image_rgba8(argv[2]);
  if (!a || !b) {
    std::fprintf(stderr, "compare_frames: %s\n", (!a ? a.error() : b.error()).message.c_str());
    return 2;
  }
  if (a->width != b->width || a->height != b->height) {
    std::fprintf(stderr, "compare_frames: %s is %dx%d, %s is %dx%d\n", argv[1], a->width, a->height, argv[2], b->width,
                 b->height);
    return 1;
  }
  const tvt::ImageDiff diff = tvt::compare_images(*a, *b);
  uint64_t within = 0;
  for (uint64_t i = 0; i < diff.pixels; ++i) {
    int worst = 0;
    for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(int(a->texels[i * 4 + c]) - int(b->texels[i * 4 + c])));
    within += worst <= 1 ? 1 : 0;
  }
  const double fraction = double(within) / double(diff.pixels);
  std::printf("image: PSNR %.2f dB, %.4f %% of %llu pixels within 1/255, max difference %u/255, %llu pixels differ\n",
              std::isinf(diff.psnr_db) ? 99.0 : diff.psnr_db, 100.0 * fraction, (unsigned long long)diff.pixels,
              diff.max_abs, (unsigned long long)diff.pixels_differing);

  std::vector<uint8_t> ta, tb;
  if (!read_bytes(argv[3], ta) || !read_bytes(argv[4], tb)) {
    std::fprintf(stderr, "compare_frames: cannot read %s\n", !read_bytes(argv[3], ta) ? argv[3] : argv[4]);
    return 2;
  }
  bool tables_equal = ta == tb;
  if (tables_equal) {
    size_t valid = 0;
    for (size_t i = 0; i + 4 <= ta.size(); i += 4) {
      uint32_t e;
      std::memcpy(&e, &ta[i], 4);
      valid += tvt::gpu::tvt_pte_valid(e) ? 1 : 0;
    }
    std::printf("page tables: identical, %zu bytes, %zu of %zu entries valid\n", ta.size(), valid, ta.size() / 4);
  } else if (ta.size() != tb.size()) {
    std::printf("page tables: sizes differ (%zu and %zu bytes)\n", ta.size(), tb.size());
  } else {
    size_t differ = 0, mip_differs = 0, first = 0;
    for (size_t i = 0; i + 4 <= ta.size(); i += 4) {
      uint32_t x, y;
      std::memcpy(&x, &ta[i], 4);
      std::memcpy(&y, &tb[i], 4);
      if (x == y) continue;
      if (differ++ == 0) first = i / 4;
      mip_differs += (tvt::gpu::tvt_pte_valid(x) != tvt::gpu::tvt_pte_valid(y) || tvt::gpu::tvt_pte_mip(x) != tvt::gpu::tvt_pte_mip(y)) ? 1 : 0;
    }
    std::printf("page tables: %zu of %zu entries differ (%zu in validity or data mip, the rest in the cache slot only), first at entry %zu\n",
                differ, ta.size() / 4, mip_differs, first);
  }
  const bool ok = diff.psnr_db >= min_psnr && fraction >= min_within && tables_equal;
  if (!ok)
    std::printf("FAIL: needs PSNR >= %.1f dB, >= %.2f %% within 1/255 and identical page tables\n", min_psnr, 100.0 * min_within);
  return ok ? 0 : 1;
}
