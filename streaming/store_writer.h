// Internal to streaming/: appends records to `<path>.partial`, resumes a partial that is a
// prefix of the same bake, and finishes the store (index, header, fsync, rename). Used by
// bake_store and merge_stores. One writer per path at a time (flock on the .partial).
#pragma once
#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "streaming/file_io.h"
#include "streaming/store_format.h"

namespace tvt::store_format {

// Which header fields of an in-progress store differ, with both plans: "it differs in plan
// (the partial: V = 2^10, ..., plan of 85 pages (hash ...), shard 0/1; this bake: ...)".
std::string header_difference(const uint8_t* partial, const uint8_t* wanted);

class StoreWriter {
 public:
  // Opens (creating if needed) and locks `<path>.partial`; does not change it yet.
  static Result<StoreWriter> open(const std::string& path);

  // Keeps the complete records of an existing partial whose header and dictionary are exactly
  // `header` / `dictionary` and whose records are the first pages of `pages`; cuts off the rest.
  // Returns how many records were kept; 0 with `note` saying why when the partial is too short
  // to hold a header (the caller then calls start()). A partial of another bake is an error that
  // says how it differs (header_difference()), and is left untouched.
  Result<uint64_t> resume(const std::array<uint8_t, k_header_bytes>& header, std::span<const uint8_t> dictionary,
                          std::span<const PageId> pages, uint64_t page_bytes, std::string& note);
  // Empties the partial and writes the in-progress header and the dictionary.
  Status start(const std::array<uint8_t, k_header_bytes>& header, std::span<const uint8_t> dictionary);

  // Appends one record (buffered; written by flush() or when the buffer is large).
  Status append(const PageId& page, std::span<const uint8_t> blob, uint64_t blob_hash, uint64_t page_hash);
  Status flush();

  // Writes the index after the records and the final header (index fields filled in), syncs,
  // and renames the partial to the store path. Returns the store's size in bytes.
  Result<uint64_t> finish(Header header);
  // Syncs what was written so far (after a cancel or a source error) and unlocks.
  void abandon();
  // Deletes the partial (a failed merge: there is nothing to resume) and unlocks.
  void discard();

  uint64_t records() const { return entries_.size(); }
  // Record `i` (0-based, in append order) as written: its entry, and its blob read back into
  // `blob` once flush() put it on disk. False when it is not on disk yet or cannot be read.
  const StoreEntry& entry(uint64_t i) const { return entries_[size_t(i)]; }
  bool read_blob(uint64_t i, std::vector<uint8_t>& blob) const;
  uint64_t stored_bytes() const { return stored_bytes_; }
  const std::string& partial_path() const { return partial_; }

 private:
  StoreWriter() = default;
  std::string path_, partial_;
  fileio::UniqueFd fd_;
  uint64_t end_ = 0;  // file offset after the last record (buffered ones included)
  uint64_t written_ = 0;  // file offset up to which bytes are on disk
  uint64_t stored_bytes_ = 0;
  std::vector<uint8_t> pending_;
  std::vector<StoreEntry> entries_;
};

}  // namespace tvt::store_format
