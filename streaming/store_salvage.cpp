// salvage_store: a new, valid store from the intact records of a damaged one (index lost,
// truncated, trailing bytes, some records corrupt). The header must be intact: it gives the VT,
// the layers and the dictionary every record depends on. The file is mapped read-only and
// scanned from the end of the dictionary: a record is kept when its record header (magic and
// its own hash), page id, size, blob_hash, frame content size and page_hash all check out and
// its page was not kept before; anything else is skipped by searching for the next record
// magic. Kept blobs are copied, never recompressed, through the StoreWriter (atomic, fsync'd).
#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <memory>
#include <unordered_set>

#include "streaming/bake.h"
#include "streaming/file_io.h"
#include "streaming/store_format.h"
#include "streaming/store_writer.h"

namespace tvt {

namespace sf = store_format;

namespace {

// A read-only mapping of a whole file; empty for an empty file.
class Mapping {
 public:
  Mapping(const void* p, size_t n) : data_(static_cast<const uint8_t*>(p)), size_(n) {}
  ~Mapping() {
    if (size_) ::munmap(const_cast<uint8_t*>(data_), size_);
  }
  Mapping(const Mapping&) = delete;
  Mapping& operator=(const Mapping&) = delete;
  std::span<const uint8_t> bytes() const { return {data_, size_}; }

