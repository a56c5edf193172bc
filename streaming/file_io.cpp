#include "streaming/file_io.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>

namespace tvt::fileio {

void UniqueFd::reset() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

std::string errno_text(int err) { return std::strerror(err); }

namespace {

// inject_write_failure(): bytes written so far, the mark, and the error past it.
std::atomic<uint64_t> g_written{0};
std::atomic<uint64_t> g_fail_after{std::numeric_limits<uint64_t>::max()};
std::atomic<int> g_fail_errno{ENOSPC};

// One pwrite, unless inject_write_failure() says the disk is full: then fewer bytes, or -1
// with errno set.
ssize_t checked_pwrite(int fd, const void* data, size_t bytes, off_t offset) {
  const uint64_t limit = g_fail_after.load(std::memory_order_relaxed);
  if (limit != std::numeric_limits<uint64_t>::max()) {
    const uint64_t done = g_written.load(std::memory_order_relaxed);
    if (done >= limit) {
      errno = g_fail_errno.load(std::memory_order_relaxed);
      return -1;
    }
    bytes = size_t(std::min<uint64_t>(bytes, limit - done));
  }
  const ssize_t n = ::pwrite(fd, data, bytes, offset);
  if (n > 0) g_written.fetch_add(uint64_t(n), std::memory_order_relaxed);
  return n;
}

}  // namespace

void inject_write_failure(uint64_t after_bytes, int err) {
  g_written = 0;
  g_fail_errno = err;
  g_fail_after = after_bytes;
}

int64_t pread_full(int fd, void* data, size_t bytes, uint64_t offset) {
  auto* p = static_cast<uint8_t*>(data);
  size_t done = 0;
  while (done < bytes) {
    const ssize_t n = ::pread(fd, p + done, bytes - done, off_t(offset + done));
    if (n < 0) {
      if (errno == EINTR) continue;
      return -1;
    }
    if (n == 0) break;
    done += size_t(n);
  }
  return int64_t(done);
}

Status pwrite_full(int fd, const void* data, size_t bytes, uint64_t offset, const std::string& path) {
  const auto* p = static_cast<const uint8_t*>(data);
  size_t done = 0;
  while (done < bytes) {
    const ssize_t n = checked_pwrite(fd, p + done, bytes - done, off_t(offset + done));
    if (n < 0) {
      if (errno == EINTR) continue;
      return make_error(path + ": cannot write " + std::to_string(bytes) + " bytes at offset " + std::to_string(offset) +
                        ": " + errno_text(errno));
    }
    if (n == 0)  // no progress and no error: would loop forever
      return make_error(path + ": cannot write " + std::to_string(bytes) + " bytes at offset " + std::to_string(offset) +
                        ": the system wrote nothing");
    done += size_t(n);
  }
  return Ok{};
}

Status fsync_file(int fd, const std::string& path) {
  if (::fsync(fd) != 0) return make_error(path + ": fsync failed: " + errno_text(errno));
  return Ok{};
}

Status rename_durable(const std::string& from, const std::string& to) {
  if (::rename(from.c_str(), to.c_str()) != 0)
    return make_error(to + ": cannot rename " + from + " to it: " + errno_text(errno));
  std::string dir = std::filesystem::path(to).parent_path().string();
  if (dir.empty()) dir = ".";
  UniqueFd d(::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (d.get() < 0 || ::fsync(d.get()) != 0) return make_error(to + ": renamed, but cannot sync its folder: " + errno_text(errno));
  return Ok{};
}

Status write_file_durable(const std::string& path, const void* bytes, size_t size) {
  auto file = StagedFile::create(path);
  if (!file) return file.error();
  if (auto w = file->append(bytes, size); !w) return w;
  return file->commit();
}

Result<StagedFile> StagedFile::create(const std::string& path) {
  StagedFile f;
  f.path_ = path;
  f.temporary_ = path + ".tmp-" + std::to_string(::getpid());
  f.fd_ = UniqueFd(::open(f.temporary_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644));
  if (f.fd_.get() < 0) return make_error(path + ": cannot create " + f.temporary_ + ": " + errno_text(errno));
  return f;
}

StagedFile& StagedFile::operator=(StagedFile&& o) noexcept {
  if (this != &o) {
    remove_temporary();
    path_ = std::move(o.path_);
    temporary_ = std::move(o.temporary_);
    fd_ = std::move(o.fd_);
    size_ = o.size_;
    failed_ = o.failed_;
  }
  return *this;
}

StagedFile::~StagedFile() { remove_temporary(); }

void StagedFile::remove_temporary() {
  if (fd_.get() < 0) return;  // moved from, or committed
  fd_.reset();
  ::unlink(temporary_.c_str());
}

Status StagedFile::append(const void* data, size_t bytes) {
  if (fd_.get() < 0 || failed_) return make_error(path_ + ": not open for writing (an earlier write failed)");
  if (auto w = pwrite_full(fd_.get(), data, bytes, size_, path_); !w) {
    failed_ = true;
    return w;
  }
  size_ += bytes;
  return Ok{};
}

Status StagedFile::commit() {
  if (fd_.get() < 0 || failed_) return make_error(path_ + ": not open for writing (an earlier write failed)");
  if (auto s = fsync_file(fd_.get(), path_); !s) {
    failed_ = true;
    return s;
  }
  // close() reports errors that some file systems (NFS) defer to it.
  if (::close(fd_.release()) != 0) {
    const int err = errno;
    ::unlink(temporary_.c_str());
    return make_error(path_ + ": cannot close " + temporary_ + ": " + errno_text(err));
  }
  if (auto s = rename_durable(temporary_, path_); !s) {
    ::unlink(temporary_.c_str());
    return s;
  }
  return Ok{};
}

Result<uint64_t> file_size(int fd, const std::string& path) {
  struct stat st {};
  if (::fstat(fd, &st) != 0) return make_error(path + ": cannot stat: " + errno_text(errno));
  if (!S_ISREG(st.st_mode)) return make_error(path + ": not a regular file");
  return uint64_t(st.st_size);
}

Status lock_exclusive(int fd, const std::string& path) {
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    if (errno == EWOULDBLOCK) return make_error(path + ": another terravt process holds it (locked)");
    return make_error(path + ": cannot lock: " + errno_text(errno));
  }
  return Ok{};
}

}  // namespace tvt::fileio
