// A value made on first request and shared by every later one, from any number of threads;
// concurrent first requests make it once. A failure is remembered like a value (no retry).
#pragma once
#include <atomic>
#include <mutex>
#include <optional>
#include <utility>

#include "vt/result.h"

namespace tvt {

template <class T>
class OnceResult {
 public:
  // make() -> Result<T>, run by the first caller only; the others wait for it.
  template <class Make>
  const OnceResult& get(Make&& make) {
    if (!done_.load(std::memory_order_acquire)) {
      std::lock_guard lock(mutex_);
      if (!done_.load(std::memory_order_relaxed)) {
        auto r = std::forward<Make>(make)();
        if (r) value_ = std::move(r.value());
        else error_ = r.error();
        done_.store(true, std::memory_order_release);
      }
    }
    return *this;
  }
  bool done() const { return done_.load(std::memory_order_acquire); }
  bool ok() const { return done() && !error_; }
  const std::optional<Error>& error() const { return error_; }  // after get() / done()
  const T& value() const { return value_; }                      // after get() / ok()

 private:
  std::mutex mutex_;
  std::atomic<bool> done_{false};
  T value_{};
  std::optional<Error> error_;
};

}  // namespace tvt
