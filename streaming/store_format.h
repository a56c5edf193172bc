// Byte layout of a terravt page store, version 1 (docs/page-store.md has the table with every
// field and the reasons). Little-endian throughout.
//
//   [header 256 B][dictionary][record 0]...[record N-1][index N x 40 B]
//   record = [record header 40 B][zstd frame of one page]
//
// Every byte of a complete store is covered by a check: the header by its hash, the dictionary
// and the index by hashes in the header, record headers by their own hash (and readers compare
// them with the index entry), blobs by blob_hash, the decompressed page by page_hash; nothing
// may follow the index.
#pragma once
#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "streaming/page_store.h"

namespace tvt::store_format {

inline constexpr std::array<uint8_t, 8> k_magic = {'T', 'V', 'T', 'S', 'T', 'O', 'R', 'E'};
inline constexpr uint32_t k_version = 1;
inline constexpr uint32_t k_header_bytes = 256;
inline constexpr uint32_t k_record_magic = 0x50545654u;  // "TVTP" in file byte order
inline constexpr uint32_t k_record_header_bytes = 40;
inline constexpr uint32_t k_index_entry_bytes = 40;
inline constexpr uint32_t k_max_layers = 4;
inline constexpr uint32_t k_producer_bytes = 64;  // NUL-padded, so at most 63 bytes of text
inline constexpr uint64_t k_max_dictionary_bytes = uint64_t(1) << 26;

// Header field offsets (bytes from the start of the file).
namespace off {
inline constexpr size_t magic = 0, version = 8, header_bytes = 12, log2_size = 16, page_texels = 20,
                        border_texels = 24, layer_count = 28, layers = 32, page_bytes = 48, scene_hash = 56,
                        producer = 64, zstd_level = 128, pyramid = 132, dict_offset = 136, dict_bytes = 144,
                        dict_hash = 152, shard_index = 160, shard_count = 164, plan_pages = 168, plan_hash = 176,
                        first_plan_page = 184, page_count = 192, index_offset = 200, index_bytes = 208,
                        index_hash = 216, reserved = 224, header_hash = 248;
}  // namespace off

// Record header and index entry field offsets.
namespace rec {
inline constexpr size_t magic = 0, stored_bytes = 4, page = 8, blob_hash = 16, page_hash = 24, header_hash = 32;
}
namespace idx {
inline constexpr size_t page = 0, offset = 8, stored_bytes = 16, reserved = 20, blob_hash = 24, page_hash = 32;
}

uint64_t hash(std::span<const uint8_t> bytes);  // XXH3-64, seed 0

inline void put_u32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = uint8_t(v >> (8 * i));
}
inline void put_u64(uint8_t* p, uint64_t v) {
  for (int i = 0; i < 8; ++i) p[i] = uint8_t(v >> (8 * i));
}
inline uint32_t get_u32(const uint8_t* p) {
  uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}
inline uint64_t get_u64(const uint8_t* p) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

struct Header {
  StoreDesc desc;  // dictionary left empty: it follows the header
  uint64_t page_bytes = 0;
  uint64_t dict_offset = 0, dict_bytes = 0, dict_hash = 0;
  StoreLayout layout;
  uint64_t page_count = 0;
  uint64_t index_offset = 0, index_bytes = 0, index_hash = 0;  // all 0 while a bake is in progress

  uint64_t records_offset() const { return k_header_bytes + dict_bytes; }
};

// The header a bake of `desc` for this plan/shard starts with (index fields 0).
Header make_header(const StoreDesc& desc, const StoreLayout& layout, uint64_t page_count);
std::array<uint8_t, k_header_bytes> encode_header(const Header& header);  // fills header_hash

// Decodes and checks a complete store's header against the file size. Appends one line per
// problem ("<path>: header <field>: <what>") and returns nullopt when there was any; stops
// after structural problems (magic, version, checksum) that make the other fields meaningless.
std::optional<Header> decode_header(std::span<const uint8_t> bytes, uint64_t file_bytes, const std::string& path,
                                    std::vector<std::string>& problems);

struct RecordHeader {
  uint64_t page = 0;  // packed PageId
  uint32_t stored_bytes = 0;
  uint64_t blob_hash = 0, page_hash = 0;
};
void encode_record_header(const RecordHeader& r, uint8_t* out);  // k_record_header_bytes
// False if the magic or the record header's own hash is wrong.
bool decode_record_header(const uint8_t* in, RecordHeader& out);

void encode_index_entry(const StoreEntry& e, uint8_t* out);  // k_index_entry_bytes
StoreEntry decode_index_entry(const uint8_t* in, uint32_t* reserved);

// Largest zstd frame a page of `page_bytes` can compress to (ZSTD_compressBound).
uint64_t max_stored_bytes(uint64_t page_bytes);

// "<path>: mip M page (X,Y)" for page-level messages.
std::string page_where(const std::string& path, const PageId& page);

}  // namespace tvt::store_format
