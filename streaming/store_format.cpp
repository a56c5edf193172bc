#include "streaming/store_format.h"

#include <xxhash.h>
#include <zstd.h>

#include <algorithm>
#include <cstring>

namespace tvt::store_format {

uint64_t hash(std::span<const uint8_t> bytes) { return XXH3_64bits(bytes.data(), bytes.size()); }

uint64_t max_stored_bytes(uint64_t page_bytes) { return ZSTD_compressBound(size_t(page_bytes)); }

std::string page_where(const std::string& path, const PageId& page) {
  return path + ": mip " + std::to_string(page.mip) + " page (" + std::to_string(page.x) + "," +
         std::to_string(page.y) + ")";
}

Header make_header(const StoreDesc& desc, const StoreLayout& layout, uint64_t page_count) {
  Header h;
  h.desc = desc;
  h.desc.dictionary.clear();
  h.page_bytes = desc.page_bytes();
  if (!desc.dictionary.empty()) {
    h.dict_offset = k_header_bytes;
    h.dict_bytes = desc.dictionary.size();
    h.dict_hash = hash(desc.dictionary);
  }
  h.layout = layout;
  h.page_count = page_count;
  return h;
}

std::array<uint8_t, k_header_bytes> encode_header(const Header& h) {
  std::array<uint8_t, k_header_bytes> b{};
  uint8_t* p = b.data();
  std::memcpy(p + off::magic, k_magic.data(), k_magic.size());
  put_u32(p + off::version, k_version);
  put_u32(p + off::header_bytes, k_header_bytes);
  put_u32(p + off::log2_size, h.desc.vt.log2_size);
  put_u32(p + off::page_texels, h.desc.vt.page_texels);
  put_u32(p + off::border_texels, h.desc.vt.border_texels);
  put_u32(p + off::layer_count, uint32_t(h.desc.layers.size()));
  for (size_t i = 0; i < h.desc.layers.size() && i < k_max_layers; ++i)
    put_u32(p + off::layers + 4 * i, uint32_t(h.desc.layers[i]));
  put_u64(p + off::page_bytes, h.page_bytes);
  put_u64(p + off::scene_hash, h.desc.scene_hash);
  std::memcpy(p + off::producer, h.desc.producer.data(), std::min<size_t>(h.desc.producer.size(), k_producer_bytes - 1));
  put_u32(p + off::zstd_level, uint32_t(h.desc.zstd_level));
  put_u32(p + off::pyramid, uint32_t(h.desc.pyramid));
  put_u64(p + off::dict_offset, h.dict_offset);
  put_u64(p + off::dict_bytes, h.dict_bytes);
  put_u64(p + off::dict_hash, h.dict_hash);
  put_u32(p + off::shard_index, h.layout.shard_index);
  put_u32(p + off::shard_count, h.layout.shard_count);
  put_u64(p + off::plan_pages, h.layout.plan_pages);
  put_u64(p + off::plan_hash, h.layout.plan_hash);
  put_u64(p + off::first_plan_page, h.layout.first_plan_page);
  put_u64(p + off::page_count, h.page_count);
  put_u64(p + off::index_offset, h.index_offset);
  put_u64(p + off::index_bytes, h.index_bytes);
  put_u64(p + off::index_hash, h.index_hash);
  put_u64(p + off::header_hash, hash({p, off::header_hash}));
  return b;
}

std::optional<Header> decode_header(std::span<const uint8_t> bytes, uint64_t file_bytes, const std::string& path,
                                    std::vector<std::string>& problems) {
  const std::string at = path + ": header ";
  if (bytes.size() < k_header_bytes || file_bytes < k_header_bytes) {
    problems.push_back(path + ": file is " + std::to_string(file_bytes) + " bytes, shorter than the " +
                       std::to_string(k_header_bytes) + "-byte header (truncated, or not a page store)");
    return std::nullopt;
  }
  const uint8_t* p = bytes.data();
  if (std::memcmp(p, k_magic.data(), k_magic.size()) != 0) {
    problems.push_back(at + "magic: not a terravt page store (expected \"TVTSTORE\")");
    return std::nullopt;
  }
  if (const uint32_t v = get_u32(p + off::version); v != k_version) {
    problems.push_back(at + "version: unsupported version " + std::to_string(v) + " (this build reads version " +
                       std::to_string(k_version) + ")");
    return std::nullopt;
  }
  if (const uint32_t hb = get_u32(p + off::header_bytes); hb != k_header_bytes) {
    problems.push_back(at + "header_bytes: must be " + std::to_string(k_header_bytes) + " in version 1, got " +
                       std::to_string(hb));
    return std::nullopt;
  }
  if (get_u64(p + off::header_hash) != hash({p, off::header_hash})) {
    problems.push_back(at + "header_hash: checksum mismatch (the header is damaged)");
    return std::nullopt;
  }

  const size_t before = problems.size();
  auto bad = [&](const char* field, const std::string& what) {  // returns false: `ok = bad(...)`
    problems.push_back(at + field + ": " + what);
    return false;
  };
  Header h;
  h.desc.vt.log2_size = get_u32(p + off::log2_size);
  h.desc.vt.page_texels = get_u32(p + off::page_texels);
  h.desc.vt.border_texels = get_u32(p + off::border_texels);
  const Status vt_status = validate(h.desc.vt, path + ": header vt");
  const bool vt_ok = vt_status.ok();
  if (!vt_ok) problems.push_back(vt_status.error().message);

  const uint32_t layer_count = get_u32(p + off::layer_count);
  bool layers_ok = layer_count >= 1 && layer_count <= k_max_layers;
  if (!layers_ok) bad("layer_count", "must be 1 to 4, got " + std::to_string(layer_count));
  h.desc.layers.clear();
  for (uint32_t i = 0; i < k_max_layers; ++i) {
    const uint32_t f = get_u32(p + off::layers + 4 * i);
    if (i < layer_count) {
      if (f != uint32_t(PageLayerFormat::rgba8_albedo_height)) {
        bad(("layers[" + std::to_string(i) + "]").c_str(), "unknown page format " + std::to_string(f));
        layers_ok = false;
      }
      h.desc.layers.push_back(PageLayerFormat(f));
    } else if (f != 0) {
      bad(("layers[" + std::to_string(i) + "]").c_str(), "unused layer slot must be 0, got " + std::to_string(f));
    }
  }
  h.page_bytes = get_u64(p + off::page_bytes);
  if (vt_ok && layers_ok && h.page_bytes != h.desc.page_bytes())
    bad("page_bytes", std::to_string(h.page_bytes) + " does not match the VT and layers (expected " +
                          std::to_string(h.desc.page_bytes()) + ")");
  h.desc.scene_hash = get_u64(p + off::scene_hash);

  const uint8_t* prod = p + off::producer;
  const size_t len = size_t(std::find(prod, prod + k_producer_bytes, uint8_t(0)) - prod);
  if (len == k_producer_bytes) {
    bad("producer", "not NUL-terminated within 64 bytes");
  } else {
    if (std::any_of(prod + len, prod + k_producer_bytes, [](uint8_t c) { return c != 0; }))
      bad("producer", "bytes after the terminating NUL must be 0");
    h.desc.producer.assign(reinterpret_cast<const char*>(prod), len);
  }
  h.desc.zstd_level = int32_t(get_u32(p + off::zstd_level));
  if (!((h.desc.zstd_level >= 1 && h.desc.zstd_level <= 19) || (h.desc.zstd_level >= -5 && h.desc.zstd_level <= -1)))
    bad("zstd_level", "must be 1..19 or -5..-1, got " + std::to_string(h.desc.zstd_level));
  // Was a reserved 0 before filtered stores existed: older stores read as `composed`.
  const uint32_t pyramid = get_u32(p + off::pyramid);
  if (pyramid > uint32_t(StorePyramid::filtered))
    bad("pyramid", "must be 0 (composed) or 1 (filtered), got " + std::to_string(pyramid));
  h.desc.pyramid = StorePyramid(std::min(pyramid, uint32_t(StorePyramid::filtered)));
  if (std::any_of(p + off::reserved, p + off::header_hash, [](uint8_t c) { return c != 0; }))
    bad("reserved", "reserved bytes must be 0");

  h.dict_offset = get_u64(p + off::dict_offset);
  h.dict_bytes = get_u64(p + off::dict_bytes);
  h.dict_hash = get_u64(p + off::dict_hash);
  bool dict_ok = true;
  if (h.dict_bytes == 0) {
    if (h.dict_offset != 0 || h.dict_hash != 0) dict_ok = bad("dict_offset", "must be 0 (with dict_hash) when dict_bytes is 0");
  } else {
    if (h.dict_offset != k_header_bytes)
      dict_ok = bad("dict_offset", "must be " + std::to_string(k_header_bytes) + ", got " + std::to_string(h.dict_offset));
    if (h.dict_bytes > k_max_dictionary_bytes || h.dict_bytes > file_bytes - k_header_bytes)
      dict_ok = bad("dict_bytes", std::to_string(h.dict_bytes) + " bytes do not fit in the file (" +
                                      std::to_string(file_bytes) + " bytes) or exceed the 64 MiB limit");
  }

  h.layout.shard_index = get_u32(p + off::shard_index);
  h.layout.shard_count = get_u32(p + off::shard_count);
  h.layout.plan_pages = get_u64(p + off::plan_pages);
  h.layout.plan_hash = get_u64(p + off::plan_hash);
  h.layout.first_plan_page = get_u64(p + off::first_plan_page);
  h.page_count = get_u64(p + off::page_count);
  h.index_offset = get_u64(p + off::index_offset);
  h.index_bytes = get_u64(p + off::index_bytes);
  h.index_hash = get_u64(p + off::index_hash);
  bool layout_ok = true;
  if (h.layout.shard_count == 0 || h.layout.shard_index >= h.layout.shard_count)
    layout_ok = bad("shard_index", "shard " + std::to_string(h.layout.shard_index) + " of " +
                                       std::to_string(h.layout.shard_count) + " is not a valid shard");
  if (h.layout.plan_pages == 0 || h.layout.plan_pages > k_max_plan_pages)
    layout_ok = bad("plan_pages", "must be 1 to " + std::to_string(k_max_plan_pages) + ", got " +
                                      std::to_string(h.layout.plan_pages));
  if (layout_ok) {
    const ShardRange r = shard_range(h.layout.plan_pages, h.layout.shard_index, h.layout.shard_count);
    if (r.first != h.layout.first_plan_page || r.count != h.page_count)
      layout_ok = bad("page_count", "pages [" + std::to_string(h.layout.first_plan_page) + ", +" + std::to_string(h.page_count) +
                            ") are not shard " + std::to_string(h.layout.shard_index) + " of " +
                            std::to_string(h.layout.shard_count) + " of a " + std::to_string(h.layout.plan_pages) +
                            "-page plan (expected [" + std::to_string(r.first) + ", +" + std::to_string(r.count) + "))");
  }
  if (layout_ok && dict_ok) {
    // page_count <= 2^28 here, so none of these products overflow.
    if (h.index_bytes != h.page_count * k_index_entry_bytes)
      bad("index_bytes", "must be page_count x " + std::to_string(k_index_entry_bytes) + " = " +
                             std::to_string(h.page_count * k_index_entry_bytes) + ", got " + std::to_string(h.index_bytes));
    else if (h.index_offset < h.records_offset() + h.page_count * (k_record_header_bytes + 1) ||
             h.index_offset > file_bytes || file_bytes - h.index_offset != h.index_bytes)
      bad("index_offset", "the index [" + std::to_string(h.index_offset) + ", +" + std::to_string(h.index_bytes) +
                              ") must follow the records and end at the end of the file (" + std::to_string(file_bytes) +
                              " bytes): truncated, or trailing data");
  }
  if (problems.size() != before) return std::nullopt;
  return h;
}

void encode_record_header(const RecordHeader& r, uint8_t* out) {
  put_u32(out + rec::magic, k_record_magic);
  put_u32(out + rec::stored_bytes, r.stored_bytes);
  put_u64(out + rec::page, r.page);
  put_u64(out + rec::blob_hash, r.blob_hash);
  put_u64(out + rec::page_hash, r.page_hash);
  put_u64(out + rec::header_hash, hash({out, rec::header_hash}));
}

bool decode_record_header(const uint8_t* in, RecordHeader& out) {
  if (get_u32(in + rec::magic) != k_record_magic) return false;
  if (get_u64(in + rec::header_hash) != hash({in, rec::header_hash})) return false;
  out.stored_bytes = get_u32(in + rec::stored_bytes);
  out.page = get_u64(in + rec::page);
  out.blob_hash = get_u64(in + rec::blob_hash);
  out.page_hash = get_u64(in + rec::page_hash);
  return true;
}

void encode_index_entry(const StoreEntry& e, uint8_t* out) {
  put_u64(out + idx::page, e.page.pack());
  put_u64(out + idx::offset, e.offset);
  put_u32(out + idx::stored_bytes, e.stored_bytes);
  put_u32(out + idx::reserved, 0);
  put_u64(out + idx::blob_hash, e.blob_hash);
  put_u64(out + idx::page_hash, e.page_hash);
}

StoreEntry decode_index_entry(const uint8_t* in, uint32_t* reserved) {
  StoreEntry e;
  e.page = PageId::unpack(get_u64(in + idx::page));
  e.offset = get_u64(in + idx::offset);
  e.stored_bytes = get_u32(in + idx::stored_bytes);
  if (reserved) *reserved = get_u32(in + idx::reserved);
  e.blob_hash = get_u64(in + idx::blob_hash);
  e.page_hash = get_u64(in + idx::page_hash);
  return e;
}

}  // namespace tvt::store_format
