// The terravt executable against hostile use: a second run on an output another run owns, a
// bake over another plan's .partial, option values that are NaN, infinite, out of range, or
// name a directory, FIFO, socket or device, and JSON nested past the parsers' limit. Every
// case must end quickly with exit code 2 (1 for verify/info), name the flag or file, and
// leave what was there untouched. Each command runs under `timeout`, so a hang fails the test
// instead of stalling the suite.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/file.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "compose/image.h"
#include "streaming/store_format.h"
#include "support/cli.h"
#include "support/file_scene.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;
namespace sf = tvt::store_format;

namespace {

class HostileCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = tvt::test::fresh_test_dir("tvt_hostile_cli");
    scene_ = tvt::test::write_small_default_scene(dir_);
  }
  void TearDown() override {
    for (int fd : held_) ::close(fd);
    fs::remove_all(dir_);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  // Runs terravt (at most 120 s: 124 means it hung); stdout+stderr land in `output_`.
  int run(const std::string& args) { return tvt::test::run_terravt(dir_, args, output_, "timeout 120 "); }
  std::string bake_args(const std::string& out) const {
    return "bake --cpu --quiet --method linear --scene " + scene_ + " --out " + out;
  }
  bool said(const std::string& text) const { return output_.find(text) != std::string::npos; }

  std::string make_fifo(const std::string& name) const {
    const std::string p = path(name);
    EXPECT_EQ(::mkfifo(p.c_str(), 0644), 0);
    return p;
  }
  std::string make_socket(const std::string& name) {
    const std::string p = path(name);
    const int s = ::socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::strncpy(a.sun_path, p.c_str(), sizeof(a.sun_path) - 1);
    EXPECT_EQ(::bind(s, reinterpret_cast<const sockaddr*>(&a), sizeof(a)), 0) << p;
    held_.push_back(s);
    return p;
  }
  // A link to /dev/null: a device node in the place of a file (were it replaced, only the link would go).
  std::string make_device_link(const std::string& name) const {
    const std::string p = path(name);
    fs::create_symlink("/dev/null", p);
    return p;
  }
  // Holds the lock another terravt run would hold on `output` until the test ends.
  void hold_output_lock(const std::string& output) {
    const int fd = ::open((output + ".lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    ASSERT_GE(fd, 0);
    ASSERT_EQ(::flock(fd, LOCK_EX | LOCK_NB), 0);
    held_.push_back(fd);
  }
  static bool is_fifo(const std::string& p) { return fs::is_fifo(fs::symlink_status(p)); }

  fs::path dir_;
  std::string scene_;
  std::string output_;
  std::vector<int> held_;
};

std::string bytes(const std::string& file) {
  std::ifstream in(file, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

}  // namespace

// ---- concurrency: one run per output --------------------------------------------------------

TEST_F(HostileCli, ASecondRunOnAnOutputAnotherRunOwnsIsRefusedNamingItAndWritesNothing) {
  const std::string render_out = path("render"), compare_out = path("compare"), png = path("sheet.png"),
                    exr = path("meta.exr");
  for (const std::string& out : {render_out, compare_out, png, exr}) hold_output_lock(out);
  const std::pair<std::string, std::string> runs[] = {
      {"render --quiet --frames 2 --width 64 --height 36 --scene " + scene_ + " --out " + render_out, render_out},
      {"compare --quiet --scene " + scene_ + " --out " + compare_out, compare_out},
      {"compose --device cpu --size 16 --methods linear --scene " + scene_ + " --out " + png, png},
      {"metatex --generator cobbles --resolution 64 --out " + exr, exr},
  };
  for (const auto& [args, out] : runs) {
    EXPECT_EQ(run(args), 2) << args << ": " << output_;
    EXPECT_TRUE(said("--out: " + out + " is in use: " + out + ".lock: another terravt process holds it (locked)"))
        << args << ": " << output_;
    EXPECT_FALSE(fs::exists(out)) << args;
  }
  // Let go (as the first run would on exit): the next run owns the output, and removes its lock file.
  for (int fd : held_) ::close(fd);
  held_.clear();
  fs::remove(png + ".lock");
  ASSERT_EQ(run("compose --device cpu --size 16 --methods linear --scene " + scene_ + " --out " + png), 0) << output_;
  EXPECT_TRUE(fs::exists(png));
  EXPECT_FALSE(fs::exists(png + ".lock"));
}

TEST_F(HostileCli, TheOwnerOfAnOutputIsTheSameHoweverItsPathIsSpelt) {
  fs::create_directories(path("render"));
  hold_output_lock(path("render"));
  EXPECT_EQ(run("render --quiet --scene " + scene_ + " --out " + path("render") + "/"), 2) << output_;
  EXPECT_TRUE(said("another terravt process holds it")) << output_;
  EXPECT_EQ(run("render --quiet --scene " + scene_ + " --out " + path("x/../render")), 2) << output_;
  EXPECT_TRUE(said("another terravt process holds it")) << output_;
  EXPECT_FALSE(fs::exists(path("x")));
}

// ---- a .partial belongs to one bake plan ---------------------------------------------------

// Writes the first `keep` bytes of the finished store `from` as the .partial of `to`, with the
// in-progress header a bake writes (index fields 0): an interrupted bake of the same plan.
void make_partial(const std::string& from, const std::string& to, size_t keep) {
  std::string b = bytes(from);
  std::vector<std::string> problems;
  auto h = sf::decode_header(std::span(reinterpret_cast<const uint8_t*>(b.data()), sf::k_header_bytes), b.size(), from,
                             problems);
  ASSERT_TRUE(h) << (problems.empty() ? "" : problems.front());
  h->index_offset = h->index_bytes = h->index_hash = 0;
  const auto header = sf::encode_header(*h);
  b.replace(0, header.size(), reinterpret_cast<const char*>(header.data()), header.size());
  std::ofstream(to + ".partial", std::ios::binary) << b.substr(0, keep);
}

TEST_F(HostileCli, ABakeOfAnotherPlanRefusesAPartialNamingBothPlansAndTheSamePlanResumesIt) {
  ASSERT_EQ(run(bake_args(path("whole.tvt")) + " --mips 1,3"), 0) << output_;
  const std::string whole = bytes(path("whole.tvt"));
  const std::string out = path("out.tvt");
  make_partial(path("whole.tvt"), out, whole.size() / 2);
  const std::string partial = bytes(out + ".partial");

  for (const std::string other : {" --mips 2,3", " --mips 1,3 --region 0,0,512,512", " --mips 1,3 --level 5"}) {
    EXPECT_EQ(run(bake_args(out) + other), 1) << other << ": " << output_;
    EXPECT_TRUE(said(out + ".partial: holds " + std::to_string(partial.size()) + " bytes of another bake, not resumed"))
        << other << ": " << output_;
    EXPECT_TRUE(said("(the partial: V = 2^10, 128+4-texel pages, plan of 21 pages")) << other << ": " << output_;
    EXPECT_TRUE(said("--restart")) << output_;
    EXPECT_EQ(bytes(out + ".partial"), partial) << other;  // untouched
    EXPECT_FALSE(fs::exists(out)) << other;
  }
  EXPECT_EQ(run(bake_args(out) + " --mips 2,3"), 1);
  EXPECT_TRUE(said("it differs in plan (the partial: V = 2^10, 128+4-texel pages, plan of 21 pages")) << output_;
  EXPECT_TRUE(said("this bake: V = 2^10, 128+4-texel pages, plan of 5 pages")) << output_;

  // The same plan resumes it, to the same bytes as the uninterrupted bake.
  ASSERT_EQ(run(bake_args(out) + " --mips 1,3"), 0) << output_;
  EXPECT_TRUE(said("resumed)")) << output_;
  EXPECT_FALSE(said(" (0 resumed)")) << output_;
  EXPECT_TRUE(bytes(out) == whole);

  // --restart discards another plan's partial.
  make_partial(path("whole.tvt"), path("again.tvt"), whole.size() / 2);
  ASSERT_EQ(run(bake_args(path("again.tvt")) + " --mips 2,3 --restart"), 0) << output_;
  EXPECT_TRUE(said("(0 resumed)")) << output_;
  EXPECT_FALSE(fs::exists(path("again.tvt.partial")));
}

// ---- option values -------------------------------------------------------------------------

TEST_F(HostileCli, BadBakeValuesAreRefusedUnderTheirFlagWithTheValidRange) {
  fs::create_directories(path("dict-folder"));
  const std::string fifo = make_fifo("dict.fifo");
  const std::string out = path("out.tvt");
  const std::pair<std::string, std::string> cases[] = {
      {" --dict " + path("dict-folder"), "--dict: " + path("dict-folder") + ": is a directory, not a regular file"},
      {" --dict " + fifo, "--dict: " + fifo + ": is a FIFO, not a regular file"},
      {" --mips 0,99", "--mips: lo,hi with 0 <= lo <= hi <= 3 (the top mip of this scene's 2^10 texels), got 0,99"},
      {" --mips 3,1", "--mips: lo,hi with 0 <= lo <= hi <= 3"},
      {" --region 0,0,2000,16", "--region: x,y,width,height must lie inside the 1024 x 1024 level-0 texels"},
      {" --region 1000,0,100,16", "got 1000,0,100,16"},
      {" --region 9223372036854775807,0,1,1", "--region: x,y,width,height must lie inside"},
      {" --region 0,0,1,9223372036854775807", "--region: x,y,width,height must lie inside"},
      {" --scene " + fifo, "--scene: " + fifo + ": is a FIFO, not a regular file"},
      {" --scene " + path("dict-folder"), "is a directory, not a regular file"},
      {" --mip-strategy supersample:3", "--mip-strategy: mip strategy: must be direct, prefiltered or supersample:S"},
      {" --mip-strategy supersample:4", "--mip-strategy: only used with --pyramid composed"},
  };
  for (const auto& [args, message] : cases) {
    EXPECT_EQ(run(bake_args(out) + args), 2) << args << ": " << output_;
    EXPECT_TRUE(said(message)) << args << ": " << output_;
    EXPECT_FALSE(fs::exists(out)) << args;
    EXPECT_FALSE(fs::exists(out + ".partial")) << args;
  }
}

TEST_F(HostileCli, NanInfiniteAndUnwritableValuesAreRefusedUnderTheirFlagBeforeAnyWork) {
  const std::string out = path("m.exr");
  fs::create_directories(path("r"));
  const std::string meta = "metatex --generator cobbles --resolution 64 --auto --out " + out;
  const std::pair<std::string, std::string> cases[] = {
      {meta + " --blur nan", "--blur: must be a finite number in [0, 1024], got nan"},
      {meta + " --blur inf", "--blur: must be a finite number in [0, 1024], got inf"},
      {meta + " --blur -1", "--blur: must be a finite number"},
      {meta + " --blur x", "--blur: must be a number"},
      {meta + " --threshold nan", "--threshold: must be a finite number in [0, 1], got nan"},
      {meta + " --threshold -inf", "--threshold: must be a finite number in [0, 1]"},
      {meta + " --threshold 1e999", "--threshold: must be a finite number"},
      {"render --fps nan --out " + path("r"), "--fps"},
      {"render --detail-relief inf --out " + path("r"), "--detail-relief"},
      {"bench frame --fps nan", "--fps: must be a finite number in [0.001, 1000], got nan"},
      {"bench frame --brilinear-band nan", "--brilinear-band"},
      {"bench-loader --synthetic --seconds nan", "--seconds"},
      {"bench-loader --synthetic --json " + path("no/such/b.json"), "--json: folder does not exist"},
      {"bench frame --json " + path("r"), "--json: " + path("r") + " is a directory"},
      {"render --mip-strategy supersample:128 --out " + path("r"), "--mip-strategy: mip strategy: must be direct, prefiltered or supersample:S"},
      {"render --mip-strategy prefiltered:2 --out " + path("r"), "got 'prefiltered:2'"},
      {"compare --mip-strategy nan --out " + path("r"), "--mip-strategy"},
      {"bench frame --mip-strategy supersample:3", "--mip-strategy"},
  };
  for (const auto& [args, message] : cases) {
    EXPECT_EQ(run(args), 2) << args << ": " << output_;
    EXPECT_TRUE(said(message)) << args << ": " << output_;
  }
  EXPECT_FALSE(fs::exists(out));
}

// ---- an output never replaces an input ---------------------------------------------------

// Every command that reads files refuses an output that is one of them, however the path is
// spelt (another spelling, a symbolic or a hard link), with --overwrite or not, before any work:
// the run would destroy what it reads. The inputs stay byte for byte what they were.
TEST_F(HostileCli, AnOutputThatIsAnInputOfTheSameRunIsRefusedNamingBothFlags) {
  // A scene under an image's name (compose writes images) and a camera path; dummy store parts.
  const std::string scene_png = path("scene.png");
  fs::copy_file(scene_, scene_png);
  ASSERT_EQ(run("render --scene " + scene_ + " --save-camera " + path("camera.json")), 0) << output_;
  const std::string camera = path("camera.json");
  fs::create_symlink(camera, path("camera-link.json"));
  fs::create_hard_link(scene_, path("scene-hard.json"));
  std::ofstream(path("part.tvt")) << "part";
  std::ofstream(path("nothing.tvt")) << "x";
  fs::create_directories(path("cmp"));
  fs::copy_file(camera, path("cmp/compare.json"));
  // Inputs under the names a run gives the files it writes beside its output and removes.
  fs::copy_file(scene_, path("st.tvt.partial"));
  fs::copy_file(scene_png, path("c.png.lock"));
  fs::copy_file(scene_, path("plot.svg"));
  fs::create_directories(path("pan"));
  fs::create_directories(path("pan2"));
  fs::copy_file(scene_, path("pan/compose-linear.png"));
  const std::string inputs[] = {scene_, scene_png, camera, path("part.tvt"), path("cmp/compare.json"),
                                path("st.tvt.partial"), path("c.png.lock"), path("plot.svg"), path("pan/compose-linear.png")};
  std::vector<std::string> before;
  for (const std::string& f : inputs) before.push_back(bytes(f));
  const std::pair<std::string, std::string> cases[] = {
      {"compose --device cpu --size 16 --scene " + scene_png + " --out " + scene_png, "--out " + scene_png + ": is the --scene file"},
      {"compose --device cpu --size 16 --methods linear --scene " + path("pan/compose-linear.png") + " --out " + path("s2.png") +
           " --panels " + path("pan"),
       "--panels linear " + path("pan/compose-linear.png") + ": is the --scene file"},
      {"bench compose --scene " + scene_ + " --json " + path("x/../scene.json"), "--json " + path("x/../scene.json") + ": is the --scene file"},
      {"bench mips --scene " + scene_ + " --json " + path("m.json") + " --svg " + path("scene-hard.json"), "--svg " + path("scene-hard.json") + ": is the --scene file"},
      {"bench frame --scene " + scene_ + " --json " + scene_, "--json " + scene_ + ": is the --scene file"},
      {"bench-loader --store " + path("part.tvt") + " --json " + path("part.tvt"), "--json " + path("part.tvt") + ": is the --store file"},
      {bake_args(scene_) + " --overwrite", "--out " + scene_ + ": is the --scene file"},
      {bake_args(path("b.tvt")) + " --dict auto --save-dict " + scene_ + " --overwrite", "--save-dict " + scene_ + ": is the --scene file"},
      {"render --quiet --scene " + scene_ + " --camera " + camera + " --save-camera " + path("camera-link.json") + " --overwrite",
       "--save-camera " + path("camera-link.json") + ": is the --camera file"},
      {"render --quiet --scene " + scene_ + " --page-table " + scene_ + " --overwrite --out " + path("r"), "--page-table " + scene_ + ": is the --scene file"},
      {"compare --quiet --scene " + scene_ + " --camera " + path("cmp/compare.json") + " --out " + path("cmp") + " --overwrite",
       "--out " + path("cmp/compare.json") + ": is the --camera file"},
      // Said before any advice to pass --overwrite.
      {"merge " + path("nothing.tvt") + " " + path("part.tvt") + " --out " + path("part.tvt"), "--out " + path("part.tvt") + ": is the part 2 file"},
      {"bake --cpu --quiet --method linear --scene " + path("st.tvt.partial") + " --out " + path("st.tvt") + " --restart",
       "--out " + path("st.tvt") + ": its " + path("st.tvt.partial") + " (written and removed by the run) is the --scene file"},
      {"compose --device cpu --size 16 --scene " + path("c.png.lock") + " --out " + path("c.png"),
       "--out " + path("c.png") + ": its " + path("c.png.lock") + " (written and removed by the run) is the --scene file"},
      {"bench mips --scene " + path("plot.svg") + " --json " + path("plot.json"),
       "--svg (the --json name as .svg; pass --svg to move it) " + path("plot.svg") + ": is the --scene file"},
  };
  fs::create_directories(path("x"));
  for (const auto& [args, message] : cases) {
    EXPECT_EQ(run(args), 2) << args << ": " << output_;
    EXPECT_TRUE(said(message + "; an output never replaces an input")) << args << ": " << output_;
  }
  // Nor one output another: the sheet over a panel.
  EXPECT_EQ(run("compose --device cpu --size 16 --methods linear --scene " + scene_ + " --out " +
                path("pan2/compose-linear.png") + " --panels " + path("pan2")),
            2)
      << output_;
  EXPECT_TRUE(said("--out " + path("pan2/compose-linear.png") + ": is also --panels linear; two outputs cannot share a file"))
      << output_;
  EXPECT_TRUE(fs::is_empty(path("pan2")));
  for (size_t i = 0; i < before.size(); ++i) EXPECT_EQ(bytes(inputs[i]), before[i]) << inputs[i];
  EXPECT_FALSE(fs::exists(path("b.tvt")));
  EXPECT_FALSE(fs::exists(path("r")));
  EXPECT_FALSE(fs::exists(path("st.tvt")));
  EXPECT_FALSE(fs::exists(path("c.png")));
}

// The files a scene names are inputs too: a material image in the place of an output is
// refused once the scene is loaded, naming the scene's field, before anything is written.
TEST_F(HostileCli, AnOutputThatIsAFileTheSceneNamesIsRefusedNamingTheField) {
  tvt::ImageRGBA8 rock(32, 32);
  for (size_t i = 0; i < rock.texels.size(); ++i) rock.texels[i] = uint8_t(i * 37 % 251);
  ASSERT_TRUE(tvt::write_image(path("rock.png"), rock).ok());
  fs::create_directories(path("panels"));
  fs::create_symlink(path("rock.png"), path("panels/compose-linear.png"));
  fs::create_directories(path("cmp"));
  fs::create_symlink(path("rock.png"), path("cmp/compare.json"));
  const std::string scene = tvt::test::write_scene_json(dir_, "rock_scene.json", R"(
      {"name": "ground", "albedo": {"generator": "sand", "resolution": 16}, "weight": "remainder"},
      {"name": "rock", "albedo": {"image": "rock.png"}, "weight": {"rule": {"height": [0.5, 1]}}})");
  const std::string field = ": is the scene's /materials/1/albedo/image file; an output never replaces an input";
  const std::string before = bytes(path("rock.png"));
  const std::pair<std::string, std::string> cases[] = {
      {"compose --device cpu --size 16 --methods linear --scene " + scene + " --out " + path("rock.png"), "--out " + path("rock.png") + field},
      {"compose --device cpu --size 16 --methods linear --scene " + scene + " --out " + path("sheet.png") + " --panels " + path("panels"),
       "--panels linear " + path("panels/compose-linear.png") + field},
      {"bake --cpu --quiet --method linear --scene " + scene + " --out " + path("rock.png") + " --overwrite", "--out " + path("rock.png") + field},
      {"render --quiet --scene " + scene + " --page-table " + path("rock.png") + " --overwrite --out " + path("r"),
       "--page-table " + path("rock.png") + field},
      // Before any advice to pass --overwrite.
      {"compare --quiet --scene " + scene + " --out " + path("cmp"), "--out " + path("cmp") + "/compare.json" + field},
  };
  for (const auto& [args, message] : cases) {
    EXPECT_EQ(run(args), 2) << args << ": " << output_;
    EXPECT_TRUE(said(message)) << args << ": " << output_;
  }
  EXPECT_EQ(bytes(path("rock.png")), before);
  EXPECT_FALSE(fs::exists(path("sheet.png")));
  EXPECT_FALSE(fs::exists(path("r")));
}

// With --overwrite, render removes an earlier run's frames and stats from its --out folder:
// never an input that lies there under such a name (a frame reused as a texture, a camera
// saved as stats.jsonl), nor one an input links to. Refused before anything is removed.
TEST_F(HostileCli, RenderNeverRemovesAnInputThatLiesInItsOutputFolder) {
  tvt::ImageRGBA8 rock(32, 32);
  for (size_t i = 0; i < rock.texels.size(); ++i) rock.texels[i] = uint8_t(i * 37 % 251);
  fs::create_directories(path("r"));
  ASSERT_TRUE(tvt::write_image(path("r/frame_00003.png"), rock).ok());
  std::ofstream(path("r/frame_00004.png")) << "an earlier frame";
  const std::string scene = tvt::test::write_scene_json(dir_, "frame_scene.json", R"(
      {"name": "ground", "albedo": {"generator": "sand", "resolution": 16}, "weight": "remainder"},
      {"name": "rock", "albedo": {"image": "r/frame_00003.png"}, "weight": {"rule": {"height": [0.5, 1]}}})");
  // A link in the folder that the scene names: removing it would take the scene's texture away.
  fs::create_directories(path("l"));
  fs::create_symlink(path("r/frame_00003.png"), path("l/frame_00001.png"));
  const std::string link_scene = tvt::test::write_scene_json(dir_, "link_scene.json", R"(
      {"name": "ground", "albedo": {"generator": "sand", "resolution": 16}, "weight": "remainder"},
      {"name": "rock", "albedo": {"image": "l/frame_00001.png"}, "weight": {"rule": {"height": [0.5, 1]}}})");
  ASSERT_EQ(run("render --scene " + scene_ + " --save-camera " + path("camera.json")), 0) << output_;
  fs::create_directories(path("c"));
  fs::copy_file(path("camera.json"), path("c/stats.jsonl"));
  fs::create_symlink(path("c/stats.jsonl"), path("camera-link.json"));
  const std::string frame = bytes(path("r/frame_00003.png")), camera = bytes(path("c/stats.jsonl"));
  const std::pair<std::string, std::string> cases[] = {
      {"render --quiet --frames 1 --scene " + scene + " --out " + path("r") + " --overwrite",
       "--out " + path("r") + ": its frame_00003.png (an earlier run's output, which this run removes or replaces) is the "
                              "scene's /materials/1/albedo/image file"},
      {"render --quiet --frames 1 --scene " + scene_ + " --camera " + path("c/stats.jsonl") + " --out " + path("c") + " --overwrite",
       "--out " + path("c") + ": its stats.jsonl (an earlier run's output, which this run removes or replaces) is the --camera file"},
      {"render --quiet --frames 1 --scene " + scene_ + " --camera " + path("camera-link.json") + " --out " + path("c"),
       "--out " + path("c") + ": its stats.jsonl (an earlier run's output, which this run removes or replaces) is the --camera file"},
      {"render --quiet --frames 1 --scene " + link_scene + " --out " + path("l") + " --overwrite",
       "--out " + path("l") + ": its frame_00001.png (an earlier run's output, which this run removes or replaces) is the "
                              "scene's /materials/1/albedo/image file"},
  };
  for (const auto& [args, message] : cases) {
    EXPECT_EQ(run(args), 2) << args << ": " << output_;
    EXPECT_TRUE(said(message + "; an output never replaces an input")) << args << ": " << output_;
  }
  EXPECT_EQ(bytes(path("r/frame_00003.png")), frame);
  EXPECT_EQ(bytes(path("r/frame_00004.png")), "an earlier frame");
  EXPECT_EQ(bytes(path("c/stats.jsonl")), camera);
  EXPECT_FALSE(fs::exists(path("r/stats.jsonl")));
  EXPECT_TRUE(fs::is_symlink(path("l/frame_00001.png")));
  // Nor is the page table written under a name the run writes into --out.
  EXPECT_EQ(run("render --quiet --frames 1 --scene " + scene_ + " --out " + path("p") + " --page-table " + path("p/stats.jsonl")), 2)
      << output_;
  EXPECT_TRUE(said("--page-table " + path("p/stats.jsonl") + ": is a name this run writes into --out " + path("p"))) << output_;
  EXPECT_FALSE(fs::exists(path("p")));
  // A frame in the folder that is only a link to an input is removed, not followed, and a
  // hard link elsewhere to a frame keeps its data: both allowed.
  fs::create_hard_link(path("r/frame_00003.png"), path("hard.png"));
  const std::string hard_scene = tvt::test::write_scene_json(dir_, "hard_scene.json", R"(
      {"name": "ground", "albedo": {"generator": "sand", "resolution": 16}, "weight": "remainder"},
      {"name": "rock", "albedo": {"image": "hard.png"}, "weight": {"rule": {"height": [0.5, 1]}}})");
  EXPECT_EQ(run("render --quiet --frames 1 --width 32 --height 32 --scene " + hard_scene + " --out " + path("r") + " --overwrite"), 0)
      << output_;
  EXPECT_EQ(bytes(path("hard.png")), frame);
  fs::create_symlink(path("camera.json"), path("c/frame_00000.png"));
  fs::remove(path("c/stats.jsonl"));
  EXPECT_EQ(run("render --quiet --frames 1 --width 32 --height 32 --scene " + scene_ + " --camera " + path("camera.json") +
                " --out " + path("c") + " --overwrite"),
            0)
      << output_;
  EXPECT_EQ(bytes(path("camera.json")), camera);
  EXPECT_FALSE(fs::is_symlink(path("c/frame_00000.png")));
}

// compare's flags are checked before its procedural run (minutes), not after it.
TEST_F(HostileCli, CompareChecksEveryFlagAndItsStoreBeforeAnyWork) {
  fs::create_directories(path("folder.tvt"));
  const std::string fifo = make_fifo("store.fifo");
  std::ofstream(path("garbage.tvt")) << "not a page store";
  const std::string out = path("cmp");
  const std::pair<std::string, std::string> cases[] = {
      {" --staging 0", "--staging: must be between 1 and 4096"},
      {" --loader-threads 0", "--loader-threads: must be between 1 and 64"},
      {" --cache-slots 1", "--cache-slots"},
      {" --page-budget 0", "--page-budget"},
      {" --width 0", "--width"},
      {" --level 0", "--level"},
      {" --truth-pages 5000", "--truth-pages"},
      {" --truth-max-mip 0", "--truth-max-mip"},
      {" --store " + path("missing.tvt"), "--store: " + path("missing.tvt") + ": file not found"},
      {" --store " + path("folder.tvt"), "--store: " + path("folder.tvt") + ": is a directory"},
      {" --store " + fifo, "--store: " + fifo + ": is a FIFO"},
      {" --store " + path("garbage.tvt"), "--store: " + path("garbage.tvt")},
  };
  for (const auto& [args, message] : cases) {
    EXPECT_EQ(run("compare --quiet --scene " + scene_ + " --out " + out + args), 2) << args << ": " << output_;
    EXPECT_TRUE(said(message)) << args << ": " << output_;
    EXPECT_FALSE(said("procedural")) << args << ": " << output_;
    EXPECT_FALSE(fs::exists(out)) << args;
  }
}

TEST_F(HostileCli, CompareReplacesAnEarlierRunsFilesOnlyWithOverwrite) {
  const std::string out = path("cmp");
  fs::create_directories(out);
  std::ofstream(out + "/compare.json") << "{\"earlier\": true}";
  EXPECT_EQ(run("compare --quiet --scene " + scene_ + " --out " + out), 2) << output_;
  EXPECT_TRUE(said("--out: " + out + "/compare.json exists; pass --overwrite to replace it (an earlier run's output)"))
      << output_;
  // With --overwrite the folder passes (the bad scene that follows stops the run).
  std::ofstream(path("bad.json")) << "{\"vt\": 1}";
  EXPECT_EQ(run("compare --quiet --overwrite --scene " + path("bad.json") + " --out " + out), 2) << output_;
  EXPECT_TRUE(said("bad.json: /vt:")) << output_;
  EXPECT_EQ(bytes(out + "/compare.json"), "{\"earlier\": true}");
  EXPECT_FALSE(fs::exists(out + ".lock"));
}

TEST_F(HostileCli, ComposeChecksItsOutputBeforeComposing) {
  fs::create_directories(path("folder.png"));
  const std::pair<std::string, std::string> cases[] = {
      {path("missing/sheet.png"), "--out " + path("missing/sheet.png") + ": folder '" + path("missing") + "' does not exist"},
      {path("folder.png"), "--out " + path("folder.png") + ": is a folder"},
      {path("sheet.nope"), "no image writer for extension '.nope'"},
  };
  for (const auto& [out, message] : cases) {
    EXPECT_EQ(run("compose --device cpu --size 16 --scene " + scene_ + " --out " + out), 2) << out << ": " << output_;
    EXPECT_TRUE(said(message)) << out << ": " << output_;
    EXPECT_FALSE(said("pages per method")) << out << ": composed first: " << output_;
  }
}

// ---- files that are not regular files ------------------------------------------------------

TEST_F(HostileCli, NonRegularOutputsAreNeverReplacedEvenWithOverwrite) {
  const std::string fifo = make_fifo("out.fifo"), socket = make_socket("out.sock"), device = make_device_link("null");
  fs::create_directories(path("folder"));
  const std::pair<std::string, std::string> targets[] = {
      {fifo, "is a FIFO"}, {socket, "is a socket"}, {device, "is a character device"}, {path("folder"), "is a directory"}};
  for (const auto& [target, kind] : targets) {
    const std::string runs[] = {
        bake_args(target) + " --overwrite",
        "bake --cpu --quiet --method linear --scene " + scene_ + " --dict auto --dict-samples 4 --out " +
            path("d.tvt") + " --overwrite --save-dict " + target,
        "merge " + path("nothing.tvt") + " --out " + target + " --overwrite",
        "render --quiet --scene " + scene_ + " --overwrite --save-camera " + target,
    };
    for (const std::string& args : runs) {
      if (args.starts_with("merge")) std::ofstream(path("nothing.tvt")) << "x";
      EXPECT_EQ(run(args), 2) << args << ": " << output_;
      EXPECT_TRUE(said(target + " " + kind + "; terravt writes only regular files and never replaces anything else"))
          << args << ": " << output_;
      EXPECT_FALSE(said("pass --overwrite")) << args << ": " << output_;
    }
    for (const std::string& args : {"compose --device cpu --size 16 --scene " + scene_ + " --out " + target,
                                    "metatex --generator cobbles --resolution 64 --out " + target}) {
      EXPECT_EQ(run(args), 2) << args << ": " << output_;
      EXPECT_TRUE(said(target)) << args << ": " << output_;
    }
  }
  EXPECT_TRUE(is_fifo(fifo));
  EXPECT_TRUE(fs::is_socket(fs::symlink_status(socket)));
  EXPECT_TRUE(fs::is_symlink(fs::symlink_status(device)));
  EXPECT_TRUE(fs::is_character_file(fs::status("/dev/null")));
  EXPECT_FALSE(fs::exists(path("d.tvt")));
}

TEST_F(HostileCli, VerifyInfoAndReadersRefuseAFifoWithoutBlocking) {
  const std::string fifo = make_fifo("store.fifo");
  fs::create_directories(path("folder.tvt"));
  for (const std::string& store : {fifo, path("folder.tvt")}) {
    EXPECT_EQ(run("verify " + store), 1) << output_;
    EXPECT_TRUE(said(store + ": not a regular file")) << output_;
    EXPECT_EQ(run("info " + store), 1) << output_;
    EXPECT_TRUE(said(store + ": not a regular file")) << output_;
    EXPECT_EQ(run("render --quiet --source stored --store " + store + " --out " + path("r")), 2) << output_;
    EXPECT_TRUE(said("--store: " + store + ": not a regular file")) << output_;
  }
  EXPECT_EQ(run("render --quiet --camera " + fifo + " --out " + path("r")), 2) << output_;
  EXPECT_TRUE(said(fifo + ": cannot read camera file: it is not a regular file (a FIFO)")) << output_;
  EXPECT_EQ(run("metatex --input " + fifo + " --out " + path("m.exr")), 2) << output_;
  EXPECT_TRUE(said(fifo + ": is not a regular file, not an image file")) << output_;
  EXPECT_EQ(run("merge " + fifo + " --out " + path("m.tvt")), 2) << output_;
  EXPECT_TRUE(said(fifo + ": is a FIFO, not a regular file")) << output_;
  EXPECT_FALSE(fs::exists(path("r")));
  EXPECT_TRUE(is_fifo(fifo));
}

// ---- JSON nesting --------------------------------------------------------------------------

TEST_F(HostileCli, TwoHundredKilobytesOfNestedBracketsAreRefusedNamingTheFileAndTheLimit) {
  const std::string deep = std::string(100000, '[') + std::string(100000, ']');
  std::ofstream(path("d.json")) << deep;
  EXPECT_EQ(run("render --quiet --scene " + path("d.json") + " --out " + path("r")), 2) << output_;
  EXPECT_TRUE(said(path("d.json") + ": /0/0/")) << output_;
  EXPECT_TRUE(said("nested deeper than 64 arrays/objects")) << output_;
  EXPECT_EQ(run("render --quiet --camera " + path("d.json") + " --out " + path("r")), 2) << output_;
  EXPECT_TRUE(said("--camera: " + path("d.json") + ": /0/0/")) << output_;
  EXPECT_TRUE(said("nested deeper than 64 arrays/objects")) << output_;
  EXPECT_FALSE(fs::exists(path("r")));
}
