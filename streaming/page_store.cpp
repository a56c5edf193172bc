#include "streaming/page_store.h"

#include <fcntl.h>
#include <unistd.h>
#include <zdict.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <new>

#include "streaming/file_io.h"
#include "streaming/store_format.h"

namespace tvt {

namespace sf = store_format;

std::string_view to_string(PageLayerFormat format) {
  switch (format) {
    case PageLayerFormat::rgba8_albedo_height: return "rgba8_albedo_height";
  }
  return "unknown";
}

std::string_view to_string(StorePyramid pyramid) {
  switch (pyramid) {
    case StorePyramid::composed: return "composed";
    case StorePyramid::filtered: return "filtered";
  }
  return "unknown";
}

std::string_view to_string(PageError error) {
  switch (error) {
    case PageError::none: return "none";
    case PageError::missing: return "missing";
    case PageError::io: return "io";
    case PageError::truncated: return "truncated";
    case PageError::corrupt: return "corrupt";
  }
  return "unknown";
}

uint64_t StoreDesc::page_bytes() const {
  const uint64_t slot = vt.slot_texels();
  return slot * slot * 4 * layers.size();
}

bool operator==(const StoreDesc& a, const StoreDesc& b) {
  return a.vt.log2_size == b.vt.log2_size && a.vt.page_texels == b.vt.page_texels &&
         a.vt.border_texels == b.vt.border_texels && a.layers == b.layers && a.scene_hash == b.scene_hash &&
         a.producer == b.producer && a.zstd_level == b.zstd_level && a.dictionary == b.dictionary && a.pyramid == b.pyramid;
}

Status validate(const StoreDesc& d, const std::string& where) {
  if (auto s = validate(d.vt, where + " vt"); !s) return s.error();
  if (d.layers.empty() || d.layers.size() > sf::k_max_layers)
    return make_error(where + " layers: must hold 1 to 4 layers, got " + std::to_string(d.layers.size()));
  for (size_t i = 0; i < d.layers.size(); ++i)
    if (d.layers[i] != PageLayerFormat::rgba8_albedo_height)
      return make_error(where + " layers[" + std::to_string(i) + "]: unknown page format " +
                        std::to_string(uint32_t(d.layers[i])));
  if (d.producer.size() >= sf::k_producer_bytes)
    return make_error(where + " producer: at most 63 bytes, got " + std::to_string(d.producer.size()));
  if (d.producer.find('\0') != std::string::npos) return make_error(where + " producer: must not contain NUL bytes");
  if (!((d.zstd_level >= 1 && d.zstd_level <= 19) || (d.zstd_level >= -5 && d.zstd_level <= -1)))
    return make_error(where + " zstd_level: must be 1..19 or -5..-1, got " + std::to_string(d.zstd_level));
  if (d.pyramid != StorePyramid::composed && d.pyramid != StorePyramid::filtered)
    return make_error(where + " pyramid: must be composed (0) or filtered (1), got " + std::to_string(uint32_t(d.pyramid)));
  if (d.dictionary.size() > sf::k_max_dictionary_bytes)
    return make_error(where + " dictionary: at most 64 MiB, got " + std::to_string(d.dictionary.size()) + " bytes");
  if (!d.dictionary.empty()) {
    ZSTD_DDict* dd = ZSTD_createDDict(d.dictionary.data(), d.dictionary.size());
    ZSTD_freeDDict(dd);
    if (!dd) return make_error(where + " dictionary: zstd cannot load it (malformed zstd dictionary)");
  }
  return Ok{};
}

namespace {

// The page rectangle of each mip of a plan, coarsest first (spans[k] is mip mip_hi - k), and in
// `total` their page count. Errors on an empty or invalid region and beyond k_max_plan_pages.
struct PlanSpan {
  uint32_t mip;
  uint64_t x0, x1, y0, y1;
};
Result<std::vector<PlanSpan>> plan_spans(const VtConfig& vt, const BakeRegion& r, uint64_t& total) {
  if (auto s = validate(vt, "bake plan: vt"); !s) return s.error();
  const uint64_t size = vt.size_texels();
  const uint64_t x1 = std::min(r.x1, size), y1 = std::min(r.y1, size);
  if (r.x0 >= x1 || r.y0 >= y1)
    return make_error("bake plan: region: [" + std::to_string(r.x0) + "," + std::to_string(r.x1) + ")x[" +
                      std::to_string(r.y0) + "," + std::to_string(r.y1) + ") is empty inside the " +
                      std::to_string(size) + "-texel virtual texture");
  const uint32_t top = vt.mip_count() - 1;
  const uint32_t mip_hi = std::min(r.mip_hi, top);
  if (r.mip_lo > mip_hi)
    return make_error("bake plan: region mip_lo: " + std::to_string(r.mip_lo) + " is above mip_hi " +
                      std::to_string(mip_hi) + " (top mip " + std::to_string(top) + ")");
  std::vector<PlanSpan> spans;
  total = 0;
  for (uint32_t m = mip_hi + 1; m-- > r.mip_lo;) {
    const uint64_t footprint = uint64_t(vt.page_texels) << m;  // level-0 texels per page side
    const PlanSpan s{m, r.x0 / footprint, (x1 + footprint - 1) / footprint, r.y0 / footprint,
                     (y1 + footprint - 1) / footprint};
    total += (s.x1 - s.x0) * (s.y1 - s.y0);
    if (total > k_max_plan_pages)
      return make_error("bake plan: region: more than " + std::to_string(k_max_plan_pages) +
                        " pages; bake the terrain in smaller regions or fewer mips");
    spans.push_back(s);
  }
  return spans;
}

}  // namespace

Result<uint64_t> bake_plan_pages(const VtConfig& vt, const BakeRegion& r) {
  uint64_t total = 0;
  auto spans = plan_spans(vt, r, total);
  if (!spans) return spans.error();
  return total;
}

Result<std::vector<PageId>> bake_plan(const VtConfig& vt, const BakeRegion& r, StorePyramid order) {
  uint64_t total = 0;
  auto spans = plan_spans(vt, r, total);
  if (!spans) return spans.error();
  std::vector<PageId> plan;
  plan.reserve(total);
  for (size_t i = 0; i < spans->size(); ++i) {
    const PlanSpan& s = (*spans)[order == StorePyramid::filtered ? spans->size() - 1 - i : i];
    for (uint64_t y = s.y0; y < s.y1; ++y)
      for (uint64_t x = s.x0; x < s.x1; ++x) plan.push_back(PageId{s.mip, uint32_t(x), uint32_t(y)});
  }
  return plan;
}

ShardRange shard_range(uint64_t plan_pages, uint32_t index, uint32_t count) {
  if (count == 0 || index >= count) return {};
  const uint64_t q = plan_pages / count, r = plan_pages % count;
  return ShardRange{index * q + std::min<uint64_t>(index, r), q + (index < r ? 1 : 0)};
}

uint64_t plan_hash(std::span<const PageId> plan) {
  std::vector<uint8_t> bytes(plan.size() * 8);
  for (size_t i = 0; i < plan.size(); ++i) sf::put_u64(bytes.data() + 8 * i, plan[i].pack());
  return sf::hash(bytes);
}

// ---------------------------------------------------------------------------------------------
// Reader

PageStoreReader::Decoder::~Decoder() { ZSTD_freeDCtx(dctx_); }

PageStoreReader::~PageStoreReader() {
  if (fd_ >= 0) ::close(fd_);
  ZSTD_freeDDict(ddict_);
}

Result<std::unique_ptr<PageStoreReader>> PageStoreReader::open(const std::string& path) {
  std::vector<std::string> problems;
  auto r = open_impl(path, problems, false);
  if (!r) return make_error(problems.empty() ? path + ": cannot open" : problems.front());
  return r;
}

std::unique_ptr<PageStoreReader> PageStoreReader::open_collect(const std::string& path,
                                                               std::vector<std::string>& problems) {
  return open_impl(path, problems, true);
}

std::unique_ptr<PageStoreReader> PageStoreReader::open_impl(const std::string& path, std::vector<std::string>& problems,
                                                            bool collect) {
  const size_t first_problem = problems.size();
  // O_NONBLOCK: a FIFO must not block the open; file_size() then refuses anything but a
  // regular file (on which O_NONBLOCK changes nothing).
  fileio::UniqueFd fd(::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC));
  if (fd.get() < 0) {
    problems.push_back(path + ": cannot open page store: " + fileio::errno_text(errno));
    return nullptr;
  }
  auto size = fileio::file_size(fd.get(), path);
  if (!size) {
    problems.push_back(size.error().message);
    return nullptr;
  }
  const uint64_t file_bytes = size.value();
  std::array<uint8_t, sf::k_header_bytes> hb{};
  const int64_t got = fileio::pread_full(fd.get(), hb.data(), hb.size(), 0);
  if (got < 0) {
    problems.push_back(path + ": cannot read the header: " + fileio::errno_text(errno));
    return nullptr;
  }
  auto header = sf::decode_header(std::span(hb.data(), size_t(got)), file_bytes, path, problems);
  if (!header) return nullptr;
  const sf::Header& h = *header;

