// Two levels of errors: Result<T> for everything a user, a file, the device or the driver can
// cause (bad scene, missing file, corrupt page, API misuse, out of memory, device lost; Vulkan
// failures are latched by gpu/context.h), and TVT_CHECK only for terravt's own invariants,
// which no input and no call sequence reaches (a failed one is a terravt bug, not an error).
// Error text names the file and the field.
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
