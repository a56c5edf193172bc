// Two levels of errors: TVT_CHECK for what must not fail, Result<T> for what a
// user can cause (bad scene, missing file, corrupt page). Error text names file and field.
#pragma once
#include <cstdio>
#include <cstdlib>
#include <string>
#include <utility>
#include <variant>

namespace tvt {

struct Error {
  std::string message;  // complete, human readable: "scene.json: /materials/2/mode: ..."
};

template <class T>
class [[nodiscard]] Result {
 public:
  Result(T value) : v_(std::move(value)) {}  // NOLINT: implicit by design
  Result(Error error) : v_(std::move(error)) {}  // NOLINT
  bool ok() const { return v_.index() == 0; }
  explicit operator bool() const { return ok(); }
  T& value() & { return std::get<0>(v_); }
  const T& value() const& { return std::get<0>(v_); }
  T&& value() && { return std::get<0>(std::move(v_)); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }
  const Error& error() const { return std::get<1>(v_); }

 private:
  std::variant<T, Error> v_;
};

struct Ok {};
using Status = Result<Ok>;

inline Error make_error(std::string message) { return Error{std::move(message)}; }

[[noreturn]] inline void fatal(const char* file, int line, const char* expr, const char* what) {
  std::fprintf(stderr, "terravt: fatal: %s:%d: %s%s%s\n", file, line, expr, what ? ": " : "", what ? what : "");
  std::abort();
}

}  // namespace tvt

#define TVT_CHECK(expr)                                                   \
  do {                                                                    \
    if (!(expr)) ::tvt::fatal(__FILE__, __LINE__, #expr, nullptr);        \
  } while (0)
