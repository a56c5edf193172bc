#include "streaming/store_writer.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>

namespace tvt::store_format {

namespace {
constexpr size_t k_flush_bytes = size_t(4) << 20;  // write records in chunks of about 4 MiB

std::string hex(uint64_t v) {
  char buf[24];
  std::snprintf(buf, sizeof(buf), "%016llx", (unsigned long long)v);
  return buf;
}

// What a bake's header says about its plan, for a person: "V = 2^10, 64+4-texel pages, plan of
// 85 pages (hash ...), shard 0/1".
std::string plan_text(const uint8_t* h) {
  return "V = 2^" + std::to_string(get_u32(h + off::log2_size)) + ", " + std::to_string(get_u32(h + off::page_texels)) +
         "+" + std::to_string(get_u32(h + off::border_texels)) + "-texel pages, plan of " +
         std::to_string(get_u64(h + off::plan_pages)) + " pages (hash " + hex(get_u64(h + off::plan_hash)) + "), shard " +
         std::to_string(get_u32(h + off::shard_index)) + "/" + std::to_string(get_u32(h + off::shard_count));
}

}  // namespace

std::string header_difference(const uint8_t* partial, const uint8_t* wanted) {
  std::string fields;
  auto differs = [&](const char* name, size_t at, size_t bytes) {
    if (std::memcmp(partial + at, wanted + at, bytes) != 0) fields += std::string(fields.empty() ? "" : ", ") + name;
  };
  differs("VT", off::log2_size, off::layer_count - off::log2_size);
  differs("layers", off::layer_count, off::page_bytes - off::layer_count);
  differs("scene", off::scene_hash, 8);
  differs("producer", off::producer, k_producer_bytes);
  differs("zstd level", off::zstd_level, 4);
  differs("pyramid", off::pyramid, 4);
  differs("dictionary", off::dict_offset, off::shard_index - off::dict_offset);
  differs("plan", off::plan_pages, 16);
  differs("shard", off::shard_index, 8);
  if (fields.empty()) fields = "header bytes";  // e.g. a damaged header
  return "it differs in " + fields + " (the partial: " + plan_text(partial) + "; this bake: " + plan_text(wanted) + ")";
}

Result<StoreWriter> StoreWriter::open(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) return make_error(path + ": is a folder, not a page store path");
  StoreWriter w;
  w.path_ = path;
  w.partial_ = path + ".partial";
  w.fd_ = fileio::UniqueFd(::open(w.partial_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644));
  if (w.fd_.get() < 0) return make_error(w.partial_ + ": cannot create: " + fileio::errno_text(errno));
  if (auto s = fileio::lock_exclusive(w.fd_.get(), w.partial_); !s) return s.error();
  return w;
}

Result<uint64_t> StoreWriter::resume(const std::array<uint8_t, k_header_bytes>& header,
                                     std::span<const uint8_t> dictionary, std::span<const PageId> pages,
                                     uint64_t page_bytes, std::string& note) {
  auto size = fileio::file_size(fd_.get(), partial_);
  if (!size) return size.error();
  const uint64_t file_bytes = size.value();
  if (file_bytes == 0) return uint64_t(0);  // nothing to resume: not worth a note
  const uint64_t records_at = k_header_bytes + dictionary.size();
  std::vector<uint8_t> buf(records_at);
  if (file_bytes < records_at || fileio::pread_full(fd_.get(), buf.data(), buf.size(), 0) != int64_t(buf.size())) {
    note = partial_ + ": shorter than its header: started over";
    return uint64_t(0);
  }
  if (std::memcmp(buf.data(), header.data(), header.size()) != 0 ||
      !std::equal(dictionary.begin(), dictionary.end(), buf.begin() + k_header_bytes)) {
    // Another bake's work (maybe hours of it) is never thrown away unasked.
    return make_error(partial_ + ": holds " + std::to_string(file_bytes) + " bytes of another bake, not resumed and left as it is: " +
                      header_difference(buf.data(), header.data()) +
                      "; bake that plan again to resume it, or start over without resuming (terravt bake --restart)");
  }
  // Walk the records; keep each one whose header is intact, names the expected page and whose
  // blob is complete with the right hash. Everything after the first bad one is cut off.
  const uint64_t max_stored = max_stored_bytes(page_bytes);
  uint64_t pos = records_at;
  std::array<uint8_t, k_record_header_bytes> rh_bytes{};
  std::vector<uint8_t> blob;
  entries_.clear();
  stored_bytes_ = 0;
  for (const PageId& page : pages) {
    if (file_bytes - pos < k_record_header_bytes) break;
    if (fileio::pread_full(fd_.get(), rh_bytes.data(), rh_bytes.size(), pos) != int64_t(rh_bytes.size())) break;
    RecordHeader rh;
    if (!decode_record_header(rh_bytes.data(), rh) || rh.page != page.pack()) break;
    if (rh.stored_bytes == 0 || rh.stored_bytes > max_stored) break;
    if (file_bytes - pos - k_record_header_bytes < rh.stored_bytes) break;
    blob.resize(rh.stored_bytes);
    if (fileio::pread_full(fd_.get(), blob.data(), blob.size(), pos + k_record_header_bytes) != int64_t(blob.size())) break;
    if (hash(blob) != rh.blob_hash) break;
    entries_.push_back(StoreEntry{page, pos + k_record_header_bytes, rh.stored_bytes, rh.blob_hash, rh.page_hash});
    stored_bytes_ += rh.stored_bytes;
    pos += k_record_header_bytes + rh.stored_bytes;
  }
  if (::ftruncate(fd_.get(), off_t(pos)) != 0) return make_error(partial_ + ": cannot truncate: " + fileio::errno_text(errno));
  end_ = written_ = pos;
  return uint64_t(entries_.size());
}

