// Writes the page-store fuzz seeds into the folder given: small valid stores (plain, with a
// dictionary, one shard), each prefixed with the fuzz input's flags byte.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "streaming/bake.h"
#include "streaming/synthetic_pages.h"

namespace {

int make(const std::string& dir, const std::string& name, const tvt::StoreDesc& desc, uint32_t shard, uint32_t shards,
         uint8_t flags) {
  tvt::BakeRegion region;
  region.y1 = 512;
  region.mip_lo = 5;  // mip 6: 1 page, mip 5: 2 pages
  auto plan = tvt::bake_plan(desc.vt, region);
  if (!plan) return std::fprintf(stderr, "%s\n", plan.error().message.c_str()), 1;
  tvt::BakeOptions o;
  o.threads = 1;
  o.shard_index = shard;
  o.shard_count = shards;
  o.resume = false;
  const std::string store = dir + "/" + name + ".store";
  auto r = tvt::bake_store(store, desc, plan.value(), tvt::synthetic_source(desc, tvt::SyntheticPages{1, 0}), o);
  if (!r) return std::fprintf(stderr, "%s\n", r.error().message.c_str()), 1;
  std::ifstream in(store, std::ios::binary);
  const std::vector<char> bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  std::ofstream out(dir + "/" + name + ".tvt", std::ios::binary | std::ios::trunc);
  out.put(char(flags));
  out.write(bytes.data(), std::streamsize(bytes.size()));
  std::filesystem::remove(store);
  return out ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) return std::fprintf(stderr, "usage: make_store_seeds <folder>\n"), 2;
  const std::string dir = argv[1];
  std::filesystem::create_directories(dir);
  tvt::StoreDesc desc;
  desc.vt = tvt::VtConfig{10, 16, 2};  // 20x20 texel pages: seeds of about a kilobyte
  desc.producer = "fuzz seed";
  int failed = make(dir, "plain", desc, 0, 1, 1);
  tvt::StoreDesc with_dict = desc;
  for (int i = 0; i < 256; ++i) with_dict.dictionary.push_back(uint8_t(i * 29 + 3));
  failed |= make(dir, "dictionary", with_dict, 0, 1, 7);
  failed |= make(dir, "shard", desc, 1, 2, 3);
  return failed;
}
