// Checked reading of JSON input files (json_check.h).
#include "json/json_check.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <vector>

namespace tvt::json_check {

namespace fs = std::filesystem;

namespace {

std::string strip_nlohmann_prefix(std::string what) {
  // "[json.exception.parse_error.101] parse error at ..." -> "parse error at ..."
  if (!what.empty() && what.front() == '[') {
    const size_t close = what.find("] ");
    if (close != std::string::npos) what.erase(0, close + 2);
  }
  return what;
}


// Builds the DOM like nlohmann's own SAX DOM parser, but knows the JSON pointer of the value
// being read, so overflowing numbers (1e999) and duplicate keys are reported by field.
class DomBuilder final : public nlohmann::json_sax<json> {
 public:
  explicit DomBuilder(std::string_view text) : text_(text) {}

  json root;
  std::string error;  // complete message minus the source prefix; empty on success

  bool null() override { return scalar(json(nullptr)); }
  bool boolean(bool v) override { return scalar(json(v)); }
  bool number_integer(number_integer_t v) override { return scalar(json(v)); }
  bool number_unsigned(number_unsigned_t v) override { return scalar(json(v)); }
  bool number_float(number_float_t v, const string_t&) override { return scalar(json(v)); }
  bool string(string_t& v) override { return scalar(json(std::move(v))); }
  bool binary(binary_t& v) override { return scalar(json::binary(std::move(v))); }
  bool start_object(std::size_t) override { return open(json::object()); }
  bool start_array(std::size_t) override { return open(json::array()); }
  bool end_object() override { return close(); }
  bool end_array() override { return close(); }

  bool key(string_t& k) override {
    if (stack_.back()->contains(k)) {
      error = show_pointer(path_ / k) + ": duplicate field \"" + k + "\"";
      return false;
    }
    key_ = std::move(k);
    have_key_ = true;
    return true;
  }

  bool parse_error(std::size_t position, const std::string& token, const nlohmann::detail::exception& ex) override {
    if (ex.id == 406) {  // number overflow, e.g. 1e999: report it at its field
      error = show_pointer(current()) + ": number is out of range (" + line_column(position) + "), got " + token;
    } else {
      const Ptr at = current();
      error =
          (at.empty() ? std::string() : show_pointer(at) + ": ") + "invalid JSON: " + strip_nlohmann_prefix(ex.what());
    }
    return false;
  }

 private:
  // Pointer of the value about to be read (or of the innermost open container). O(depth):
  // for error messages only.
  Ptr current() const {
    if (stack_.empty()) return path_;
    if (stack_.back()->is_array()) return path_ / stack_.back()->size();
    return have_key_ ? path_ / key_ : path_;
  }

  std::string line_column(size_t position) const {
    size_t line = 1, column = 0;
    for (size_t i = 0; i < position && i < text_.size(); ++i) {
      if (text_[i] == '\n') {
        ++line;
        column = 0;
      } else {
        ++column;
      }
    }
    return "line " + std::to_string(line) + ", column " + std::to_string(column);
  }

  json* put(json v) {
    if (stack_.empty()) {
      root = std::move(v);
      return &root;
    }
    json& top = *stack_.back();
    if (top.is_array()) {
      top.push_back(std::move(v));
      return &top.back();
    }
    have_key_ = false;
    json& slot = top[key_];
    slot = std::move(v);
    return &slot;
  }
  bool scalar(json v) {
    put(std::move(v));
    return true;
  }

  bool open(json container) {
    if (stack_.size() >= k_max_depth) {
      error = show_pointer(current()) + ": nested deeper than " + std::to_string(k_max_depth) +
              " arrays/objects (the limit for input files)";
      return false;
    }
    // The new container's own pointer token; path_ grows and shrinks by one token per level,
    // so each value costs O(1), not O(depth) (copying whole pointers made deep input quadratic).
    std::string token;
    if (!stack_.empty()) token = stack_.back()->is_array() ? std::to_string(stack_.back()->size()) : key_;
    // A child container is only ever referenced while open; its parent gets no new element
    // until it is closed, so the pointer stays valid even inside a vector.
    json* slot = put(std::move(container));
    if (!stack_.empty()) path_.push_back(std::move(token));
    stack_.push_back(slot);
    have_key_ = false;
    return true;
  }

