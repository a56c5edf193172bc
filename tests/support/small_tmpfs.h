// A real full disk for write-path tests: a tmpfs of a few KiB mounted on a fresh folder for
// the life of the object (mount(2) needs root / CAP_SYS_ADMIN). Where mounting is not allowed,
// ok() is false and why() says so: the test skips with that reason (GTEST_SKIP), it does not
// fail.
#pragma once
#include <sys/mount.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <string>

namespace tvt::test {

class SmallTmpfs {
 public:
  // Mounts a tmpfs of `kib` KiB on `dir` (created if missing).
  SmallTmpfs(const std::filesystem::path& dir, unsigned kib) : dir_(dir) {
    std::filesystem::create_directories(dir_);
    const std::string options = "size=" + std::to_string(kib) + "k";
    if (::mount("tmpfs", dir_.c_str(), "tmpfs", 0, options.c_str()) == 0)
      mounted_ = true;
    else
      why_ = "cannot mount a " + std::to_string(kib) + " KiB tmpfs on " + dir_.string() + " (" + std::strerror(errno) +
             "; needs root / CAP_SYS_ADMIN)";
  }
  ~SmallTmpfs() {
    if (mounted_) ::umount2(dir_.c_str(), MNT_DETACH);
  }
  SmallTmpfs(const SmallTmpfs&) = delete;
  SmallTmpfs& operator=(const SmallTmpfs&) = delete;
  bool ok() const { return mounted_; }
  const std::string& why() const { return why_; }
  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path dir_;
  bool mounted_ = false;
  std::string why_;
};

}  // namespace tvt::test