  std::unique_ptr<PageStoreReader> r(new PageStoreReader());
  r->path_ = path;
  r->desc_ = h.desc;
  r->layout_ = h.layout;
  r->page_bytes_ = h.page_bytes;
  r->file_bytes_ = file_bytes;

  // Dictionary: its size was checked against the file size by decode_header.
  if (h.dict_bytes > 0) {
    r->desc_.dictionary.resize(size_t(h.dict_bytes));
    if (fileio::pread_full(fd.get(), r->desc_.dictionary.data(), size_t(h.dict_bytes), h.dict_offset) != int64_t(h.dict_bytes)) {
      problems.push_back(path + ": dictionary: cannot read " + std::to_string(h.dict_bytes) + " bytes at offset " +
                         std::to_string(h.dict_offset));
      return nullptr;
    }
    if (sf::hash(r->desc_.dictionary) != h.dict_hash) {
      problems.push_back(path + ": dictionary: checksum mismatch (dict_hash)");
      return nullptr;
    }
    r->ddict_ = ZSTD_createDDict(r->desc_.dictionary.data(), r->desc_.dictionary.size());
    if (!r->ddict_) {
      problems.push_back(path + ": dictionary: zstd cannot load it (malformed zstd dictionary)");
      return nullptr;
    }
  }

