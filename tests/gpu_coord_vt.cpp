// The coordinate producer through the whole virtual texture (issue 3, test 1): compose.comp in
// its coordinate pattern (shaders/shared/compose_coord.h) writes pages whose texels encode their
// own address; the real VtSystem chooses them from feedback, puts them into cache slots and
// scatters the page table on the GPU; test_vt_coord.comp samples them through vt_sample.glsl
// with the VtSystem's bilinear sampler. The test decodes every sample back into a texel
// address and compares it with the analytic position, at V = 2^24 near the origin and at the
// far corner: within 1/256 texel of the data mip.
//
// Decoding: the four texels the bilinear filter reads are fetched exactly; each names its own
// (X, Y) (the block hash makes a texel of the wrong mip or place decode to noise), so the data
// fixes the texel the sample starts from. Two positions follow:
//  * address: that texel plus the fraction tvt_vt_lookup() hands the sampler — asserted within
//    1/256 texel of the analytic position (the bound);
//  * filtered: that texel plus the weight the bilinear filter gave its neighbour, read from the
//    phase channel (255 * weight of the odd texel). The filter quantises weights to
//    2^-subTexelPrecisionBits (8 bits on lavapipe) and returns an 8-bit value for an RGBA8 cache,
//    so this one is asserted within 1/256 + 1/255 texel.
// Where both texels of a row are the same (the VT edge: border texels repeat the last texel),
// the sample is constant and the analytic position is clamped to that texel's centre, as
// clamp-to-edge filtering does.
#include <gtest/gtest.h>

#include <embedded_shaders.h>

#include <array>
#include <cmath>
#include <cstring>
#include <optional>
#include <ostream>
#include <random>

#include "compose/packed_scene.h"
#include "composer/builtin_producers.h"
#include "render/vt_system.h"
#include "shaders/shared/compose_coord.h"
#include "shaders/shared/vt_coord_test_types.h"
#include "shaders/shared/vt_test_types.h"
#include "support/gpu_test.h"
#include "support/synthetic_scene.h"

using namespace tvt;