bool StoreWriter::read_blob(uint64_t i, std::vector<uint8_t>& blob) const {
  if (i >= entries_.size()) return false;
  const StoreEntry& e = entries_[size_t(i)];
  if (e.offset + e.stored_bytes > written_) return false;
  blob.resize(e.stored_bytes);
  return fileio::pread_full(fd_.get(), blob.data(), blob.size(), e.offset) == int64_t(blob.size()) && hash(blob) == e.blob_hash;
}

Status StoreWriter::start(const std::array<uint8_t, k_header_bytes>& header, std::span<const uint8_t> dictionary) {
  if (::ftruncate(fd_.get(), 0) != 0) return make_error(partial_ + ": cannot truncate: " + fileio::errno_text(errno));
  entries_.clear();
  pending_.clear();
  stored_bytes_ = 0;
  if (auto s = fileio::pwrite_full(fd_.get(), header.data(), header.size(), 0, partial_); !s) return s;
  if (auto s = fileio::pwrite_full(fd_.get(), dictionary.data(), dictionary.size(), k_header_bytes, partial_); !s) return s;
  end_ = written_ = k_header_bytes + dictionary.size();
  return Ok{};
}

Status StoreWriter::append(const PageId& page, std::span<const uint8_t> blob, uint64_t blob_hash, uint64_t page_hash) {
  const RecordHeader rh{page.pack(), uint32_t(blob.size()), blob_hash, page_hash};
  const size_t at = pending_.size();
  pending_.resize(at + k_record_header_bytes + blob.size());
  encode_record_header(rh, pending_.data() + at);
  std::copy(blob.begin(), blob.end(), pending_.begin() + ptrdiff_t(at + k_record_header_bytes));
  entries_.push_back(StoreEntry{page, end_ + k_record_header_bytes, uint32_t(blob.size()), blob_hash, page_hash});
  end_ += k_record_header_bytes + blob.size();
  stored_bytes_ += blob.size();
  if (pending_.size() >= k_flush_bytes) return flush();
  return Ok{};
}

Status StoreWriter::flush() {
  if (pending_.empty()) return Ok{};
  if (auto s = fileio::pwrite_full(fd_.get(), pending_.data(), pending_.size(), written_, partial_); !s) return s;
  written_ += pending_.size();
  pending_.clear();
  return Ok{};
}

Result<uint64_t> StoreWriter::finish(Header h) {
  if (auto s = flush(); !s) return s.error();
  std::vector<uint8_t> index(entries_.size() * k_index_entry_bytes);
  for (size_t i = 0; i < entries_.size(); ++i) encode_index_entry(entries_[i], index.data() + i * k_index_entry_bytes);
  h.page_count = entries_.size();
  h.index_offset = end_;
  h.index_bytes = index.size();
  h.index_hash = hash(index);
  const auto header = encode_header(h);
  const uint64_t file_bytes = end_ + index.size();
  if (auto s = fileio::pwrite_full(fd_.get(), index.data(), index.size(), end_, partial_); !s) return s.error();
  if (::ftruncate(fd_.get(), off_t(file_bytes)) != 0)
    return make_error(partial_ + ": cannot truncate: " + fileio::errno_text(errno));
  if (auto s = fileio::pwrite_full(fd_.get(), header.data(), header.size(), 0, partial_); !s) return s.error();
  if (auto s = fileio::fsync_file(fd_.get(), partial_); !s) return s.error();
  // Rename while still holding the lock, so no other writer can start on the partial in between.
  if (auto s = fileio::rename_durable(partial_, path_); !s) return s.error();
  fd_.reset();
  return file_bytes;
}

void StoreWriter::abandon() {
  (void)flush();
  (void)fileio::fsync_file(fd_.get(), partial_);
  fd_.reset();
}

void StoreWriter::discard() {
  ::unlink(partial_.c_str());  // before unlocking, so no other writer's new partial is removed
  fd_.reset();
}

}  // namespace tvt::store_format
