// verify_store: header and index checks (every problem listed), then every page read and
// decompressed on `threads` workers; one line per bad page, in index order. In a filtered store
// each worker also recomputes the coarse pages whose finer pages the store holds.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <mutex>
#include <thread>

#include "streaming/bake.h"
#include "streaming/file_io.h"
#include "streaming/pyramid.h"
#include "streaming/store_format.h"

namespace tvt {

namespace {

// True when every mip m-1 page a filtered mip-m page is made of (its children and, for the
// border, their neighbours; clamped at the terrain edge) is in the store.
bool finer_pages_present(const PageStoreReader& store, const PageId& page) {
  const VtConfig& vt = store.desc().vt;
  const int64_t P = vt.page_texels, B = vt.border_texels, last = int64_t(vt.mip_texels(page.mip)) - 1;
  const int64_t x0 = std::clamp<int64_t>(page.x * P - B, 0, last), x1 = std::clamp<int64_t>(page.x * P + P + B - 1, 0, last);
  const int64_t y0 = std::clamp<int64_t>(page.y * P - B, 0, last), y1 = std::clamp<int64_t>(page.y * P + P + B - 1, 0, last);
  for (int64_t y = 2 * y0 / P; y <= (2 * y1 + 1) / P; ++y)
    for (int64_t x = 2 * x0 / P; x <= (2 * x1 + 1) / P; ++x)
      if (!store.contains(PageId{page.mip - 1, uint32_t(x), uint32_t(y)})) return false;
  return true;
}

}  // namespace

Result<VerifyReport> verify_store(const std::string& path, uint32_t threads) {
  {
    fileio::UniqueFd fd(::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC));  // a FIFO must not block
    if (fd.get() < 0) return make_error(path + ": cannot open page store: " + fileio::errno_text(errno));
    if (auto size = fileio::file_size(fd.get(), path); !size) return size.error();
  }
  VerifyReport report;
  const std::unique_ptr<PageStoreReader> reader = PageStoreReader::open_collect(path, report.problems);
  if (!reader) return report;

  const auto entries = reader->entries();
  report.pages = entries.size();
  report.pyramid = reader->desc().pyramid;
  const bool filtered = report.pyramid == StorePyramid::filtered;
  std::atomic<uint64_t> filter_checked{0};
  const uint32_t workers =
      std::clamp<uint32_t>(threads ? threads : std::thread::hardware_concurrency(), 1u,
                           std::min<uint32_t>(k_max_verify_threads, uint32_t(std::max<size_t>(entries.size(), 1))));
  std::atomic<size_t> next{0};
  std::atomic<uint64_t> ok{0};
  std::mutex mutex;
  std::vector<std::pair<size_t, std::string>> bad;
  auto work = [&] {
    auto decoder = reader->make_decoder();
    std::vector<uint8_t> page(reader->page_bytes());
    // Finer pages come from the store only; a page that is missing or unreadable is not filtered
    // from (pages whose finer pages are all present are the only ones checked).
    auto finer_decoder = reader->make_decoder();
    PageLookup lookup;
    lookup.has = [&](const PageId& p) { return reader->contains(p); };
    lookup.read = [&](const PageId& p, std::span<uint8_t> out) -> Status {
      std::string message;
      if (reader->read_page(p, out, *finer_decoder, &message) != PageError::none) return make_error(message);
      return Ok{};
    };
    auto nothing = [](std::span<const PageId> pages, std::vector<std::vector<uint8_t>>&) -> Status {
      return make_error(to_string(pages.front()) + " is not in the store");
    };
    FilteredPyramid pyramid(reader->desc(), nothing, std::move(lookup), FilteredPyramid::Options{});
    for (size_t i = next++; i < entries.size(); i = next++) {
      std::string message;
      const PageId id = entries[i].page;
      if (reader->read_page(id, page, *decoder, &message) == PageError::none) {
        if (filtered && id.mip > 0 && finer_pages_present(*reader, id)) {
          // A finer page that does not read is reported on its own line; this one stays unchecked.
          auto expected = pyramid.page(id);
          if (expected && expected.value() != page) {
            const size_t at = size_t(std::mismatch(page.begin(), page.end(), expected->begin()).first - page.begin());
            const uint32_t slot = reader->desc().vt.slot_texels();
            message = store_format::page_where(path, id) + ": not the box filter of mip " + std::to_string(id.mip - 1) +
                      " (first difference at slot texel (" + std::to_string(at / 4 % slot) + "," +
                      std::to_string(at / 4 / slot % slot) + "))";
          }
          if (expected) ++filter_checked;
        }
      }
      if (message.empty()) {
        ++ok;
      } else {
        std::lock_guard lock(mutex);
        bad.emplace_back(i, std::move(message));
      }
    }
  };
  std::vector<std::thread> pool;
  for (uint32_t t = 1; t < workers; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
  std::sort(bad.begin(), bad.end());
  for (auto& [i, message] : bad) report.problems.push_back(std::move(message));
  report.ok = ok;
  report.filter_checked = filter_checked;
  return report;
}

}  // namespace tvt
