// POSIX file helpers for every file terravt writes: an owning descriptor, full pread/pwrite
// loops that survive EINTR and short transfers, durable rename, staged (temporary name, fsync,
// rename) files. Every write is checked: a full disk or an I/O error is an error naming the
// file and the OS error, never a silently short file. Errors name the file.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "vt/result.h"

namespace tvt::fileio {

class UniqueFd {
 public:
  UniqueFd() = default;
  explicit UniqueFd(int fd) : fd_(fd) {}
  ~UniqueFd() { reset(); }
  UniqueFd(UniqueFd&& o) noexcept : fd_(o.release()) {}
  UniqueFd& operator=(UniqueFd&& o) noexcept {
    if (this != &o) {
      reset();
      fd_ = o.release();
    }
    return *this;
  }
  UniqueFd(const UniqueFd&) = delete;
  UniqueFd& operator=(const UniqueFd&) = delete;
  int get() const { return fd_; }
  int release() {
    const int f = fd_;
    fd_ = -1;
    return f;
  }
  void reset();

 private:
  int fd_ = -1;
};

std::string errno_text(int err);

// Reads up to `bytes` at `offset`; returns the count read (less at end of file) or -1 with
// errno set.
int64_t pread_full(int fd, void* data, size_t bytes, uint64_t offset);
// Writes everything or returns an error "<path>: cannot write ...: <errno text>".
Status pwrite_full(int fd, const void* data, size_t bytes, uint64_t offset, const std::string& path);
Status fsync_file(int fd, const std::string& path);
// Renames `from` over `to` and syncs the folder, so the rename survives a power cut.
Status rename_durable(const std::string& from, const std::string& to);
// Writes `bytes` to `path` through a temporary file in the same folder, fsync and
// rename_durable: a failure leaves any earlier file untouched and no temporary behind.
Status write_file_durable(const std::string& path, const void* bytes, size_t size);

// A file written front to back under a temporary name in its folder (<path>.tmp-<pid>) and
// renamed over `path` by commit() after fsync. Until commit() succeeds `path` is untouched;
// a StagedFile destroyed uncommitted removes its temporary. Move-only; one owner thread.
class StagedFile {
 public:
  // Creates the temporary (truncating one a crashed run of this pid left). Errors name `path`.
  static Result<StagedFile> create(const std::string& path);
  StagedFile() = default;
  StagedFile(StagedFile&&) noexcept = default;
  StagedFile& operator=(StagedFile&& o) noexcept;
  ~StagedFile();
  // Every byte or an error "<path>: cannot write ...: <OS error>"; after an error the
  // file is unusable (later appends and commit() fail).
  Status append(const void* data, size_t bytes);
  Status append(std::string_view text) { return append(text.data(), text.size()); }
  // fsync, then rename_durable over path(). Once only.
  Status commit();
  bool is_open() const { return fd_.get() >= 0; }
  const std::string& path() const { return path_; }
  const std::string& temporary_path() const { return temporary_; }

 private:
  void remove_temporary();
  std::string path_, temporary_;
  UniqueFd fd_;
  uint64_t size_ = 0;
  bool failed_ = false;
};

// Fault injection, for tests of the write paths: once this process has written `after_bytes`
// bytes through pwrite_full (every StagedFile, durable write and page-store write goes through
// it), each further write fails with `err`; a write crossing the mark is first cut short
// there, as on a full disk. after_bytes = UINT64_MAX turns it off and resets the count.
// The terravt executable sets it from TERRAVT_FAULT_WRITE_AFTER=<bytes> (ENOSPC), so a test
// can make it meet a full disk at a chosen byte; the library itself reads no environment.
void inject_write_failure(uint64_t after_bytes, int err);
// Size of an open file, or an error naming `path`.
Result<uint64_t> file_size(int fd, const std::string& path);
// Takes a non-blocking exclusive lock on `fd` (flock): fails if another process holds it.
Status lock_exclusive(int fd, const std::string& path);

}  // namespace tvt::fileio
