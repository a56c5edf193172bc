// Errors are values (no Vulkan header needed: plain C++, also used by terravt's CPU-only code): every terravt call that can fail returns Result<T> (or Status), never
// aborts, never throws across the API and never writes to stderr. An Error carries a kind a
// program can branch on, the VkResult where Vulkan failed, and a complete message that names
// what was wrong (the file and field, the missing feature, the Vulkan call).
#pragma once
#include <cstdint>
#include <string>
#include <utility>
#include <variant>

#include "terravt/export.h"

namespace terravt {

enum class ErrorKind {
  invalid_argument,    // a value the caller passed is out of range or inconsistent
  unsupported_device,  // the device lacks a version, feature or queue terravt needs
  vulkan,              // a Vulkan call failed (see Error::vk_result)
  device_lost,         // VK_ERROR_DEVICE_LOST: nothing more can be recorded on this device
  out_of_memory,       // host or device memory ran out
  io,                  // a file could not be read or written
  producer_failed,     // a page producer could not produce a page
  misuse,              // calls out of order (e.g. a completed frame going backwards)
};

TERRAVT_API const char* to_string(ErrorKind kind) noexcept;

struct Error {
  ErrorKind kind = ErrorKind::invalid_argument;
  std::string message;             // complete and human readable
  int32_t vk_result = 0;            // the failing call's VkResult (vulkan, device_lost, out_of_memory); 0 otherwise
};

// A value or an Error. Checked access: value() on an error (or error() on a value) is a
// programming mistake that std::get reports by throwing std::bad_variant_access.
template <class T>
class [[nodiscard]] Result {
 public:
  Result(T value) : v_(std::move(value)) {}      // NOLINT: implicit by design
  Result(Error error) : v_(std::move(error)) {}  // NOLINT
  bool ok() const noexcept { return v_.index() == 0; }
  explicit operator bool() const noexcept { return ok(); }
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

}  // namespace terravt
