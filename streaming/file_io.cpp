#include "streaming/file_io.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>

namespace tvt::fileio {

void UniqueFd::reset() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

std::string errno_text(int err) { return std::strerror(err); }

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
    const ssize_t n = ::pwrite(fd, p + done, bytes - done, off_t(offset + done));
    if (n < 0) {
      if (errno == EINTR) continue;
      return make_error(path + ": cannot write " + std::to_string(bytes) + " bytes at offset " + std::to_string(offset) +
                        ": " + errno_text(errno));
    }
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
  const std::string temporary = path + ".tmp-" + std::to_string(::getpid());
  Status written = [&]() -> Status {
    UniqueFd fd(::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644));
    if (fd.get() < 0) return make_error(path + ": cannot create " + temporary + ": " + errno_text(errno));
    if (auto w = pwrite_full(fd.get(), bytes, size, 0, temporary); !w) return w;
    return fsync_file(fd.get(), temporary);
  }();
  if (written) written = rename_durable(temporary, path);
  if (!written) ::unlink(temporary.c_str());
  return written;
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
