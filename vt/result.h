// Two levels of errors: TVT_CHECK for what must not fail, Result<T> for what a
// user can cause (bad scene, missing file, corrupt page). Error text names file and field.
#pragma once
#include <cstdio>
#include <cstdlib>
#include <string>
#include <utility>

#include "terravt/error.h"

namespace tvt {

// One error type inside and outside the library: the public terravt::Error (a kind, the
// VkResult where Vulkan failed, a complete message) and terravt::Result<T>.
using Error = terravt::Error;
using ErrorKind = terravt::ErrorKind;
template <class T>
using Result = terravt::Result<T>;
using Ok = terravt::Ok;
using Status = terravt::Status;

inline Error make_error(std::string message, ErrorKind kind = ErrorKind::invalid_argument) {
  return Error{kind, std::move(message)};
}

[[noreturn]] inline void fatal(const char* file, int line, const char* expr, const char* what) {
  std::fprintf(stderr, "terravt: fatal: %s:%d: %s%s%s\n", file, line, expr, what ? ": " : "", what ? what : "");
  std::abort();
}

}  // namespace tvt

#define TVT_CHECK(expr)                                                   \
  do {                                                                    \
    if (!(expr)) ::tvt::fatal(__FILE__, __LINE__, #expr, nullptr);        \
  } while (0)
