// streaming/file_io.h write paths: a failed write (an injected short write / ENOSPC at a chosen
// byte, or a real full tmpfs) is an error naming the file and the OS error, and leaves neither
// a half-written target nor a temporary behind. Image writes (compose/image.h) go through the
// same checked writes.
#include <gtest/gtest.h>

#include <cerrno>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include "compose/image.h"
#include "streaming/file_io.h"
#include "support/small_tmpfs.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;
using namespace tvt;

namespace {

constexpr uint64_t k_no_fault = std::numeric_limits<uint64_t>::max();

class FileIo : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = test::fresh_test_dir("tvt_file_io"); }
  void TearDown() override {
    fileio::inject_write_failure(k_no_fault, 0);
    fs::remove_all(dir_);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::vector<std::string> names() const {
    std::vector<std::string> n;
    for (const auto& e : fs::directory_iterator(dir_)) n.push_back(e.path().filename().string());
    return n;
  }
  static std::string read(const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
  }
  fs::path dir_;
};

ImageRGBA8 noise_image(int w, int h) {
  ImageRGBA8 image(w, h);
  uint32_t state = 12345;
  for (uint8_t& t : image.texels) {
    state = state * 1664525u + 1013904223u;
    t = uint8_t(state >> 24);  // incompressible: the PNG is about as large as the texels
  }
  return image;
}

TEST_F(FileIo, AStagedFileAppearsOnlyAtCommitAndAnUncommittedOneLeavesNothing) {
  {
    auto f = fileio::StagedFile::create(path("a.txt"));
    ASSERT_TRUE(f.ok()) << f.error().message;
    ASSERT_TRUE(f->append("hello ").ok());
    ASSERT_TRUE(f->append("world").ok());
    EXPECT_FALSE(fs::exists(path("a.txt")));
    ASSERT_TRUE(f->commit().ok());
  }
  EXPECT_EQ(read(path("a.txt")), "hello world");
  {
    auto f = fileio::StagedFile::create(path("b.txt"));
    ASSERT_TRUE(f.ok());
    ASSERT_TRUE(f->append("never committed").ok());
  }
  EXPECT_EQ(names(), std::vector<std::string>{"a.txt"});
}

TEST_F(FileIo, AWriteThatMeetsAFullDiskFailsNamingTheFileAndTheOsError) {
  std::ofstream(path("earlier.txt")) << "earlier contents";
  fileio::inject_write_failure(10, ENOSPC);  // a short write at byte 10, then ENOSPC
  {
    auto f = fileio::StagedFile::create(path("earlier.txt"));
    ASSERT_TRUE(f.ok());
    const Status w = f->append(std::string(64, 'x'));
    ASSERT_FALSE(w.ok());
    EXPECT_NE(w.error().message.find(path("earlier.txt")), std::string::npos) << w.error().message;
    EXPECT_NE(w.error().message.find("No space left on device"), std::string::npos) << w.error().message;
    // Once failed, the file stays failed: no later append or commit claims success.
    EXPECT_FALSE(f->append("y").ok());
    EXPECT_FALSE(f->commit().ok());
  }
  EXPECT_EQ(read(path("earlier.txt")), "earlier contents");
  EXPECT_EQ(names(), std::vector<std::string>{"earlier.txt"});
}

TEST_F(FileIo, EveryByteOffsetOfAFailureIsCaughtByTheDurableWrite) {
  const std::string text(300, 'z');
  for (uint64_t at : {uint64_t(0), uint64_t(1), uint64_t(150), uint64_t(299)}) {
    fileio::inject_write_failure(at, EIO);
    const Status w = fileio::write_file_durable(path("t.txt"), text.data(), text.size());
    ASSERT_FALSE(w.ok()) << "failure at byte " << at;
    EXPECT_NE(w.error().message.find("Input/output error"), std::string::npos) << w.error().message;
    EXPECT_TRUE(names().empty()) << "failure at byte " << at;
  }
  fileio::inject_write_failure(300, EIO);  // exactly enough room
  EXPECT_TRUE(fileio::write_file_durable(path("t.txt"), text.data(), text.size()).ok());
  EXPECT_EQ(read(path("t.txt")), text);
}

TEST_F(FileIo, AnImageWriteThatMeetsAFullDiskFailsAndKeepsTheEarlierImage) {
  ASSERT_TRUE(write_image(path("frame.png"), noise_image(8, 8)).ok());
  const std::string before = read(path("frame.png"));
  for (const char* name : {"frame.png", "frame.exr", "frame.tif"}) {
    fileio::inject_write_failure(100, ENOSPC);
    const Status w = write_image(path(name), noise_image(64, 64));
    ASSERT_FALSE(w.ok()) << name;
    EXPECT_NE(w.error().message.find(path(name)), std::string::npos) << w.error().message;
    EXPECT_NE(w.error().message.find("No space left on device"), std::string::npos) << w.error().message;
  }
  EXPECT_EQ(read(path("frame.png")), before);
  EXPECT_EQ(names(), std::vector<std::string>{"frame.png"});
}

TEST_F(FileIo, ARealFullTmpfsFailsImageAndFileWritesWithNoSpaceLeft) {
  test::SmallTmpfs disk(dir_ / "small", 64);
  if (!disk.ok()) GTEST_SKIP() << disk.why();
  const std::string png = (disk.dir() / "big.png").string();
  const Status w = write_image(png, noise_image(256, 256));  // about 256 KiB of PNG
  ASSERT_FALSE(w.ok());
  EXPECT_NE(w.error().message.find(png), std::string::npos) << w.error().message;
  EXPECT_NE(w.error().message.find("No space left on device"), std::string::npos) << w.error().message;
  const std::vector<char> bytes(128 * 1024, 'q');
  const std::string bin = (disk.dir() / "big.bin").string();
  const Status d = fileio::write_file_durable(bin, bytes.data(), bytes.size());
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.error().message.find(bin), std::string::npos) << d.error().message;
  EXPECT_TRUE(fs::is_empty(disk.dir()));  // no 0-byte image, no temporary
  // What fits is written whole.
  EXPECT_TRUE(write_image((disk.dir() / "small.png").string(), noise_image(8, 8)).ok());
}

}  // namespace