  bool close() {
    stack_.pop_back();
    if (!path_.empty()) path_.pop_back();
    have_key_ = false;
    return true;
  }

  std::string_view text_;
  std::vector<json*> stack_;
  Ptr path_;  // pointer of stack_.back()
  std::string key_;
  bool have_key_ = false;
};

}  // namespace

std::string show_number(double v) {
  std::array<char, 40> buf{};
  const auto r = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return std::string(buf.data(), r.ptr);
}

std::string show_value(const json& v) {
  std::string s = v.dump(-1, ' ', false, json::error_handler_t::replace);
  if (s.size() > 80) s = s.substr(0, 77) + "...";
  return s;
}

std::string show_pointer(const Ptr& p) {
  const std::string s = p.to_string();
  return s.empty() ? "<root>" : s;
}

Result<json> parse(std::string_view text, const std::string& source) {
  DomBuilder dom(text);
  bool parsed = false;
  try {
    parsed = json::sax_parse(text, &dom);
  } catch (const json::exception& e) {  // e.g. invalid UTF-8 handling; report, never crash
    return make_error(source + ": invalid JSON: " + strip_nlohmann_prefix(e.what()));
  }
  if (!parsed) return make_error(source + ": " + (dom.error.empty() ? std::string("invalid JSON") : dom.error));
  return std::move(dom.root);
}

Result<std::string> read_text_file(const std::string& path, const std::string& what) {
  const std::string cannot = path + ": cannot read " + what + " file: ";
  // O_NONBLOCK: opening a FIFO must not wait for a writer; fstat then refuses anything but a
  // regular file before a byte is read (a FIFO, device or socket could block or never end).
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    if (err == ENOENT || err == ENOTDIR) return make_error(cannot + "file not found");
    if (err == EISDIR) return make_error(cannot + "it is a directory");
    return make_error(cannot + "cannot open it (" + std::strerror(err) + ")");
  }
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0) return make_error(cannot + "cannot open it (" + std::strerror(errno) + ")");
  if (S_ISDIR(st.st_mode)) return make_error(cannot + "it is a directory");
  if (!S_ISREG(st.st_mode)) return make_error(cannot + "it is not a regular file (" + file_kind(st.st_mode) + ")");
  if (st.st_size > off_t(k_max_text_bytes))
    return make_error(cannot + "it is " + std::to_string(st.st_size) + " bytes, more than the limit of " +
                      std::to_string(k_max_text_bytes));
  std::string text;
  char buf[65536];
  for (;;) {
    const ssize_t n = ::read(fd, buf, sizeof(buf));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return make_error(cannot + "read error (" + std::strerror(errno) + ")");
    if (n == 0) break;
    text.append(buf, size_t(n));
    if (text.size() > k_max_text_bytes)
      return make_error(cannot + "it grew past the limit of " + std::to_string(k_max_text_bytes) + " bytes");
  }
  return text;
}

std::string file_kind(unsigned mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  if (S_ISREG(mode)) return "a regular file";
  return "not a regular file";
}

const json* field(const json& object, const char* key) {
  const auto it = object.find(key);
  return it == object.end() ? nullptr : &*it;
}

void Reader::fail(const Ptr& at, const std::string& what, const std::string& got) const {
  throw Failure{source_ + ": " + show_pointer(at) + ": " + what + ", got " + got};
}
void Reader::fail(const Ptr& at, const std::string& what, const json& got) const {
  fail(at, what, show_value(got));
}

const json& Reader::require(const json& object, const Ptr& at, const char* key) const {
  const json* f = field(object, key);
  if (!f) throw Failure{source_ + ": " + show_pointer(at / key) + ": required field is missing"};
  return *f;
}

void Reader::object(const json& v, const Ptr& at, std::initializer_list<std::string_view> allowed) const {
  std::string names;
  for (std::string_view a : allowed) names += (names.empty() ? "" : ", ") + std::string(a);
  if (!v.is_object()) fail(at, "must be an object with fields " + names, v);
  for (const auto& [key, value] : v.items()) {
    bool known = false;
    for (std::string_view a : allowed) known = known || key == a;
    if (!known) fail(at / key, "unknown field \"" + key + "\" (allowed here: " + names + ")", value);
  }
}

