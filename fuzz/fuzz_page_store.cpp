// libFuzzer target: arbitrary bytes as a page store file -> PageStoreReader::open -> read every
// page (and, by input flags, verify_store and a PageLoader). Must never crash, leak, hit UB or
// allocate beyond what the file size justifies; a page read as ok must match its page hash.
//
// Input: [flags byte][file bytes]. Flag bit 0 repairs the checksums (dictionary, record
// headers, blobs, index, header) after mutation, so that mutated sizes, offsets and zstd frames
// get past the hashes to the checks and the decoder behind them. Bit 1 adds verify_store,
// bit 2 a PageLoader pass.
#include <sys/mman.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "streaming/bake.h"
#include "streaming/page_loader.h"
#include "streaming/store_format.h"

namespace sf = tvt::store_format;

namespace {

void repair(std::vector<uint8_t>& b) {
  if (b.size() < sf::k_header_bytes) return;
  uint8_t* p = b.data();
  const uint64_t size = b.size();
  const uint64_t dict_at = sf::get_u64(p + sf::off::dict_offset), dict_bytes = sf::get_u64(p + sf::off::dict_bytes);
  if (dict_bytes > 0 && dict_at <= size && dict_bytes <= size - dict_at)
    sf::put_u64(p + sf::off::dict_hash, sf::hash({p + dict_at, size_t(dict_bytes)}));
  const uint64_t index_at = sf::get_u64(p + sf::off::index_offset), index_bytes = sf::get_u64(p + sf::off::index_bytes);
  if (index_at <= size && index_bytes <= size - index_at) {
    for (uint64_t e = index_at; e + sf::k_index_entry_bytes <= index_at + index_bytes; e += sf::k_index_entry_bytes) {
      const uint64_t at = sf::get_u64(p + e + sf::idx::offset);
      const uint32_t stored = sf::get_u32(p + e + sf::idx::stored_bytes);
      if (at < sf::k_record_header_bytes || at > size || stored > size - at) continue;
      const uint64_t blob_hash = sf::hash({p + at, stored});
      sf::put_u64(p + e + sf::idx::blob_hash, blob_hash);
      const sf::RecordHeader rh{sf::get_u64(p + e + sf::idx::page), stored, blob_hash, sf::get_u64(p + e + sf::idx::page_hash)};
      sf::encode_record_header(rh, p + at - sf::k_record_header_bytes);
    }
    sf::put_u64(p + sf::off::index_hash, sf::hash({p + index_at, size_t(index_bytes)}));
  }
  sf::put_u64(p + sf::off::header_hash, sf::hash({p, sf::off::header_hash}));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const int fd = ::memfd_create("fuzz-page-store", MFD_CLOEXEC);
  static const std::string path = "/proc/self/fd/" + std::to_string(fd);
  if (fd < 0 || size < 1) return 0;
  const uint8_t flags = data[0];
  std::vector<uint8_t> bytes(data + 1, data + size);
  if (flags & 1) repair(bytes);
  if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, bytes.data(), bytes.size(), 0) != ssize_t(bytes.size())) std::abort();

  if (flags & 2) {
    auto report = tvt::verify_store(path, 1);
    if (!report.ok() || report.value().ok > report.value().pages) std::abort();
  }
  auto opened = tvt::PageStoreReader::open(path);
  if (!opened) return 0;
  std::shared_ptr<const tvt::PageStoreReader> store(std::move(opened.value()));
  if (store->page_bytes() > (uint64_t(4) << 20)) return 0;  // valid but slow to fill; the header checks ran
  auto decoder = store->make_decoder();
  std::vector<uint8_t> page(store->page_bytes());
  for (const tvt::StoreEntry& e : store->entries()) {
    if (store->find(e.page) != &e) std::abort();
    if (store->read_page(e.page, page, *decoder) == tvt::PageError::none && sf::hash(page) != e.page_hash) std::abort();
  }
  if (flags & 4) {
    tvt::PageLoader loader(store, tvt::PageLoaderOptions{1, 4});
    std::vector<tvt::LoadedPage> done;
    size_t asked = 0;
    for (const tvt::StoreEntry& e : store->entries()) {
      while (!loader.request(e.page, asked)) {
        loader.wait_idle();
        const size_t before = done.size();
        loader.poll(done);
        for (size_t i = before; i < done.size(); ++i)
          if (done[i].status == tvt::LoadStatus::ok) loader.release(done[i].staging);
      }
      ++asked;
    }
    loader.wait_idle();
    loader.poll(done);
    if (done.size() != asked) std::abort();
  }
  return 0;
}
