// POSIX file helpers for the page store: an owning descriptor, full pread/pwrite loops that
// survive EINTR and short transfers, durable rename. Errors name the file.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>

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
// Size of an open file, or an error naming `path`.
Result<uint64_t> file_size(int fd, const std::string& path);
// Takes a non-blocking exclusive lock on `fd` (flock): fails if another process holds it.
Status lock_exclusive(int fd, const std::string& path);

}  // namespace tvt::fileio
