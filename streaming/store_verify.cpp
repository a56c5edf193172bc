// verify_store: header and index checks (every problem listed), then every page read and
// decompressed on `threads` workers; one line per bad page, in index order.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <mutex>
#include <thread>

#include "streaming/bake.h"
#include "streaming/file_io.h"

namespace tvt {

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
  const uint32_t workers =
      std::clamp<uint32_t>(threads ? threads : std::thread::hardware_concurrency(), 1u, uint32_t(std::max<size_t>(entries.size(), 1)));
  std::atomic<size_t> next{0};
  std::atomic<uint64_t> ok{0};
  std::mutex mutex;
  std::vector<std::pair<size_t, std::string>> bad;
  auto work = [&] {
    auto decoder = reader->make_decoder();
    std::vector<uint8_t> page(reader->page_bytes());
    for (size_t i = next++; i < entries.size(); i = next++) {
      std::string message;
      if (reader->read_page(entries[i].page, page, *decoder, &message) == PageError::none) {
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
  return report;
}

}  // namespace tvt
