// Terrain geometry on the CPU: the heightfield as a square grid of chunks over the level-0 VT
// texel grid, per-chunk LOD and frustum culling (docs/renderer.md). No Vulkan here.
//
// Chunks: chunks_per_side^2 chunks, each chunk_texels = V / chunks_per_side level-0 texels
// wide with an INTEGER origin (int64 texels). A chunk is a grid of quads_per_chunk^2 LOD-0
// quads; LOD k draws every 2^k-th vertex (step 1, 2, 4, ... quads_per_chunk). All LODs share
// one vertex buffer (grid indices i, j + skirt flag) and one index buffer with a range per LOD.
// Heights are fetched by the vertex shader from the heightfield (tvt_hf_* in
// shaders/shared/terrain_types.h); height01_at_texel() is the same computation on the CPU.
//
// Cracks between chunks of different LOD are hidden with skirts: every chunk edge has a
// vertical wall, facing outward, hanging skirt_depth_m below the edge (> the chunk's height
// range, the largest possible gap). Skirt vertices carry the texel coordinate of their edge
// vertex, so texturing stays continuous.
#pragma once
#include <cstdint>
#include <vector>

#include "compose/image.h"
#include "terrain/camera.h"
#include "vt/result.h"
#include "vt/vt_config.h"

namespace tvt {

struct TerrainMeshOptions {
  uint32_t quads_per_chunk = 32;  // LOD-0 quads per chunk side: power of two, 2 ... 256
  uint32_t chunks_per_side = 0;   // power of two; 0: heightfield texels per side / quads_per_chunk
  // LOD k (step 2^k) is used for chunks farther than lod_distances_m[k-1] from the camera
  // (distance to the chunk's bounding box, metres, increasing). Empty: chunk_m * 2^k.
  std::vector<double> lod_distances_m;
  bool skirts = true;             // false only to demonstrate cracks in tests
};

struct TerrainVertex {  // R16G16B16A16_UINT at location TVT_TERRAIN_ATTR_GRID
  uint16_t i, j;        // grid position in LOD-0 quads, 0 ... quads_per_chunk
  uint16_t skirt;       // 1: skirt vertex below (i, j)
  uint16_t pad;
};

struct LodRange {
  uint32_t first_index = 0;
  uint32_t index_count = 0;
};

struct ChunkDraw {
  int64_t origin_x = 0, origin_y = 0;  // level-0 VT texels
  uint32_t lod = 0;                    // step = 1 << lod
  double skirt_depth_m = 0.0;
  double distance_m = 0.0;             // camera to the chunk's bounding box
};

struct ChunkSelectStats {
  uint32_t total = 0;
  uint32_t culled = 0;
  std::vector<uint32_t> per_lod;  // drawn chunks per LOD
};

class TerrainMesh {
 public:
  // heightfield: 1 channel in [0,1]; extent_m: terrain edge; height_m: metres at height 1.
  static Result<TerrainMesh> create(const ImageF& heightfield, double extent_m, double height_m, const VtConfig& vt,
                                    const TerrainMeshOptions& options = {});

  // Layout.
  uint32_t log2_vt() const { return log2_vt_; }
  int64_t vt_texels() const { return int64_t(1) << log2_vt_; }
  uint32_t chunks_per_side() const { return chunks_per_side_; }
  int64_t chunk_texels() const { return chunk_texels_; }
  uint32_t quads_per_chunk() const { return options_.quads_per_chunk; }
  uint32_t quad_texels() const { return uint32_t(chunk_texels_ / options_.quads_per_chunk); }
  uint32_t lod_count() const { return uint32_t(lods_.size()); }
  double extent_m() const { return extent_m_; }
  double height_m() const { return height_m_; }
  double metres_per_texel() const { return extent_m_ / double(vt_texels()); }
  double chunk_m() const { return double(chunk_texels_) * metres_per_texel(); }
  const ImageF& heightfield() const { return heightfield_; }
  const TerrainMeshOptions& options() const { return options_; }

  // Geometry shared by all chunks.
  const std::vector<TerrainVertex>& vertices() const { return vertices_; }
  const std::vector<uint32_t>& indices() const { return indices_; }
  const LodRange& lod(uint32_t k) const { return lods_.at(k); }

  // Heights. height01_at_texel mirrors terrain.vert exactly (fixed-point addressing, fp32
  // bilinear); height_m_at is a double bilinear sample at any world position (clamped).
  float height01_at_texel(int64_t x_texel, int64_t y_texel) const;
  double height_m_at(double x_m, double y_m) const;

  // LOD of a chunk whose bounding box is distance_m away.
  uint32_t select_lod(double distance_m) const;
  // Chunks to draw for `camera` (frustum-culled on their bounding boxes, skirts included),
  // with their LOD. Order: row-major chunk order.
  std::vector<ChunkDraw> select(const Camera& camera, double aspect, ChunkSelectStats* stats = nullptr) const;

  // Bounding box of chunk (cx, cy) in world metres.
  struct Bounds {
    double min_z_m = 0.0, max_z_m = 0.0, skirt_depth_m = 0.0;
  };
  const Bounds& bounds(uint32_t cx, uint32_t cy) const { return bounds_[size_t(cy) * chunks_per_side_ + cx]; }

 private:
  ImageF heightfield_;
  double extent_m_ = 0.0, height_m_ = 0.0;
  uint32_t log2_vt_ = 0;
  uint32_t chunks_per_side_ = 0;
  int64_t chunk_texels_ = 0;
  TerrainMeshOptions options_;
  std::vector<double> lod_distances_m_;
  std::vector<TerrainVertex> vertices_;
  std::vector<uint32_t> indices_;
  std::vector<LodRange> lods_;
  std::vector<Bounds> bounds_;
};

}  // namespace tvt
