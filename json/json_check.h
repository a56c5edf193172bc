// Checked reading of the project's JSON input files (scene files, camera paths): a parser
// that knows the JSON pointer of every value, and field readers whose errors name the file and
// the field the same way everywhere:
//   "<source>: <json pointer>: <what is wrong>, got <value>"
// A reader's failed check throws json_check::Failure; run() turns it into a Result, so nothing
// escapes a parse function.
#pragma once
#include <cstdint>
#include <initializer_list>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <utility>

#include "vt/result.h"

namespace tvt::json_check {

using json = nlohmann::json;
using Ptr = json::json_pointer;

constexpr double k_inf = std::numeric_limits<double>::infinity();

struct Failure {
  std::string message;  // complete, with the source prefix
};

std::string show_number(double v);
std::string show_value(const json& v);  // compact, cut at 80 characters
std::string show_pointer(const Ptr& p);  // "<root>" for the root

// Arrays/objects nested deeper than this are refused: the project's files need fewer than 10
// levels, and a bound keeps hostile input from costing stack or time (docs/scene-format.md).
constexpr size_t k_max_depth = 64;

// The whole text as a DOM, in time linear in its length. Errors: "<source>: [<pointer>: ]invalid JSON: ... (line l, column c)";
// overflowing numbers (1e999), duplicate keys and nesting deeper than k_max_depth are reported
// at their field.
Result<json> parse(std::string_view text, const std::string& source);

// A whole file's text, at most k_max_text_bytes. Errors: "<path>: cannot read <what> file: file
// not found" (or "it is a directory", "it is not a regular file (a FIFO)", "cannot open it",
// "read error"). Never blocks on a FIFO or reads a device.
constexpr size_t k_max_text_bytes = size_t(64) << 20;
Result<std::string> read_text_file(const std::string& path, const std::string& what);

// "a directory", "a FIFO", "a character device", "a block device", "a socket" for a st_mode.
std::string file_kind(unsigned mode);

// The member `key` of an object, or nullptr.
const json* field(const json& object, const char* key);

// Bounds of a real-valued field. `interval` fields are reported as a whole range
// ("in (0, 0.5]"); the others name only the violated side (so a sanity cap such as 1e6 does
// not clutter the usual "> 0" message).
struct Bound {
  double lo = -k_inf;
  bool lo_open = false;
  double hi = k_inf;
  bool hi_open = false;
  bool interval = false;
};
inline Bound closed(double lo, double hi) { return {lo, false, hi, false, true}; }
inline Bound open_closed(double lo, double hi) { return {lo, true, hi, false, true}; }
inline Bound open(double lo, double hi) { return {lo, true, hi, true, true}; }
inline Bound above(double lo, double cap = k_inf) { return {lo, true, cap, false, false}; }
inline Bound at_least(double lo, double cap = k_inf) { return {lo, false, cap, false, false}; }
inline Bound any_finite() { return {}; }

// Field readers for one source file; every failure throws Failure naming source and pointer.
class Reader {
 public:
  // base_dir: where relative file paths are taken from (empty: the working directory).
  explicit Reader(std::string source, std::string base_dir = {})
      : source_(std::move(source)), base_dir_(std::move(base_dir)) {}

  const std::string& source() const { return source_; }

  [[noreturn]] void fail(const Ptr& at, const std::string& what, const std::string& got) const;
  [[noreturn]] void fail(const Ptr& at, const std::string& what, const json& got) const;
  // "<source>: <pointer>: <what>" without a "got" part.
  [[noreturn]] void fail(const Ptr& at, const std::string& what) const;

  const json& require(const json& object, const Ptr& at, const char* key) const;
  // `v` must be an object whose keys are all in `allowed`.
  void object(const json& v, const Ptr& at, std::initializer_list<std::string_view> allowed) const;
  double real(const json& v, const Ptr& at, const Bound& b) const;
  // A JSON integer (or an integral float such as 512.0) in [lo, hi].
  uint32_t uint(const json& v, const Ptr& at, uint32_t lo, uint32_t hi, bool power_of_two = false) const;
  bool boolean(const json& v, const Ptr& at) const;
  std::string text(const json& v, const Ptr& at) const;
  // A path to an existing file; relative paths are taken from base_dir.
  std::string file(const json& v, const Ptr& at) const;
  // [lo, hi] with lo <= hi, each within `b`.
  std::pair<double, double> window(const json& v, const Ptr& at, const Bound& b) const;
  // An array of exactly `n` numbers, each within `b` (n <= 4).
  void reals(const json& v, const Ptr& at, size_t n, const Bound& b, double* out) const;

 protected:
  std::string source_;
  std::string base_dir_;
};

// Runs a reading function, turning a Failure into an Error.
template <class T, class F>
Result<T> run(F&& read) {
  try {
    return read();
  } catch (const Failure& f) {
    return make_error(f.message);
  }
}

}  // namespace tvt::json_check
