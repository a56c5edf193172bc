// merge_stores: shard stores -> the store a single bake of the whole plan writes, byte for byte.
// Records are copied (after checking record header and blob hash), never recompressed.
#include <chrono>
#include <map>
#include <memory>

#include "streaming/bake.h"
#include "streaming/store_writer.h"

namespace tvt {

namespace sf = store_format;

namespace {

// First field in which two descs differ, for "not from the same bake" messages.
std::string desc_difference(const StoreDesc& a, const StoreDesc& b) {
  if (a.vt.log2_size != b.vt.log2_size || a.vt.page_texels != b.vt.page_texels || a.vt.border_texels != b.vt.border_texels)
    return "vt";
  if (a.layers != b.layers) return "layers";
  if (a.scene_hash != b.scene_hash) return "scene_hash";
  if (a.producer != b.producer) return "producer";
  if (a.zstd_level != b.zstd_level) return "zstd_level";
  if (a.dictionary != b.dictionary) return "dictionary";
  if (a.pyramid != b.pyramid) return "pyramid";
  return {};
}

}  // namespace

Result<BakeSummary> merge_stores(std::span<const std::string> parts, const std::string& path) {
  const auto t0 = std::chrono::steady_clock::now();
  if (parts.empty()) return make_error(path + ": merge: no shard stores given");
  std::vector<std::unique_ptr<PageStoreReader>> readers;
  for (const std::string& part : parts) {
    auto r = PageStoreReader::open(part);
    if (!r) return r.error();
    readers.push_back(std::move(r.value()));
  }
  const PageStoreReader& ref = *readers.front();
  const StoreLayout& rl = ref.layout();
  // By shard index; a map, not a vector of shard_count: that count comes from a file.
  std::map<uint32_t, const PageStoreReader*> by_shard;
  for (const auto& r : readers) {
    const StoreLayout& l = r->layout();
    if (const std::string field = desc_difference(r->desc(), ref.desc()); !field.empty())
      return make_error(r->path() + ": header " + field + ": differs from " + ref.path() + " (not shards of the same bake)");
    if (l.shard_count != rl.shard_count)
      return make_error(r->path() + ": header shard_count: " + std::to_string(l.shard_count) + ", but " + ref.path() +
                        " has " + std::to_string(rl.shard_count) + " (not shards of the same bake)");
    if (l.plan_pages != rl.plan_pages || l.plan_hash != rl.plan_hash)
      return make_error(r->path() + ": header plan_hash: another plan than " + ref.path() + " (not shards of the same bake)");
    if (const auto it = by_shard.find(l.shard_index); it != by_shard.end())
      return make_error(r->path() + ": header shard_index: shard " + std::to_string(l.shard_index) + " of " +
                        std::to_string(l.shard_count) + " is given twice (also " + it->second->path() + ")");
    by_shard[l.shard_index] = r.get();
  }
  // Every index below shard_count must be there: the first one missing is at most parts.size().
  for (uint64_t i = 0; i < rl.shard_count && i <= parts.size(); ++i)
    if (!by_shard.contains(uint32_t(i))) {
      const ShardRange sr = shard_range(rl.plan_pages, uint32_t(i), rl.shard_count);
      return make_error(path + ": merge: shard " + std::to_string(i) + " of " + std::to_string(rl.shard_count) +
                        " (plan pages [" + std::to_string(sr.first) + ", +" + std::to_string(sr.count) + ")) is missing");
    }
  std::vector<PageId> plan;
  plan.reserve(rl.plan_pages);
  for (const auto& [index, r] : by_shard)
    for (const StoreEntry& e : r->entries()) plan.push_back(e.page);
  if (plan.size() != rl.plan_pages || plan_hash(plan) != rl.plan_hash)
    return make_error(path + ": merge: the shards' pages do not form their plan (plan_hash mismatch)");

  const StoreDesc& desc = ref.desc();
  const sf::Header header = sf::make_header(desc, StoreLayout{0, 1, rl.plan_pages, rl.plan_hash, 0}, rl.plan_pages);
  auto opened = sf::StoreWriter::open(path);
  if (!opened) return opened.error();
  sf::StoreWriter& writer = opened.value();
  if (auto s = writer.start(sf::encode_header(header), desc.dictionary); !s) return s.error();
  for (const auto& [index, r] : by_shard) {
    auto decoder = r->make_decoder();
    for (const StoreEntry& e : r->entries()) {
      std::string message;
      if (r->read_blob(e.page, *decoder, &message) != PageError::none) {
        writer.discard();
        return make_error(message + " (merge stopped; " + path + " not written)");
      }
      if (auto s = writer.append(e.page, decoder->blob(), e.blob_hash, e.page_hash); !s) {
        writer.discard();
        return s.error();
      }
    }
  }
  auto file_bytes = writer.finish(header);
  if (!file_bytes) {
    writer.discard();
    return file_bytes.error();
  }
  BakeSummary summary;
  summary.pages = rl.plan_pages;
  summary.raw_bytes = rl.plan_pages * ref.page_bytes();
  summary.stored_bytes = writer.stored_bytes();
  summary.file_bytes = file_bytes.value();
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return summary;
}

}  // namespace tvt
