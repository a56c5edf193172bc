// bake_store: the source runs on the calling thread, a pool of PageCompressors compresses, and
// the calling thread appends records in plan order. Two batches are in flight: while the pool
// compresses batch k, the source produces batch k+1 (the GPU composer overlaps with zstd).
#include "streaming/bake.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <unordered_map>
#include <unordered_set>

#include "streaming/pyramid.h"
#include "streaming/store_writer.h"

namespace tvt {

namespace sf = store_format;

namespace {

struct Compressed {
  std::vector<uint8_t> blob;
  uint64_t blob_hash = 0, page_hash = 0;
};

// Fixed pool of compression workers, each with its own PageCompressor. One job at a time:
// submit() hands over a batch, wait() blocks until every page of it is compressed.
class CompressPool {
 public:
  CompressPool(const StoreDesc& desc, uint32_t threads) {
    for (uint32_t i = 0; i < threads; ++i) workers_.emplace_back([this, &desc] { run(desc); });
  }
  ~CompressPool() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    work_cv_.notify_all();
    for (std::thread& t : workers_) t.join();
  }
  CompressPool(const CompressPool&) = delete;
  CompressPool& operator=(const CompressPool&) = delete;

  // `raw` and `out` must stay alive and untouched until wait() returned.
  void submit(const std::vector<std::vector<uint8_t>>& raw, std::vector<Compressed>& out) {
    out.resize(raw.size());
    {
      std::lock_guard lock(mutex_);
      raw_ = &raw;
      out_ = &out;
      next_ = 0;
      remaining_ = raw.size();
    }
    work_cv_.notify_all();
  }
  void wait() {
    std::unique_lock lock(mutex_);
    done_cv_.wait(lock, [this] { return remaining_ == 0; });
    raw_ = nullptr;
    out_ = nullptr;
  }

 private:
  void run(const StoreDesc& desc) {
    const PageCompressor compressor(desc);
    std::unique_lock lock(mutex_);
    for (;;) {
      work_cv_.wait(lock, [this] { return stop_ || (raw_ && next_ < raw_->size()); });
      if (stop_) return;
      const size_t i = next_++;
      const std::vector<uint8_t>& page = (*raw_)[i];
      Compressed& c = (*out_)[i];
      lock.unlock();
      c.blob = compressor.compress(page);
      c.blob_hash = sf::hash(c.blob);
      c.page_hash = sf::hash(page);
      lock.lock();
      if (--remaining_ == 0) done_cv_.notify_all();
    }
  }

