// Stored megatexture (docs/page-store.md): one file of zstd-compressed pages with a checked header and
// index, read with pread from many threads. Layout and rationale: docs/page-store.md; the byte
// layout itself is in streaming/store_format.h.
//
// Errors follow vt/result.h: messages start with the file path, then the field
// ("store.tvt: index entry 17 (mip 2 page (3,1)): stored size 0 ...",
// "store.tvt: mip 3 page (5,2): blob checksum mismatch ...").
#pragma once
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "vt/result.h"
#include "vt/vt_config.h"

// zstd's opaque contexts (zstd.h), so that this header does not pull zstd into every user.
struct ZSTD_DCtx_s;
struct ZSTD_CCtx_s;
struct ZSTD_DDict_s;
struct ZSTD_CDict_s;

namespace tvt {

enum class PageLayerFormat : uint32_t { rgba8_albedo_height = 1 };  // (P+2B)^2 * 4 bytes per layer
std::string_view to_string(PageLayerFormat format);

// Which mip pyramid a store holds (header field `pyramid`; stores written before the field
// existed hold 0 there and read as `composed`). docs/page-store.md, "Filtered pyramid".
enum class StorePyramid : uint32_t {
  composed = 0,  // every page composed at its own mip: byte-identical to what the VT composes
  filtered = 1,  // level 0 composed; every texel of a mip-m page the box filter of mip m-1
};
std::string_view to_string(StorePyramid pyramid);  // "composed", "filtered"

struct StoreDesc {  // what a store holds; written in the header
  VtConfig vt;      // log2_size, page_texels, border_texels
  std::vector<PageLayerFormat> layers{PageLayerFormat::rgba8_albedo_height};  // 1..4
  uint64_t scene_hash = 0;          // identifies scene + method + producer params (0: unknown)
  std::string producer;             // free text <= 63 bytes, e.g. "gpu fbpb+dpt2"
  int zstd_level = 3;               // 1..19 (negative fast levels allowed: -5..-1)
  std::vector<uint8_t> dictionary;  // zstd dictionary, empty: none (stored in the file)
  StorePyramid pyramid = StorePyramid::composed;
  uint64_t page_bytes() const;      // raw bytes of one page, all layers

  friend bool operator==(const StoreDesc&, const StoreDesc&);
};

// Checks every field a store header can hold; `where` prefixes messages ("out.tvt: desc").
Status validate(const StoreDesc& desc, const std::string& where);

struct StoreEntry {          // one index entry
  PageId page;
  uint64_t offset = 0;       // of the compressed blob in the file (its record header is just before)
  uint32_t stored_bytes = 0; // compressed size
  uint64_t blob_hash = 0;    // XXH3-64 of the compressed bytes (libxxhash)
  uint64_t page_hash = 0;    // XXH3-64 of the decompressed page
};

enum class PageError : uint8_t { none, missing, io, truncated, corrupt };
std::string_view to_string(PageError error);

// Bake order: mips from coarsest to finest (`filtered`: finest to coarsest, so that the finer
// mip a page is filtered from is in the store before it), then y, then x. Pages of mips [mip_lo, mip_hi]
// whose footprint intersects the level-0 texel rectangle [x0,x1)×[y0,y1) (default: whole VT).
// Coordinates beyond the VT and mip_hi beyond the top mip are clamped.
struct BakeRegion {
  uint64_t x0 = 0, y0 = 0, x1 = UINT64_MAX, y1 = UINT64_MAX;
  uint32_t mip_lo = 0, mip_hi = UINT32_MAX;
};
inline constexpr uint64_t k_max_plan_pages = uint64_t(1) << 28;  // bake larger terrains in regions
// Errors on an empty or invalid region.
Result<std::vector<PageId>> bake_plan(const VtConfig& vt, const BakeRegion& region,
                                      StorePyramid order = StorePyramid::composed);
// bake_plan(vt, region).size() without enumerating the plan (same errors).
Result<uint64_t> bake_plan_pages(const VtConfig& vt, const BakeRegion& region);

// Deterministic part i of n of a plan of `count` pages: [first, first+count). The first
// `plan_pages % n` parts get one page more. {0, 0} when n == 0 or i >= n.
struct ShardRange {
  uint64_t first = 0, count = 0;
  friend bool operator==(const ShardRange&, const ShardRange&) = default;
};
ShardRange shard_range(uint64_t plan_pages, uint32_t index, uint32_t count);

// XXH3-64 of the plan's packed page ids (little-endian uint64 each): the plan hash in headers.
uint64_t plan_hash(std::span<const PageId> plan);

// Where a (possibly sharded) store sits in its bake; read from the header.
struct StoreLayout {
  uint32_t shard_index = 0, shard_count = 1;
  uint64_t plan_pages = 0, plan_hash = 0, first_plan_page = 0;
};

class PageStoreReader {
 public:
  // Per-thread decoding state: the ZSTD_DCtx (with the store's dictionary) and a read buffer.
  // Created by make_decoder(); not thread-safe itself; must not outlive its reader.
  class Decoder {
   public:
    ~Decoder();
    Decoder(const Decoder&) = delete;
    Decoder& operator=(const Decoder&) = delete;
    // The record read by the last successful read_blob(): the compressed bytes.
    std::span<const uint8_t> blob() const { return {buffer_.data() + blob_at_, blob_bytes_}; }