  // Index: index_bytes = page_count * 40 and ends at the end of the file (decode_header).
  std::vector<uint8_t> index(size_t(h.index_bytes));
  if (fileio::pread_full(fd.get(), index.data(), index.size(), h.index_offset) != int64_t(index.size())) {
    problems.push_back(path + ": index: cannot read " + std::to_string(h.index_bytes) + " bytes at offset " +
                       std::to_string(h.index_offset));
    return nullptr;
  }
  if (sf::hash(index) != h.index_hash) {
    problems.push_back(path + ": index: checksum mismatch (index_hash)");
    return nullptr;
  }
  constexpr size_t k_max_listed = 100;
  size_t listed = 0, unlisted = 0;
  auto entry_problem = [&](uint64_t i, const PageId& page, const std::string& what) {
    if (listed < k_max_listed) {
      problems.push_back(path + ": index entry " + std::to_string(i) + " (mip " + std::to_string(page.mip) + " page (" +
                         std::to_string(page.x) + "," + std::to_string(page.y) + ")): " + what);
      ++listed;
    } else {
      ++unlisted;
    }
  };
  const uint64_t max_stored = sf::max_stored_bytes(h.page_bytes);
  r->entries_.reserve(size_t(h.page_count));
  r->by_page_.reserve(size_t(h.page_count));
  uint64_t expected = h.records_offset() + sf::k_record_header_bytes;
  for (uint64_t i = 0; i < h.page_count && (collect || problems.size() == first_problem); ++i) {
    uint32_t reserved = 0;
    const StoreEntry e = sf::decode_index_entry(index.data() + i * sf::k_index_entry_bytes, &reserved);
    if (reserved != 0) entry_problem(i, e.page, "reserved field must be 0");
    if (!is_valid(h.desc.vt, e.page)) entry_problem(i, e.page, "page is outside the virtual texture");
    if (e.stored_bytes == 0 || e.stored_bytes > max_stored)
      entry_problem(i, e.page, "stored size " + std::to_string(e.stored_bytes) + " is outside 1.." + std::to_string(max_stored));
    if (e.offset != expected)
      entry_problem(i, e.page, "offset " + std::to_string(e.offset) + ", expected " + std::to_string(expected) +
                                   " (records follow each other in index order)");
    expected = e.offset + uint64_t(e.stored_bytes) + sf::k_record_header_bytes;  // e.offset may be garbage: checked below
    if (e.offset > h.index_offset || e.stored_bytes > h.index_offset - e.offset)
      entry_problem(i, e.page, "blob [" + std::to_string(e.offset) + ", +" + std::to_string(e.stored_bytes) +
                                   ") runs past the start of the index");
    const auto [it, inserted] = r->by_page_.emplace(e.page.pack(), uint32_t(i));
    if (!inserted) entry_problem(i, e.page, "duplicate of index entry " + std::to_string(it->second));
    r->entries_.push_back(e);
  }
  if (problems.size() == first_problem && h.page_count > 0 && expected != h.index_offset + sf::k_record_header_bytes)
    problems.push_back(path + ": index: the last record ends at " + std::to_string(expected - sf::k_record_header_bytes) +
                       " but the index starts at " + std::to_string(h.index_offset));
  if (problems.size() == first_problem && h.layout.shard_count == 1) {
    std::vector<PageId> ids(r->entries_.size());
    std::transform(r->entries_.begin(), r->entries_.end(), ids.begin(), [](const StoreEntry& e) { return e.page; });
    if (plan_hash(ids) != h.layout.plan_hash)
      problems.push_back(path + ": header plan_hash: does not match the pages of the index");
  }
  if (unlisted > 0) problems.push_back(path + ": index: " + std::to_string(unlisted) + " more problems not listed");
  if (problems.size() != first_problem) return nullptr;
  r->fd_ = fd.release();
  return r;
}