 private:
  const uint8_t* data_;
  size_t size_;
};

// Decompresses `blob` into `page` (page.size() bytes exactly) and checks page_hash.
bool page_checks_out(std::span<const uint8_t> blob, std::vector<uint8_t>& page, ZSTD_DCtx* dctx, ZSTD_DDict* ddict,
                     uint64_t page_hash) {
  if (ZSTD_getFrameContentSize(blob.data(), blob.size()) != page.size()) return false;
  const size_t r = ddict ? ZSTD_decompress_usingDDict(dctx, page.data(), page.size(), blob.data(), blob.size(), ddict)
                         : ZSTD_decompressDCtx(dctx, page.data(), page.size(), blob.data(), blob.size());
  return !ZSTD_isError(r) && r == page.size() && sf::hash(page) == page_hash;
}

}  // namespace

Result<SalvageReport> salvage_store(const std::string& damaged, const std::string& out, bool overwrite) {
  const auto t0 = std::chrono::steady_clock::now();
  std::error_code ec;
  if (std::filesystem::exists(std::filesystem::symlink_status(out, ec)) && !overwrite)
    return make_error(out + ": exists; pass --overwrite to replace it");
  if (std::filesystem::equivalent(damaged, out, ec))
    return make_error(out + ": is the damaged store itself; salvage into another file");

  fileio::UniqueFd fd(::open(damaged.c_str(), O_RDONLY | O_CLOEXEC));
  if (fd.get() < 0) return make_error(damaged + ": cannot open page store: " + fileio::errno_text(errno));
  auto size = fileio::file_size(fd.get(), damaged);
  if (!size) return size.error();
  const uint64_t file_bytes = size.value();
  if (file_bytes < sf::k_header_bytes)
    return make_error(damaged + ": " + std::to_string(file_bytes) + " bytes, shorter than the header: nothing to salvage");
  void* p = ::mmap(nullptr, size_t(file_bytes), PROT_READ, MAP_PRIVATE, fd.get(), 0);
  if (p == MAP_FAILED) return make_error(damaged + ": cannot map the file: " + fileio::errno_text(errno));
  const Mapping map(p, size_t(file_bytes));
  const std::span<const uint8_t> file = map.bytes();

  // The header as written, checked against the file size it declares (the real size may
  // differ: that is the damage being salvaged).
  const uint8_t* h = file.data();
  const uint64_t declared = sf::get_u64(h + sf::off::index_offset) + sf::get_u64(h + sf::off::index_bytes);
  if (std::memcmp(h, sf::k_magic.data(), sf::k_magic.size()) == 0 && declared == 0)
    return make_error(damaged + ": header: an unfinished bake (no index yet); run the same terravt bake again to resume it");
  std::vector<std::string> problems;
  const auto header = sf::decode_header(file.first(sf::k_header_bytes), declared, damaged, problems);
  if (!header) {
    std::string why = problems.empty() ? damaged + ": header: damaged" : problems.front();
    return make_error(why + " (salvage needs an intact header: the VT, layers and dictionary come from it)");
  }
  StoreDesc desc = header->desc;
  if (header->dict_bytes > 0) {
    if (header->dict_offset + header->dict_bytes > file_bytes)
      return make_error(damaged + ": dictionary: truncated (salvage needs it to decode any page)");
    const auto dict = file.subspan(size_t(header->dict_offset), size_t(header->dict_bytes));
    if (sf::hash(dict) != header->dict_hash) return make_error(damaged + ": dictionary: checksum mismatch (dict_hash); nothing to salvage");
    desc.dictionary.assign(dict.begin(), dict.end());
  }

  const std::unique_ptr<ZSTD_DCtx, size_t (*)(ZSTD_DCtx*)> dctx_owner(ZSTD_createDCtx(), ZSTD_freeDCtx);
  const std::unique_ptr<ZSTD_DDict, size_t (*)(ZSTD_DDict*)> ddict_owner(
      desc.dictionary.empty() ? nullptr : ZSTD_createDDict(desc.dictionary.data(), desc.dictionary.size()), ZSTD_freeDDict);
  if (!dctx_owner) return Error{ErrorKind::out_of_memory, damaged + ": zstd could not allocate a decompression context"};
  if (!desc.dictionary.empty() && !ddict_owner)
    return make_error(damaged + ": dictionary: zstd cannot load it (malformed zstd dictionary); nothing to salvage");
  ZSTD_DCtx* const dctx = dctx_owner.get();
  ZSTD_DDict* const ddict = ddict_owner.get();
  struct Kept {
    PageId page;
    uint64_t at;  // blob offset in the damaged file
    uint32_t bytes;
    uint64_t blob_hash, page_hash;
  };
  std::vector<Kept> kept;
  std::unordered_set<uint64_t> seen;
  SalvageReport report;
  const uint64_t max_stored = sf::max_stored_bytes(header->page_bytes);
  std::vector<uint8_t> page(size_t(header->page_bytes));
  uint8_t magic[4];
  sf::put_u32(magic, sf::k_record_magic);
  uint64_t pos = header->records_offset();
  while (pos + sf::k_record_header_bytes <= file_bytes) {
    sf::RecordHeader rh;
    bool ok = sf::decode_record_header(file.data() + pos, rh);
    const PageId id = PageId::unpack(rh.page);
    ok = ok && is_valid(desc.vt, id) && rh.stored_bytes >= 1 && rh.stored_bytes <= max_stored &&
         rh.stored_bytes <= file_bytes - pos - sf::k_record_header_bytes;
    if (ok) {
      const auto blob = file.subspan(size_t(pos + sf::k_record_header_bytes), rh.stored_bytes);
      ok = sf::hash(blob) == rh.blob_hash && page_checks_out(blob, page, dctx, ddict, rh.page_hash);
    }
    if (ok) {
      if (seen.insert(rh.page).second)
        kept.push_back(Kept{id, pos + sf::k_record_header_bytes, rh.stored_bytes, rh.blob_hash, rh.page_hash});
      else
        ++report.duplicates;
      pos += sf::k_record_header_bytes + rh.stored_bytes;
      continue;
    }
    // Not a good record here: on to the next record magic.
    const uint8_t* from = file.data() + pos + 1;
    const auto* next = static_cast<const uint8_t*>(::memmem(from, size_t(file_bytes - pos - 1), magic, sizeof(magic)));
    const uint64_t to = next ? uint64_t(next - file.data()) : file_bytes;
    report.skipped_bytes += to - pos;
    pos = to;
  }
  report.skipped_bytes += file_bytes - pos;
  if (kept.empty()) return make_error(damaged + ": no intact page record found; nothing to salvage, " + out + " not written");

  std::vector<PageId> plan;
  plan.reserve(kept.size());
  for (const Kept& k : kept) plan.push_back(k.page);
  const sf::Header out_header = sf::make_header(desc, StoreLayout{0, 1, plan.size(), plan_hash(plan), 0}, plan.size());
  auto opened = sf::StoreWriter::open(out);
  if (!opened) return opened.error();
  sf::StoreWriter& writer = opened.value();
  Status s = writer.start(sf::encode_header(out_header), desc.dictionary);
  for (size_t i = 0; s && i < kept.size(); ++i)
    s = writer.append(kept[i].page, file.subspan(size_t(kept[i].at), kept[i].bytes), kept[i].blob_hash, kept[i].page_hash);
  if (!s) {
    writer.discard();
    return s.error();
  }
  auto written = writer.finish(out_header);
  if (!written) {
    writer.discard();
    return written.error();
  }
  report.pages = kept.size();
  report.declared_pages = header->page_count;
  report.file_bytes = written.value();
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return report;
}

}  // namespace tvt