   private:
    friend class PageStoreReader;
    Decoder() = default;
    ZSTD_DCtx_s* dctx_ = nullptr;
    std::vector<uint8_t> buffer_;  // record header + blob; at most 40 + ZSTD_compressBound(page_bytes)
    size_t blob_at_ = 0, blob_bytes_ = 0;
  };

  // Reads and validates header and index (their own checksums, sizes, offsets inside the file,
  // no duplicate pages, pages valid for the VT). Never trusts a size field before checking it
  // against the file size.
  static Result<std::unique_ptr<PageStoreReader>> open(const std::string& path);
  // Like open(), but lists every header and index problem it can find instead of stopping at
  // the first (for verify_store). Returns nullptr when any was found.
  static std::unique_ptr<PageStoreReader> open_collect(const std::string& path, std::vector<std::string>& problems);
  ~PageStoreReader();
  PageStoreReader(const PageStoreReader&) = delete;
  PageStoreReader& operator=(const PageStoreReader&) = delete;

  const std::string& path() const { return path_; }
  const StoreDesc& desc() const { return desc_; }
  uint64_t page_bytes() const { return page_bytes_; }
  uint64_t file_bytes() const { return file_bytes_; }
  const StoreLayout& layout() const { return layout_; }
  std::span<const StoreEntry> entries() const { return entries_; }  // bake order
  const StoreEntry* find(const PageId& page) const;                  // nullptr if absent; O(1)
  bool contains(const PageId& page) const { return find(page) != nullptr; }

  std::unique_ptr<Decoder> make_decoder() const;
  // Thread-safe (pread). Reads, verifies blob_hash, decompresses into `out` (exactly
  // page_bytes), verifies page_hash. `out` may be written even on error; callers discard it.
  // `message` (optional) gets "<path>: mip M page (X,Y): <what>" on error.
  PageError read_page(const PageId& page, std::span<uint8_t> out, Decoder& decoder, std::string* message = nullptr) const;
  // The two halves of read_page, for timing them apart (benchmarks, the loader):
  // read_blob reads the page's record (header + compressed bytes) into the decoder, checks the
  // record header against the index entry and the blob hash; decoder.blob() is then valid.
  PageError read_blob(const PageId& page, Decoder& decoder, std::string* message = nullptr) const;
  // decode_blob decompresses decoder.blob() of `page` into `out` and checks page_hash.
  PageError decode_blob(const PageId& page, std::span<uint8_t> out, Decoder& decoder, std::string* message = nullptr) const;

 private:
  PageStoreReader() = default;
  static std::unique_ptr<PageStoreReader> open_impl(const std::string& path, std::vector<std::string>& problems,
                                                    bool collect);

  std::string path_;
  int fd_ = -1;
  StoreDesc desc_;
  StoreLayout layout_;
  uint64_t page_bytes_ = 0, file_bytes_ = 0;
  std::vector<StoreEntry> entries_;
  std::unordered_map<uint64_t, uint32_t> by_page_;  // packed page id -> entry index
  ZSTD_DDict_s* ddict_ = nullptr;                   // shared by all decoders (read-only in zstd)
};

// Per-thread zstd compressor with the store's level and dictionary. Not thread-safe; one per
// worker. `desc` must be valid (validate()).
class PageCompressor {
 public:
  explicit PageCompressor(const StoreDesc& desc);
  ~PageCompressor();
  PageCompressor(const PageCompressor&) = delete;
  PageCompressor& operator=(const PageCompressor&) = delete;
  std::vector<uint8_t> compress(std::span<const uint8_t> page) const;  // deterministic

 private:
  ZSTD_CCtx_s* cctx_ = nullptr;  // mutable state behind a const interface: reused between pages
  ZSTD_CDict_s* cdict_ = nullptr;
  int level_ = 3;
};

// Per-thread zstd decompressor with the store's dictionary, for pages a bake reads back from its
// own partial file. Not thread-safe; `desc` must be valid.
class PageDecompressor {
 public:
  explicit PageDecompressor(const StoreDesc& desc);
  ~PageDecompressor();
  PageDecompressor(const PageDecompressor&) = delete;
  PageDecompressor& operator=(const PageDecompressor&) = delete;
  // Decompresses one zstd frame into exactly out.size() bytes; false when it does not.
  bool decompress(std::span<const uint8_t> blob, std::span<uint8_t> out) const;

 private:
  ZSTD_DCtx_s* dctx_ = nullptr;
  ZSTD_DDict_s* ddict_ = nullptr;
};

// Trains a zstd dictionary (ZDICT) from sample pages; deterministic for the same samples.
Result<std::vector<uint8_t>> train_dictionary(std::span<const std::vector<uint8_t>> samples, size_t dict_bytes);

}  // namespace tvt