const StoreEntry* PageStoreReader::find(const PageId& page) const {
  const auto it = by_page_.find(page.pack());
  return it == by_page_.end() ? nullptr : &entries_[it->second];
}

std::unique_ptr<PageStoreReader::Decoder> PageStoreReader::make_decoder() const {
  std::unique_ptr<Decoder> d(new Decoder());
  d->dctx_ = ZSTD_createDCtx();
  if (d->dctx_ == nullptr) throw std::bad_alloc();  // zstd's allocation failure, as C++ reports any other
  return d;
}

PageError PageStoreReader::read_page(const PageId& page, std::span<uint8_t> out, Decoder& decoder,
                                     std::string* message) const {
  const PageError e = read_blob(page, decoder, message);
  if (e != PageError::none) return e;
  return decode_blob(page, out, decoder, message);
}

PageError PageStoreReader::read_blob(const PageId& page, Decoder& d, std::string* message) const {
  auto fail = [&](PageError e, const std::string& what) {
    if (message) *message = sf::page_where(path_, page) + ": " + what;
    return e;
  };
  d.blob_bytes_ = 0;
  const StoreEntry* e = find(page);
  if (!e) return fail(PageError::missing, "not in the store");
  const size_t total = sf::k_record_header_bytes + e->stored_bytes;  // stored_bytes <= compressBound(page)
  d.buffer_.resize(total);
  const int64_t n = fileio::pread_full(fd_, d.buffer_.data(), total, e->offset - sf::k_record_header_bytes);
  if (n < 0) return fail(PageError::io, "read failed: " + fileio::errno_text(errno));
  if (size_t(n) < total)
    return fail(PageError::truncated, "the file ends inside the page's record (read " + std::to_string(n) + " of " +
                                          std::to_string(total) + " bytes): truncated after it was opened");
  sf::RecordHeader rh;
  if (!sf::decode_record_header(d.buffer_.data(), rh)) return fail(PageError::corrupt, "record header damaged (magic or checksum)");
  if (rh.page != e->page.pack() || rh.stored_bytes != e->stored_bytes || rh.blob_hash != e->blob_hash ||
      rh.page_hash != e->page_hash)
    return fail(PageError::corrupt, "record header does not match its index entry");
  const std::span<const uint8_t> blob(d.buffer_.data() + sf::k_record_header_bytes, e->stored_bytes);
  if (sf::hash(blob) != e->blob_hash) return fail(PageError::corrupt, "blob checksum mismatch (compressed bytes damaged)");
  d.blob_at_ = sf::k_record_header_bytes;
  d.blob_bytes_ = e->stored_bytes;
  return PageError::none;
}

PageError PageStoreReader::decode_blob(const PageId& page, std::span<uint8_t> out, Decoder& d, std::string* message) const {
  auto fail = [&](PageError e, const std::string& what) {
    if (message) *message = sf::page_where(path_, page) + ": " + what;
    return e;
  };
  const StoreEntry* e = find(page);
  if (!e) return fail(PageError::missing, "not in the store");
  if (out.size() != page_bytes_)
    return fail(PageError::io, "output buffer holds " + std::to_string(out.size()) + " bytes, a page has " +
                                   std::to_string(page_bytes_));
  const std::span<const uint8_t> blob = d.blob();
  if (blob.size() != e->stored_bytes) return fail(PageError::io, "decode_blob without a successful read_blob");
  const unsigned long long declared = ZSTD_getFrameContentSize(blob.data(), blob.size());
  if (declared != page_bytes_)
    return fail(PageError::corrupt, "zstd frame does not declare the page size of " + std::to_string(page_bytes_) + " bytes");
  const size_t r = ddict_ ? ZSTD_decompress_usingDDict(d.dctx_, out.data(), out.size(), blob.data(), blob.size(), ddict_)
                          : ZSTD_decompressDCtx(d.dctx_, out.data(), out.size(), blob.data(), blob.size());
  if (ZSTD_isError(r)) return fail(PageError::corrupt, std::string("zstd: ") + ZSTD_getErrorName(r));
  if (r != page_bytes_)
    return fail(PageError::corrupt, "decompressed to " + std::to_string(r) + " bytes instead of " + std::to_string(page_bytes_));
  if (sf::hash(out) != e->page_hash) return fail(PageError::corrupt, "page checksum mismatch (decompressed bytes differ)");
  return PageError::none;
}