double Reader::real(const json& v, const Ptr& at, const Bound& b) const {
  const auto side = [&](bool low) {
    if (low) return std::string(b.lo_open ? "> " : ">= ") + show_number(b.lo);
    return std::string(b.hi_open ? "< " : "<= ") + show_number(b.hi);
  };
  const auto describe = [&](bool low) {
    std::string d = "must be a finite number";
    if (b.interval)
      return d + " in " + (b.lo_open ? "(" : "[") + show_number(b.lo) + ", " + show_number(b.hi) +
             (b.hi_open ? ")" : "]");
    if (b.lo > -k_inf && (low || b.hi == k_inf)) return d + " " + side(true);
    if (b.hi < k_inf) return d + " " + side(false);
    return d;
  };
  if (!v.is_number()) fail(at, describe(true), v);
  const double d = v.get<double>();
  if (!std::isfinite(d)) fail(at, describe(true), v);
  if (d < b.lo || (b.lo_open && d == b.lo)) fail(at, describe(true), v);
  if (d > b.hi || (b.hi_open && d == b.hi)) fail(at, describe(false), v);
  return d;
}

uint32_t Reader::uint(const json& v, const Ptr& at, uint32_t lo, uint32_t hi, bool power_of_two) const {
  const std::string what = std::string(power_of_two ? "must be a power of two in [" : "must be an integer in [") +
                           std::to_string(lo) + ", " + std::to_string(hi) + "]";
  uint64_t u = 0;
  if (v.is_number_unsigned()) {
    u = v.get<uint64_t>();
  } else if (v.is_number_float()) {
    const double d = v.get<double>();
    if (!std::isfinite(d) || d != std::floor(d) || d < 0.0 || d > double(hi)) fail(at, what, v);
    u = uint64_t(d);
  } else {
    fail(at, what, v);  // negative integers, strings, ...
  }
  if (u < lo || u > hi) fail(at, what, v);
  if (power_of_two && (u & (u - 1)) != 0) fail(at, what, v);
  return uint32_t(u);
}

std::string Reader::text(const json& v, const Ptr& at) const {
  if (!v.is_string() || v.get_ref<const std::string&>().empty()) fail(at, "must be a non-empty string", v);
  return v.get<std::string>();
}

std::string Reader::file(const json& v, const Ptr& at) const {
  if (!v.is_string() || v.get_ref<const std::string&>().empty()) fail(at, "must be a non-empty file path", v);
  fs::path p(v.get<std::string>());
  if (p.is_relative() && !base_dir_.empty()) p = fs::path(base_dir_) / p;
  p = p.lexically_normal();
  struct stat st {};
  if (::stat(p.c_str(), &st) != 0) fail(at, "file not found: " + p.string(), v);
  if (!S_ISREG(st.st_mode)) fail(at, "not a regular file: " + p.string() + " is " + file_kind(st.st_mode), v);
  return p.string();
}

std::pair<double, double> Reader::window(const json& v, const Ptr& at, const Bound& b) const {
  if (!v.is_array() || v.size() != 2) fail(at, "must be an array [lo, hi] of two numbers", v);
  const double lo = real(v[0], at / 0, b);
  const double hi = real(v[1], at / 1, b);
  if (lo > hi) fail(at, "lower bound must not exceed upper bound", v);
  return {lo, hi};
}

void Reader::fail(const Ptr& at, const std::string& what) const {
  throw Failure{source_ + ": " + show_pointer(at) + ": " + what};
}

bool Reader::boolean(const json& v, const Ptr& at) const {
  if (!v.is_boolean()) fail(at, "must be true or false", v);
  return v.get<bool>();
}

void Reader::reals(const json& v, const Ptr& at, size_t n, const Bound& b, double* out) const {
  if (!v.is_array() || v.size() != n) fail(at, "must be an array of " + std::to_string(n) + " numbers", v);
  for (size_t i = 0; i < n; ++i) out[i] = real(v[i], at / i, b);
}

}  // namespace tvt::json_check
