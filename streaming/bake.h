// Writing page stores: bake (resumable, sharded), merge shards, verify. docs/page-store.md.
#pragma once
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "streaming/page_store.h"

namespace tvt {

// Produces raw pages (page_bytes each) for a batch of page ids, in order. Called on the baking
// thread only (GPU composer or CPU reference live behind it). `out` arrives empty.
using PageSource = std::function<Status(std::span<const PageId> pages, std::vector<std::vector<uint8_t>>& out)>;

struct BakeProgress {
  uint64_t done = 0, total = 0, resumed = 0;  // pages in the file so far (resumed ones included), of this store
  uint64_t raw_bytes = 0, stored_bytes = 0;   // of the pages done
  double seconds = 0, eta_seconds = 0;        // this run; ETA from this run's page rate
};
struct BakeOptions {
  uint32_t threads = 0;      // compression workers; 0 = hardware_concurrency
  uint32_t batch_pages = 32; // pages asked from the source at once (1..4096)
  // true: continue `<path>.partial` if it is a prefix of this same bake; a partial of another
  // bake (other plan, shard, scene or settings) is an error and stays untouched.
  // false: discard any partial and start over.
  bool resume = true;
  uint32_t shard_index = 0, shard_count = 1;
  std::function<void(const BakeProgress&)> progress;  // called after every batch, on the baking thread
  std::function<bool()> cancelled;  // polled between batches; true: stop, keep the .partial (resumable)
  // desc.pyramid == filtered only: stores that hold pages of this same filtered bake (other
  // shards' finished files, a store of the finer mips). A coarse page's finer pages are read
  // from this bake's own file first, then from these, and made again only when neither has them.
  std::vector<std::string> finer;
};
struct BakeSummary {
  uint64_t pages = 0, resumed_pages = 0, raw_bytes = 0, stored_bytes = 0, file_bytes = 0;
  double seconds = 0;
  std::string resume_note;  // why an existing .partial was started over (too short for a header)
  // Filtered pyramid: level-0 pages composed that the store does not hold (a region's edge,
  // mips below the plan's, pages of other shards) and finer pages read back to filter from.
  uint64_t extra_composed = 0, read_back = 0;
};

// Writes `path` atomically: everything goes to `<path>.partial` (records appended in plan order,
// each self-describing so a resume can find the last complete one), then index + header, fsync,
// rename. An existing store at `path` is untouched until the rename. The result is
// byte-identical whatever the thread count and however often it was interrupted and resumed.
// The plan must be non-empty, hold no duplicates and only pages valid for desc.vt.
// desc.pyramid == filtered (streaming/pyramid.h): `source` is asked for level-0 pages only; every
// coarser page is the box filter of the mip below, read back from the pages this bake wrote
// (bake_plan(..., filtered) puts them first) or made again. The file is then byte-identical
// whatever the plan's order, batch size, threads, resumes, shards and `finer` stores.
// Cancellation returns an error ("... cancelled ...") and keeps the .partial.
Result<BakeSummary> bake_store(const std::string& path, const StoreDesc& desc, std::span<const PageId> plan,
                               const PageSource& source, const BakeOptions& options);

// Joins shard stores (any order given; each knows its i/n, plan size and plan hash) into one
// store byte-identical to the single (unsharded) bake of the same plan. Checks they belong to
// the same bake and none is missing/duplicated; writes atomically.
Result<BakeSummary> merge_stores(std::span<const std::string> parts, const std::string& path);

// Page-by-page verification for `terravt verify`: every problem, one line each. An error only
// when the file cannot be opened at all; a damaged header or index is a problem line.
// A filtered store's mip-m pages (m >= 1) whose finer pages (children and neighbours) are all in
// the store and read are also checked to be exactly their box filter (streaming/pyramid.h); a
// page that is not is a problem line (one whose finer pages do not read stays unchecked: the
// damaged finer page has its own line).
struct VerifyReport {
  uint64_t pages = 0, ok = 0;
  StorePyramid pyramid = StorePyramid::composed;
  uint64_t filter_checked = 0;  // filtered stores: coarse pages checked against the finer mip
  std::vector<std::string> problems;
};
// threads: 0 = one per core; at most k_max_verify_threads are started.
inline constexpr uint32_t k_max_verify_threads = 256;
Result<VerifyReport> verify_store(const std::string& path, uint32_t threads = 0);

// `terravt verify --salvage OUT`: writes to `out` a new, valid whole store of every intact
// record of the damaged store `damaged` (its index may be lost, truncated or followed by
// junk; damaged records are skipped), in file order, blobs copied unchanged. Needs an intact
// header (VT, layers, dictionary). Refuses an existing `out` unless `overwrite`; writes
// atomically (<out>.partial, then rename). An error when no record is intact.
struct SalvageReport {
  uint64_t pages = 0;           // records kept
  uint64_t declared_pages = 0;  // page_count of the damaged header
  uint64_t duplicates = 0;      // intact records of a page kept already (skipped)
  uint64_t skipped_bytes = 0;   // bytes after the dictionary not in a kept record (index included)
  uint64_t file_bytes = 0;      // of `out`
  double seconds = 0;
};
Result<SalvageReport> salvage_store(const std::string& damaged, const std::string& out, bool overwrite);

}  // namespace tvt
