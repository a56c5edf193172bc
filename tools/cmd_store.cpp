// Page-store tools: `terravt merge` (join shard parts into the store a single bake writes),
// `terravt verify` (every page checked, every problem printed), `terravt info` (config and
// statistics). Format: docs/page-store.md.
#include <filesystem>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <map>
#include <memory>

#include "streaming/bake.h"
#include "streaming/page_store.h"
#include "tools/cli_common.h"
#include "tools/commands.h"

namespace tvt::cli {
namespace {

struct MergeArgs {
  std::vector<std::string> parts;
  std::string out;
  bool overwrite = false;  // replace an existing --out store
};

int run_merge(const MergeArgs& a) {
  FlaggedPaths parts;
  for (size_t i = 0; i < a.parts.size(); ++i) parts.push_back({"part " + std::to_string(i + 1), a.parts[i]});
  if (auto problem = output_collision({{"--out", a.out}}, parts)) return fail("merge", *problem, 2);
  if (auto s = check_output_file("--out", a.out, a.overwrite); !s) return fail("merge", s.error().message, 2);
  auto s = merge_stores(a.parts, a.out);
  if (!s) return fail("merge", s.error().message, 1);
  std::printf("merged %zu parts: %llu pages, %.1f MB -> %s\n", a.parts.size(), (unsigned long long)s->pages,
              double(s->file_bytes) / 1e6, a.out.c_str());
  return 0;
}

const CommandRegistrar k_merge{
    "merge", "Join the parts of a sharded bake (bake --shard i/n) into one store", 41, [](CLI::App& app) -> RunFn {
      auto a = std::make_shared<MergeArgs>();
      app.add_option("parts", a->parts, "Shard stores, any order")->required()->check(regular_file());
      app.add_option("--out", a->out, "Merged store (written atomically)")->required();
      app.add_flag("--overwrite", a->overwrite, "Replace an existing --out store (otherwise an error)");
      return [a] { return run_merge(*a); };
    }};

struct VerifyArgs {
  std::string store;
  uint32_t threads = 0;
  uint32_t max_lines = 50;
  std::string salvage;     // write the intact records to this new store
  bool overwrite = false;  // replace an existing --salvage file
};

int run_verify(const VerifyArgs& a) {
  if (a.threads > k_max_verify_threads)
    return fail("verify", "--threads: must be between 0 (one per core) and " + std::to_string(k_max_verify_threads) +
                              ", got " + std::to_string(a.threads), 2);
  auto r = verify_store(a.store, a.threads);
  if (!r) return fail("verify", r.error().message, 1);
  const VerifyReport& v = r.value();
  for (size_t i = 0; i < v.problems.size() && i < a.max_lines; ++i) std::printf("%s\n", v.problems[i].c_str());
  if (v.problems.size() > a.max_lines) std::printf("... and %zu more problems\n", v.problems.size() - a.max_lines);
  if (v.pyramid == StorePyramid::filtered)
    std::printf("%s: filtered pyramid: %llu coarse pages checked to be the box filter of the finer mip\n", a.store.c_str(),
                (unsigned long long)v.filter_checked);
  std::printf("%s: %llu of %llu pages ok, %zu problems\n", a.store.c_str(), (unsigned long long)v.ok,
              (unsigned long long)v.pages, v.problems.size());
  if (a.salvage.empty()) {
    if (!v.problems.empty()) std::printf("(terravt verify %s --salvage NEW.tvt writes its intact pages to a new store)\n", a.store.c_str());
    return v.problems.empty() ? 0 : 1;
  }
  auto s = salvage_store(a.store, a.salvage, a.overwrite);
  if (!s) return fail("verify", "--salvage: " + s.error().message, 1);
  std::printf("salvaged %llu pages (the header lists %llu; %llu duplicate records and %llu other bytes skipped) into %s, "
              "%llu bytes, in %.2f s\n",
              (unsigned long long)s->pages, (unsigned long long)s->declared_pages, (unsigned long long)s->duplicates,
              (unsigned long long)s->skipped_bytes, a.salvage.c_str(), (unsigned long long)s->file_bytes, s->seconds);
  return 0;
}

const CommandRegistrar k_verify{
    "verify", "Check a page store page by page and print what is wrong", 42, [](CLI::App& app) -> RunFn {
      auto a = std::make_shared<VerifyArgs>();
      app.add_option("store", a->store, "Page store file")->required();
      app.add_option("--threads", a->threads, "Reader threads (0: all cores)")->capture_default_str();
      app.add_option("--max-lines", a->max_lines, "Problems printed at most")->capture_default_str();
      app.add_option("--salvage", a->salvage,
                     "Also write every intact page record to this new store (the index may be lost or damaged; "
                     "needs an intact header)");
      app.add_flag("--overwrite", a->overwrite, "Replace an existing --salvage file");
      return [a] { return run_verify(*a); };
    }};

struct InfoArgs {
  std::string store;
  bool json = false;
};

int run_info(const InfoArgs& a) {
  auto opened = PageStoreReader::open(a.store);
  if (!opened) return fail("info", opened.error().message, 1);
  const PageStoreReader& r = *opened.value();
  const StoreDesc& d = r.desc();
  struct MipStats {
    uint64_t pages = 0, stored = 0, min = UINT64_MAX, max = 0;
  };
  std::map<uint32_t, MipStats> mips;
  uint64_t stored = 0;
  for (const StoreEntry& e : r.entries()) {
    MipStats& m = mips[e.page.mip];
    ++m.pages;
    m.stored += e.stored_bytes;
    m.min = std::min<uint64_t>(m.min, e.stored_bytes);
    m.max = std::max<uint64_t>(m.max, e.stored_bytes);
    stored += e.stored_bytes;
  }
  const uint64_t raw = d.page_bytes() * r.entries().size();
  if (a.json) {
    nlohmann::json j;
    j["file"] = a.store;
    j["file_bytes"] = r.file_bytes();
    j["vt"] = {{"log2_size", d.vt.log2_size}, {"page_texels", d.vt.page_texels}, {"border_texels", d.vt.border_texels}};
    j["page_bytes"] = d.page_bytes();
    j["producer"] = d.producer;
    j["scene_hash"] = d.scene_hash;
    j["zstd_level"] = d.zstd_level;
    j["pyramid"] = std::string(to_string(d.pyramid));
    j["dictionary_bytes"] = d.dictionary.size();
    j["pages"] = r.entries().size();
    j["raw_bytes"] = raw;
    j["stored_bytes"] = stored;
    for (const auto& [mip, m] : mips)
      j["mips"].push_back({{"mip", mip}, {"pages", m.pages}, {"stored_bytes", m.stored},
                           {"bytes_per_page", double(m.stored) / double(m.pages)},
                           {"of_mip", d.vt.pages_per_side(mip) * d.vt.pages_per_side(mip)}});
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }
  std::printf("%s: %.2f MB\n", a.store.c_str(), double(r.file_bytes()) / 1e6);
  std::printf("  VT: V = 2^%u texels, pages %u + 2x%u border (%llu bytes raw), %u mips\n", d.vt.log2_size,
              d.vt.page_texels, d.vt.border_texels, (unsigned long long)d.page_bytes(), d.vt.mip_count());
  std::printf("  producer: %s, scene %016llx, %s pyramid, zstd level %d, dictionary %zu bytes\n", d.producer.c_str(),
              (unsigned long long)d.scene_hash, std::string(to_string(d.pyramid)).c_str(), d.zstd_level, d.dictionary.size());
  std::printf("  %zu pages, %.2f MB raw -> %.2f MB stored (ratio %.2f)\n", r.entries().size(), double(raw) / 1e6,
              double(stored) / 1e6, stored ? double(raw) / double(stored) : 0.0);
  std::printf("  %-4s %10s %12s %10s %10s %10s\n", "mip", "pages", "of the mip", "KB/page", "min KB", "max KB");
  for (const auto& [mip, m] : mips)
    std::printf("  %-4u %10llu %11.2f%% %10.1f %10.1f %10.1f\n", mip, (unsigned long long)m.pages,
                100.0 * double(m.pages) / double(d.vt.pages_per_side(mip) * d.vt.pages_per_side(mip)),
                double(m.stored) / double(m.pages) / 1024.0, double(m.min) / 1024.0, double(m.max) / 1024.0);
  return 0;
}

const CommandRegistrar k_info{
    "info", "Print a page store's configuration and statistics", 43, [](CLI::App& app) -> RunFn {
      auto a = std::make_shared<InfoArgs>();
      app.add_option("store", a->store, "Page store file")->required();
      app.add_flag("--json", a->json, "Print JSON instead of a table");
      return [a] { return run_info(*a); };
    }};

}  // namespace
}  // namespace tvt::cli