namespace {

constexpr double k_address_tolerance = 1.0 / 256.0;                   // texels of the data mip
constexpr double k_filtered_tolerance = 1.0 / 256.0 + 1.0 / 255.0;  // + one 8-bit step of the filter

struct TexelAddress {
  int64_t x = 0, y = 0;
};

// The address a pattern word names, given a position (px, py) at that mip known to within a
// few texels: the block is one of the 3x3 around it; the scramble of any other block or mip
// leaves the decoded address far from the position, so nothing is accepted.
std::optional<TexelAddress> decode_word(uint32_t word, int mip, double px, double py) {
  const uint32_t r = word & 255u, g = (word >> 8) & 255u, b = (word >> 16) & 255u, a = word >> 24;
  if ((r != 0 && r != 255) || (g != 0 && g != 255)) return std::nullopt;
  const int64_t bx0 = int64_t(std::floor(px)) >> gpu::TVT_COORD_BLOCK_SHIFT;
  const int64_t by0 = int64_t(std::floor(py)) >> gpu::TVT_COORD_BLOCK_SHIFT;
  std::optional<TexelAddress> best;
  double best_d = 3.0;  // texels
  for (int64_t by = by0 - 1; by <= by0 + 1; ++by)
    for (int64_t bx = bx0 - 1; bx <= bx0 + 1; ++bx) {
      if (bx < 0 || by < 0) continue;
      const int64_t ox = bx << gpu::TVT_COORD_BLOCK_SHIFT, oy = by << gpu::TVT_COORD_BLOCK_SHIFT;
      const uint32_t h = gpu::tvt_coord_scramble(mip, ox, oy);
      const TexelAddress t{ox | int64_t(((b ^ h) & 255u) << 1) | int64_t(r & 1u),
                           oy | int64_t(((a ^ (h >> 8)) & 255u) << 1) | int64_t(g & 1u)};
      const double d = std::max(std::abs(double(t.x) + 0.5 - px), std::abs(double(t.y) + 0.5 - py));
      if (d < best_d) best = t, best_d = d;
    }
  return best;
}

struct Decoded {
  bool ok = false;
  double address_x = 0, address_y = 0;    // texel from the data + the lookup's fraction
  double filtered_x = 0, filtered_y = 0;  // texel from the data + the filter's weight
};

// Decodes one sample: `quad` are the exact texels 00, 10, 01, 11 of the bilinear footprint,
// `phase` the filtered R and G, `fraction` the footprint position from tvt_vt_lookup() (local - 0.5
// minus the first texel), `texels` the VT size at `mip`, (px, py) the expected position.
Decoded decode_sample(const std::array<uint32_t, 4>& quad, glm::dvec2 phase, glm::dvec2 fraction, int mip,
                      int64_t texels, double px, double py) {
  std::array<TexelAddress, 4> t;
  for (size_t k = 0; k < 4; ++k) {
    const auto a = decode_word(quad[k], mip, px, py);
    if (!a) return {};
    t[k] = *a;
  }
  // Columns share X, rows share Y; neighbours are one texel apart, or equal at the VT edge.
  if (t[0].x != t[2].x || t[1].x != t[3].x || t[0].y != t[1].y || t[2].y != t[3].y) return {};
  auto step_ok = [&](int64_t first, int64_t step) {
    return step == 1 || (step == 0 && (first == 0 || first == texels - 1));
  };
  const int64_t dx = t[1].x - t[0].x, dy = t[2].y - t[0].y;
  if (!step_ok(t[0].x, dx) || !step_ok(t[0].y, dy)) return {};
  auto with_phase = [](int64_t first, int64_t step, double ph) {
    const double w = (first & 1) ? 1.0 - ph : ph;  // the filter's weight of the second texel
    return double(first) + 0.5 + double(step) * w;
  };
  Decoded r;
  r.ok = true;
  r.address_x = double(t[0].x) + 0.5 + double(dx) * fraction.x;
  r.address_y = double(t[0].y) + 0.5 + double(dy) * fraction.y;
  r.filtered_x = with_phase(t[0].x, dx, phase.x);
  r.filtered_y = with_phase(t[0].y, dy, phase.y);
  return r;
}

// Position of level-0 texel coordinate t + f at mip d, as clamp-to-edge filtering sees it.
double analytic(int64_t t, double f, int d, int64_t texels_at_mip) {
  const double p = (double(t) + f) / std::ldexp(1.0, d);
  return std::clamp(p, 0.5, double(texels_at_mip) - 0.5);
}

struct Place {
  const char* name;
  uint32_t camera_x, camera_y;  // level-0 texels
};
// Test names and listings show the place, not the struct's bytes (which hold a pointer and
// changed the CTest names from build to build).
void PrintTo(const Place& p, std::ostream* os) { *os << p.name << " (" << p.camera_x << ", " << p.camera_y << ")"; }

class GpuCoordVt : public GpuTest, public ::testing::WithParamInterface<Place> {};

std::vector<uint32_t> read_slots(vk::Context& ctx, const vk::Image& cache) {
  const VkDeviceSize bytes = VkDeviceSize(cache.width()) * cache.height() * 4 * cache.layers();
  vk::Buffer host = ctx.create_buffer(bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  ctx.run_commands([&](VkCommandBuffer cmd) {
    ctx.transition(cmd, cache, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, cache.layers()};
    region.imageExtent = {cache.width(), cache.height(), 1};
    vkCmdCopyImageToBuffer(cmd, cache.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, host.handle(), 1, &region);
    ctx.transition(cmd, cache, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL);
  });
  std::vector<uint32_t> out(bytes / 4);
  std::memcpy(out.data(), host.mapped(), bytes);
  return out;
}

}  // namespace

TEST_P(GpuCoordVt, DecodedSamplesAreWithinAFractionOfATexelOfTheAnalyticPosition) {
  const Place place = GetParam();
  // A two-material scene: the pattern ignores materials, but the composer still plans them.
  SceneAssets assets = test::make_synthetic_assets({{}, {{200, 100, 50, 255}, 0.5f}}, 24);
  assets.desc.vt.page_texels = 128;
  assets.desc.vt.border_texels = 4;
  const VtConfig& vt = assets.desc.vt;
  auto packed = pack_scene(assets, options_for(Method::Linear));
  ASSERT_TRUE(packed.ok()) << packed.error().message;
  packed->params.pattern = gpu::TVT_COMPOSE_PATTERN_COORDS;
  SceneVtOptions o;
  o.cache_slots = 128;
  o.window_pages = 16;
  o.page_budget = 64;
  auto created = create_vt_system(ctx(), packed.value(), o);
  ASSERT_TRUE(created.ok()) << created.error().message;
  VtSystem& s = *created.value();

  // Feedback: the 3x3 pages around the camera at mips 0..3 (ancestors come with them).
  const int64_t P = vt.page_texels, B = vt.border_texels, S = P + 2 * B;
  std::vector<PageFeedback> feedback;
  for (uint32_t m = 0; m < 4; ++m) {
    const int64_t n = int64_t(vt.pages_per_side(m));
    const int64_t cx = int64_t(place.camera_x) >> (vt.log2_page() + m), cy = int64_t(place.camera_y) >> (vt.log2_page() + m);
    for (int64_t j = std::max<int64_t>(cy - 1, 0); j <= std::min(cy + 1, n - 1); ++j)
      for (int64_t i = std::max<int64_t>(cx - 1, 0); i <= std::min(cx + 1, n - 1); ++i)
        feedback.push_back({PageId{m, uint32_t(i), uint32_t(j)}, 100});
  }
  for (uint64_t frame = 1; frame <= 8; ++frame) {
    s.begin_frame(frame, place.camera_x, place.camera_y, feedback);
    ctx().run_commands([&](VkCommandBuffer cmd) { TVT_CHECK(s.record(cmd).ok()); });
    s.end_frame();
  }
  for (const PageFeedback& f : feedback) ASSERT_TRUE(s.residency().is_resident(f.page)) << to_string(f.page);

  // 1. Every resident slot holds exactly its page's pattern, borders included (clamped at the
  //    VT edge as compose.comp clamps them).
  const std::vector<uint32_t> slots = read_slots(ctx(), s.cache());
  const size_t slot_words = size_t(S * S);
  size_t pages_checked = 0;
  for (const PageRequest& r : s.residency().resident_pages()) {
    const int m = int(r.page.mip);
    const int64_t last = (int64_t(1) << (vt.log2_size - uint32_t(m))) - 1;
    size_t bad = 0;
    for (int64_t ty = 0; ty < S; ++ty)
      for (int64_t tx = 0; tx < S; ++tx) {
        const int64_t x = std::clamp<int64_t>(int64_t(r.page.x) * P - B + tx, 0, last);
        const int64_t y = std::clamp<int64_t>(int64_t(r.page.y) * P - B + ty, 0, last);
        bad += slots[r.slot * slot_words + size_t(ty * S + tx)] != gpu::tvt_coord_word(m, x, y);
      }
    EXPECT_EQ(bad, 0u) << to_string(r.page) << " in slot " << r.slot;
    ++pages_checked;
  }
  EXPECT_GE(pages_checked, feedback.size());

  // 2. Queries around the camera: random positions and fractions, plus positions straddling
  //    page edges (the filter reads border texels) and the last texel of the VT.
  std::mt19937 rng(place.camera_x ^ 0x5eed);
  std::uniform_real_distribution<float> frac(0.f, 0.9999f);
  const int64_t V = int64_t(vt.size_texels());
  const int64_t lo_x = std::max<int64_t>((int64_t(place.camera_x) / P - 1) * P, 0);
  const int64_t lo_y = std::max<int64_t>((int64_t(place.camera_y) / P - 1) * P, 0);
  const int64_t hi_x = std::min(lo_x + 3 * P, V), hi_y = std::min(lo_y + 3 * P, V);
  std::vector<gpu::TvtVtQuery> queries;
  auto add = [&](int64_t x, int64_t y, float fx, float fy, int mip) {
    gpu::TvtVtQuery q{};
    q.x = std::clamp<int64_t>(x, 0, V - 1);
    q.y = std::clamp<int64_t>(y, 0, V - 1);
    q.frac = {fx, fy};
    q.mip = mip;
    queries.push_back(q);
  };
  for (int i = 0; i < 3000; ++i)
    add(lo_x + int64_t(rng() % uint32_t(hi_x - lo_x)), lo_y + int64_t(rng() % uint32_t(hi_y - lo_y)), frac(rng),
        frac(rng), int(rng() % 6));
  for (int m = 0; m < 4; ++m)  // within one mip-m texel of a mip-m page edge, in x and in y
    for (int axis = 0; axis < 2; ++axis) {
      const int64_t page = int64_t(axis == 0 ? place.camera_x : place.camera_y) / (P << m);
      for (int64_t edge = (page - 1) * (P << m); edge <= (page + 2) * (P << m); edge += P << m)
        for (int k = 0; k < 16 && edge > 0 && edge < V; ++k) {
          const int64_t across = edge + int64_t(rng() % uint32_t(2 << m)) - (int64_t(1) << m);
          const int64_t x = lo_x + int64_t(rng() % uint32_t(hi_x - lo_x)), y = lo_y + int64_t(rng() % uint32_t(hi_y - lo_y));
          add(axis == 0 ? across : x, axis == 0 ? y : across, frac(rng), frac(rng), m);
        }
    }
  for (int m = 0; m < 3; ++m) add(V - 1, V - 1, 0.9999f, 0.25f, m), add(0, 0, 0.f, 0.75f, m);

  // 3. Sample through vt_sample.glsl with the VtSystem's own info, table, cache and sampler.
  vk::Context& g = ctx();
  const size_t count = queries.size();
  vk::Buffer query_buf = g.create_buffer(count * sizeof(gpu::TvtVtQuery), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  std::memcpy(query_buf.mapped(), queries.data(), count * sizeof(gpu::TvtVtQuery));
  vk::Buffer answer_buf = g.create_buffer(count * sizeof(gpu::TvtVtCoordAnswer), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  const vk::ComputeBinding bindings[] = {{TVT_BIND_TEST_COORD_INFO, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                                         {TVT_BIND_TEST_COORD_ENTRIES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                                         {TVT_BIND_TEST_COORD_CACHE, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER},
                                         {TVT_BIND_TEST_COORD_QUERIES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                                         {TVT_BIND_TEST_COORD_ANSWERS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}};
  vk::ComputePipeline pipeline = g.create_compute_pipeline(shaders::test_vt_coord_comp(), bindings, sizeof(uint32_t));
  vk::DescriptorSet set = g.allocate_descriptor_set(pipeline);
  set.write_buffer(TVT_BIND_TEST_COORD_INFO, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, s.info_buffer());
  set.write_buffer(TVT_BIND_TEST_COORD_ENTRIES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, s.entry_buffer());
  set.write_sampled_image(TVT_BIND_TEST_COORD_CACHE, s.cache(), s.sampler(), VK_IMAGE_LAYOUT_GENERAL);
  set.write_buffer(TVT_BIND_TEST_COORD_QUERIES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, query_buf);
  set.write_buffer(TVT_BIND_TEST_COORD_ANSWERS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, answer_buf);
  const uint32_t n32 = uint32_t(count);
  g.run_commands([&](VkCommandBuffer cmd) {
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.handle());
    const VkDescriptorSet ds = set.handle();
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.layout(), 0, 1, &ds, 0, nullptr);
    vkCmdPushConstants(cmd, pipeline.layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(n32), &n32);
    vkCmdDispatch(cmd, (n32 + 63) / 64, 1, 1);
  });
  const auto* answers = static_cast<const gpu::TvtVtCoordAnswer*>(answer_buf.mapped());

  // 4. Decode and compare. Also decode corrupted footprints, taken from the real cache contents
  //    and filtered on the CPU with the same weights: shifted by one texel (an off-by-one
  //    producer or lookup), the same texels of another resident slot (a page in the wrong slot),
  //    a border texel replaced by the page's own edge texel (a producer without borders). Each
  //    must fail to decode or decode outside the tolerance.
  const std::vector<PageRequest> resident = s.residency().resident_pages();
  const PageTable& table = s.residency().page_table();
  double worst_address = 0, worst_filtered = 0;
  size_t mip_hits[gpu::TVT_MAX_VT_MIPS] = {};
  size_t shift_checked = 0, shift_caught = 0, slot_caught = 0, border_checked = 0, border_caught = 0;
  auto word = [&](uint32_t slot, int64_t tx, int64_t ty) {
    return slots[slot * slot_words + size_t(std::clamp<int64_t>(ty, 0, S - 1) * S + std::clamp<int64_t>(tx, 0, S - 1))];
  };
  auto quad_at = [&](uint32_t slot, int64_t cx, int64_t cy) {
    return std::array<uint32_t, 4>{word(slot, cx, cy), word(slot, cx + 1, cy), word(slot, cx, cy + 1), word(slot, cx + 1, cy + 1)};
  };
  for (size_t i = 0; i < count; ++i) {
    const gpu::TvtVtQuery& q = queries[i];
    const gpu::TvtVtCoordAnswer& a = answers[i];
    const uint32_t e = table.lookup(uint32_t(q.x), uint32_t(q.y), uint32_t(q.mip));
    ASSERT_TRUE(entry_valid(e)) << i;
    ASSERT_EQ(a.valid, 1u) << i;
    ASSERT_EQ(a.slot, entry_slot(e)) << i;
    ASSERT_EQ(a.data_mip, int(entry_mip(e))) << i;
    const int d = a.data_mip;
    const int64_t texels = V >> d;
    const double px = analytic(q.x, double(q.frac.x), d, texels), py = analytic(q.y, double(q.frac.y), d, texels);
    const glm::dvec2 fraction(double(a.local.x) - 0.5 - double(a.corner.x), double(a.local.y) - 0.5 - double(a.corner.y));
    const std::array<uint32_t, 4> quad{a.quad.x, a.quad.y, a.quad.z, a.quad.w};
    ASSERT_EQ(quad_at(a.slot, a.corner.x, a.corner.y), quad) << i;
    const Decoded got = decode_sample(quad, {a.filtered.r, a.filtered.g}, fraction, d, texels, px, py);
    const std::string where = "query " + std::to_string(i) + " at (" + std::to_string(q.x) + " + " +
                              std::to_string(q.frac.x) + ", " + std::to_string(q.y) + " + " + std::to_string(q.frac.y) +
                              ") mip " + std::to_string(q.mip) + ", data mip " + std::to_string(d) + ", slot " +
                              std::to_string(a.slot) + ", analytic (" + std::to_string(px) + ", " + std::to_string(py) + ")";
    ASSERT_TRUE(got.ok) << where << ": the footprint does not decode";
    const double ea = std::max(std::abs(got.address_x - px), std::abs(got.address_y - py));
    const double ef = std::max(std::abs(got.filtered_x - px), std::abs(got.filtered_y - py));
    EXPECT_LE(ea, k_address_tolerance) << where << ": address (" << got.address_x << ", " << got.address_y << ")";
    EXPECT_LE(ef, k_filtered_tolerance) << where << ": filtered (" << got.filtered_x << ", " << got.filtered_y << ")";
    worst_address = std::max(worst_address, ea);
    worst_filtered = std::max(worst_filtered, ef);
    ++mip_hits[d];

    auto caught = [&](const std::array<uint32_t, 4>& bad) {
      auto filter = [&](int c) {
        auto v = [&](size_t k) { return double((bad[k] >> (8 * c)) & 255u) / 255.0; };
        return (v(0) * (1 - fraction.x) + v(1) * fraction.x) * (1 - fraction.y) +
               (v(2) * (1 - fraction.x) + v(3) * fraction.x) * fraction.y;
      };
      const Decoded r = decode_sample(bad, {filter(0), filter(1)}, fraction, d, texels, px, py);
      return !r.ok || std::max(std::abs(r.address_x - px), std::abs(r.address_y - py)) > k_address_tolerance ||
             std::max(std::abs(r.filtered_x - px), std::abs(r.filtered_y - py)) > k_filtered_tolerance;
    };
    EXPECT_FALSE(caught(quad)) << where << ": the CPU filter disagrees with the sampler";
    // Off by one, +1 in x and -1 in y; not next to the VT edge, where clamped texels repeat.
    if (px >= 1.5 && px <= double(texels) - 1.5) ++shift_checked, shift_caught += caught(quad_at(a.slot, a.corner.x + 1, a.corner.y));
    if (py >= 1.5 && py <= double(texels) - 1.5) ++shift_checked, shift_caught += caught(quad_at(a.slot, a.corner.x, a.corner.y - 1));
    const uint32_t other = resident[(i * 7919) % resident.size()].slot;
    slot_caught += other == a.slot || caught(quad_at(other, a.corner.x, a.corner.y));
    // Border column/row B-1 (low side of the footprint) or B+P (high side) replaced by the
    // interior neighbour; not at the VT edge, where the border legitimately repeats the edge.
    for (int axis = 0; axis < 2; ++axis) {
      const int64_t c = axis == 0 ? a.corner.x : a.corner.y;
      const double pos = axis == 0 ? px : py;
      const bool low = c == B - 1, high = c + 1 == B + P;
      if (!(low || high) || pos <= 1.0 || pos >= double(texels) - 1.0) continue;
      std::array<uint32_t, 4> bad = quad;
      for (size_t k = 0; k < 4; ++k) {  // k = ix + 2 iy
        const size_t side = axis == 0 ? (k & 1) : (k >> 1);
        if (side == (low ? 0u : 1u)) bad[k] = quad[axis == 0 ? (k ^ 1) : (k ^ 2)];
      }
      ++border_checked;
      border_caught += caught(bad);
    }
  }
  RecordProperty("worst_address_error_texels", std::to_string(worst_address));
  RecordProperty("worst_filtered_error_texels", std::to_string(worst_filtered));
  std::printf("[ coord ] %s: %zu samples; worst error %.7f texel addressed, %.7f filtered; %zu border samples\n",
              place.name, count, worst_address, worst_filtered, border_checked);
  for (int m = 0; m < 4; ++m) EXPECT_GT(mip_hits[m], 50u) << "too few samples with data from mip " << m;
  EXPECT_GT(border_checked, 100u);
  EXPECT_GT(shift_checked, count);
  EXPECT_EQ(shift_caught, shift_checked);
  EXPECT_EQ(slot_caught, count);
  EXPECT_EQ(border_caught, border_checked);
}

INSTANTIATE_TEST_SUITE_P(TwoPow24, GpuCoordVt,
                         ::testing::Values(Place{"origin", 200, 90},
                                           Place{"far corner", (1u << 24) - 60, (1u << 24) - 200}),
                         [](const auto& p) { return p.index == 0 ? "NearTheOrigin" : "AtTheFarCorner"; });