// ---------------------------------------------------------------------------------------------
// Compression

PageCompressor::PageCompressor(const StoreDesc& desc) : level_(desc.zstd_level) {
  // zstd returns null only when its allocation fails (validate(StoreDesc) loaded the
  // dictionary): reported as C++ reports any other allocation failure.
  cctx_ = ZSTD_createCCtx();
  if (cctx_ == nullptr) throw std::bad_alloc();
  if (!desc.dictionary.empty()) {
    cdict_ = ZSTD_createCDict(desc.dictionary.data(), desc.dictionary.size(), level_);
    if (cdict_ == nullptr) {
      ZSTD_freeCCtx(cctx_);
      throw std::bad_alloc();
    }
  }
}

PageCompressor::~PageCompressor() {
  ZSTD_freeCDict(cdict_);
  ZSTD_freeCCtx(cctx_);
}

PageDecompressor::PageDecompressor(const StoreDesc& desc) {
  dctx_ = ZSTD_createDCtx();  // null only when zstd's allocation fails (see PageCompressor)
  if (dctx_ == nullptr) throw std::bad_alloc();
  if (!desc.dictionary.empty()) {
    ddict_ = ZSTD_createDDict(desc.dictionary.data(), desc.dictionary.size());
    if (ddict_ == nullptr) {
      ZSTD_freeDCtx(dctx_);
      throw std::bad_alloc();
    }
  }
}

PageDecompressor::~PageDecompressor() {
  ZSTD_freeDDict(ddict_);
  ZSTD_freeDCtx(dctx_);
}

bool PageDecompressor::decompress(std::span<const uint8_t> blob, std::span<uint8_t> out) const {
  const size_t r = ddict_ ? ZSTD_decompress_usingDDict(dctx_, out.data(), out.size(), blob.data(), blob.size(), ddict_)
                          : ZSTD_decompressDCtx(dctx_, out.data(), out.size(), blob.data(), blob.size());
  return !ZSTD_isError(r) && r == out.size();
}

std::vector<uint8_t> PageCompressor::compress(std::span<const uint8_t> page) const {
  std::vector<uint8_t> out(ZSTD_compressBound(page.size()));
  // One-shot calls with fixed parameters: the frame depends only on the page, the level and
  // the dictionary (content size written, no zstd checksum: the store has its own hashes).
  const size_t r = cdict_ ? ZSTD_compress_usingCDict(cctx_, out.data(), out.size(), page.data(), page.size(), cdict_)
                          : ZSTD_compressCCtx(cctx_, out.data(), out.size(), page.data(), page.size(), level_);
  TVT_CHECK(!ZSTD_isError(r));  // cannot fail with a compressBound-sized output
  out.resize(r);
  return out;
}

Result<std::vector<uint8_t>> train_dictionary(std::span<const std::vector<uint8_t>> samples, size_t dict_bytes) {
  if (dict_bytes < 256 || dict_bytes > sf::k_max_dictionary_bytes)
    return make_error("train dictionary: dict_bytes: must be 256 bytes to 64 MiB, got " + std::to_string(dict_bytes));
  if (samples.size() < 8) return make_error("train dictionary: samples: need at least 8 sample pages, got " + std::to_string(samples.size()));
  std::vector<uint8_t> all;
  std::vector<size_t> sizes;
  for (const auto& s : samples) {
    all.insert(all.end(), s.begin(), s.end());
    sizes.push_back(s.size());
  }
  std::vector<uint8_t> dict(dict_bytes);
  const size_t r = ZDICT_trainFromBuffer(dict.data(), dict.size(), all.data(), sizes.data(), unsigned(sizes.size()));
  if (ZDICT_isError(r)) return make_error(std::string("train dictionary: zstd: ") + ZDICT_getErrorName(r));
  dict.resize(r);
  return dict;
}

}  // namespace tvt