  std::mutex mutex_;
  std::condition_variable work_cv_, done_cv_;
  const std::vector<std::vector<uint8_t>>* raw_ = nullptr;
  std::vector<Compressed>* out_ = nullptr;
  size_t next_ = 0, remaining_ = 0;
  bool stop_ = false;
  std::vector<std::thread> workers_;
};

Status check_plan(const std::string& path, const StoreDesc& desc, std::span<const PageId> plan) {
  if (plan.empty()) return make_error(path + ": plan: is empty");
  if (plan.size() > k_max_plan_pages)
    return make_error(path + ": plan: " + std::to_string(plan.size()) + " pages, more than the limit of " +
                      std::to_string(k_max_plan_pages));
  std::unordered_set<uint64_t> seen;
  seen.reserve(plan.size());
  for (size_t i = 0; i < plan.size(); ++i) {
    if (!is_valid(desc.vt, plan[i]))
      return make_error(path + ": plan entry " + std::to_string(i) + " " + to_string(plan[i]) +
                        ": outside the virtual texture");
    if (!seen.insert(plan[i].pack()).second)
      return make_error(path + ": plan entry " + std::to_string(i) + " " + to_string(plan[i]) + ": duplicate page");
  }
  return Ok{};
}

// Stores given as BakeOptions::finer: opened, and checked to hold pages of the same pyramid.
struct FinerStore {
  std::unique_ptr<PageStoreReader> reader;
  std::unique_ptr<PageStoreReader::Decoder> decoder;
};
Result<std::vector<FinerStore>> open_finer(const std::string& path, const StoreDesc& desc, std::span<const std::string> files) {
  std::vector<FinerStore> out;
  for (const std::string& f : files) {
    auto r = PageStoreReader::open(f);
    if (!r) return make_error(path + ": options finer: " + r.error().message);
    const StoreDesc& d = r.value()->desc();
    const char* what = d.pyramid != StorePyramid::filtered ? "pyramid (it is not a filtered store)"
                       : !(d.vt.log2_size == desc.vt.log2_size && d.vt.page_texels == desc.vt.page_texels &&
                           d.vt.border_texels == desc.vt.border_texels) ? "vt"
                       : d.layers != desc.layers ? "layers"
                       : d.scene_hash != desc.scene_hash ? "scene_hash"
                       : d.producer != desc.producer ? "producer" : nullptr;
    if (what) return make_error(path + ": options finer: " + f + " holds pages of another bake: it differs in " + what);
    FinerStore s;
    s.decoder = r.value()->make_decoder();
    s.reader = std::move(r.value());
    out.push_back(std::move(s));
  }
  return out;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

Result<BakeSummary> bake_store(const std::string& path, const StoreDesc& desc, std::span<const PageId> plan,
                               const PageSource& source, const BakeOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  if (auto s = validate(desc, path + ": desc"); !s) return s.error();
  if (options.shard_count == 0 || options.shard_index >= options.shard_count)
    return make_error(path + ": options shard_index: shard " + std::to_string(options.shard_index) + " of " +
                      std::to_string(options.shard_count) + " does not exist");
  if (options.batch_pages == 0 || options.batch_pages > 4096)
    return make_error(path + ": options batch_pages: must be 1 to 4096, got " + std::to_string(options.batch_pages));
  if (!source) return make_error(path + ": no page source");
  if (auto s = check_plan(path, desc, plan); !s) return s.error();

  const ShardRange range = shard_range(plan.size(), options.shard_index, options.shard_count);
  const StoreLayout layout{options.shard_index, options.shard_count, plan.size(), plan_hash(plan), range.first};
  const std::span<const PageId> pages = plan.subspan(size_t(range.first), size_t(range.count));
  const sf::Header header = sf::make_header(desc, layout, range.count);
  const auto header_bytes = sf::encode_header(header);
  const uint64_t page_bytes = desc.page_bytes();

  auto opened = sf::StoreWriter::open(path);
  if (!opened) return opened.error();
  sf::StoreWriter& writer = opened.value();
  BakeSummary summary;
  if (options.resume) {
    auto kept = writer.resume(header_bytes, desc.dictionary, pages, page_bytes, summary.resume_note);
    if (!kept) return kept.error();
    summary.resumed_pages = kept.value();
  }
  if (summary.resumed_pages == 0)
    if (auto s = writer.start(header_bytes, desc.dictionary); !s) return s.error();

  // The filtered pyramid: level-0 pages come from `source`, each coarser page from the pyramid,
  // which reads finer pages back from this file (records before the batch being compressed are
  // on disk: each batch is flushed before the one after the next is asked for), from the two
  // batches in flight (the one being compressed and the one being produced), from `finer`
  // stores, and makes them again when none has them.
  std::unique_ptr<FilteredPyramid> pyramid;
  std::vector<FinerStore> finer;
  // (packed page, record index in this file), sorted: 16 bytes a page, less than a hash map.
  std::vector<std::pair<uint64_t, uint64_t>> position;
  // Pages of the batch being compressed and of the one being produced, not on disk yet: their
  // bytes stay where they are (the batch buffers) until written.
  std::unordered_map<uint64_t, const uint8_t*> compressing, producing;
  const PageDecompressor decompressor(desc);
  std::vector<uint8_t> blob;
  // The record index of a page this file holds already, or UINT64_MAX.
  auto in_file = [&](const PageId& p) {
    const auto it = std::lower_bound(position.begin(), position.end(), std::pair(p.pack(), uint64_t(0)));
    return it != position.end() && it->first == p.pack() && it->second < writer.records() ? it->second : UINT64_MAX;
  };
  PageSource produce = source;
  if (desc.pyramid == StorePyramid::filtered) {
    auto opened_finer = open_finer(path, desc, options.finer);
    if (!opened_finer) return opened_finer.error();
    finer = std::move(opened_finer.value());
    position.reserve(pages.size());
    for (size_t i = 0; i < pages.size(); ++i) position.emplace_back(pages[i].pack(), i);
    std::sort(position.begin(), position.end());
    PageLookup lookup;
    lookup.has = [&](const PageId& p) {
      if (compressing.contains(p.pack()) || producing.contains(p.pack()) || in_file(p) != UINT64_MAX) return true;
      return std::any_of(finer.begin(), finer.end(), [&](const FinerStore& f) { return f.reader->contains(p); });
    };
    lookup.read = [&](const PageId& p, std::span<uint8_t> out) -> Status {
      for (const auto* batch : {&producing, &compressing})
        if (const auto it = batch->find(p.pack()); it != batch->end()) {
          std::copy_n(it->second, out.size(), out.begin());
          return Ok{};
        }
      if (const uint64_t i = in_file(p); i != UINT64_MAX) {
        if (!writer.read_blob(i, blob) || !decompressor.decompress(blob, out) || sf::hash(out) != writer.entry(i).page_hash)
          return make_error(sf::page_where(writer.partial_path(), p) + ": cannot read it back to filter from (damaged)");
        return Ok{};
      }
      for (FinerStore& f : finer)
        if (f.reader->contains(p)) {
          std::string message;
          if (f.reader->read_page(p, out, *f.decoder, &message) != PageError::none) return make_error(message);
          return Ok{};
        }
      return make_error(to_string(p) + ": not in the store");
    };
    FilteredPyramid::Options po;
    po.batch_pages = options.batch_pages;
    po.cache_pages = 2 * options.batch_pages + 176;  // composed pages one request needs, and rows of finer pages
    pyramid = std::make_unique<FilteredPyramid>(desc, source, std::move(lookup), po);
    produce = [&](std::span<const PageId> ids, std::vector<std::vector<uint8_t>>& out) -> Status {
      // The previous call's pages are now being compressed; the one before is on disk. Moving a
      // page's vector into `out` keeps its bytes where they are.
      compressing = std::move(producing);
      producing.clear();
      pyramid->prepare(ids, true);  // the level-0 pages the whole batch lacks, composed in batches
      for (size_t i = 0; i < ids.size();) {
        if (ids[i].mip > 0) {
          auto page = pyramid->page(ids[i]);
          if (!page) return page.error();
          out.push_back(std::move(page.value()));
          producing.emplace(ids[i].pack(), out.back().data());
          ++i;
          continue;
        }
        size_t j = i;
        while (j < ids.size() && ids[j].mip == 0) ++j;
        std::vector<std::vector<uint8_t>> level0;
        if (auto s = source(ids.subspan(i, j - i), level0); !s) return s;
        if (level0.size() != j - i)
          return make_error("returned " + std::to_string(level0.size()) + " level-0 pages for " + std::to_string(j - i));
        for (size_t k = 0; k < level0.size(); ++k) {
          if (level0[k].size() != desc.page_bytes())
            return make_error("returned " + std::to_string(level0[k].size()) + " bytes for page " + to_string(ids[i + k]) +
                              ", expected " + std::to_string(desc.page_bytes()));
          out.push_back(std::move(level0[k]));
          producing.emplace(ids[i + k].pack(), out.back().data());
        }
        i = j;
      }
      return Ok{};
    };
  }

  const uint32_t threads = std::clamp(options.threads ? options.threads : std::thread::hardware_concurrency(), 1u, 256u);
  CompressPool pool(desc, threads);
  const uint64_t total = pages.size();
  uint64_t done = summary.resumed_pages;

  auto fetch = [&](uint64_t first, std::vector<std::vector<uint8_t>>& raw) -> Status {
    const auto ids = pages.subspan(size_t(first), size_t(std::min<uint64_t>(options.batch_pages, total - first)));
    raw.clear();
    if (auto s = produce(ids, raw); !s)
      return make_error(path + ": page source failed at plan page " + std::to_string(range.first + first) + " " +
                        to_string(ids.front()) + ": " + s.error().message);
    if (raw.size() != ids.size())
      return make_error(path + ": page source returned " + std::to_string(raw.size()) + " pages for a batch of " +
                        std::to_string(ids.size()));
    for (size_t i = 0; i < ids.size(); ++i)
      if (raw[i].size() != page_bytes)
        return make_error(path + ": page source returned " + std::to_string(raw[i].size()) + " bytes for page " +
                          to_string(ids[i]) + ", expected " + std::to_string(page_bytes));
    return Ok{};
  };
  auto is_cancelled = [&] { return options.cancelled && options.cancelled(); };
  auto stop = [&](const std::string& why) -> Error {  // `why` starts with a path
    writer.abandon();
    return make_error(why + "; " + std::to_string(done) + " of " + std::to_string(total) +
                      " pages are kept in " + writer.partial_path() + " for a resume");
  };

  // Two batch buffers, alternating: the pool holds pointers to the one it compresses, so the
  // buffers themselves never move or swap while a batch is in flight.
  std::array<std::vector<std::vector<uint8_t>>, 2> raw;
  std::array<std::vector<Compressed>, 2> comp;
  size_t cur = 0;
  if (done < total) {
    if (is_cancelled()) return stop(path + ": bake cancelled");
    if (auto s = fetch(done, raw[cur]); !s) return stop(s.error().message);
    pool.submit(raw[cur], comp[cur]);
  }
  while (done < total) {
    const size_t nxt = 1 - cur;
    const uint64_t next_first = done + raw[cur].size();
    bool have_next = false, cancelled = false;
    Status fetched = Ok{};
    if (next_first < total) {
      cancelled = is_cancelled();
      if (!cancelled) {
        fetched = fetch(next_first, raw[nxt]);  // overlaps the compression of the current batch
        have_next = fetched.ok();
      }
    }
    pool.wait();
    if (have_next) pool.submit(raw[nxt], comp[nxt]);
    Status written = Ok{};
    for (size_t i = 0; i < comp[cur].size() && written.ok(); ++i) {
      const Compressed& c = comp[cur][i];
      written = writer.append(pages[size_t(done + i)], c.blob, c.blob_hash, c.page_hash);
    }
    if (written.ok()) written = writer.flush();
    if (!written) {
      if (have_next) pool.wait();
      return stop(written.error().message);
    }
    done = next_first;
    if (options.progress) {
      BakeProgress p;
      p.done = done;
      p.total = total;
      p.resumed = summary.resumed_pages;
      p.raw_bytes = done * page_bytes;
      p.stored_bytes = writer.stored_bytes();
      p.seconds = seconds_since(t0);
      const double rate = p.seconds > 0 ? double(done - summary.resumed_pages) / p.seconds : 0.0;
      p.eta_seconds = rate > 0 ? double(total - done) / rate : 0.0;
      options.progress(p);
    }
    if (!fetched) return stop(fetched.error().message);
    if (cancelled) return stop(path + ": bake cancelled");
    cur = nxt;
  }

  auto file_bytes = writer.finish(header);
  if (!file_bytes) return file_bytes.error();
  summary.pages = total;
  summary.raw_bytes = total * page_bytes;
  summary.stored_bytes = writer.stored_bytes();
  summary.file_bytes = file_bytes.value();
  summary.seconds = seconds_since(t0);
  if (pyramid) {
    summary.extra_composed = pyramid->composed_pages();
    summary.read_back = pyramid->read_pages();
  }
  return summary;
}

}  // namespace tvt
