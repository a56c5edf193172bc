// Vulkan allocation callbacks for tests: they count every host allocation made through them and
// what is still outstanding, and can refuse one chosen allocation (return NULL, so the Vulkan
// call that asked for it fails with VK_ERROR_OUT_OF_HOST_MEMORY). Thread-safe.
#pragma once
#include <vulkan/vulkan.h>

#include <algorithm>
#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <unordered_map>

namespace tvt {

struct CountingAllocator {
  std::mutex mutex;
  std::unordered_map<void*, size_t> live;  // outstanding blocks and their sizes
  size_t allocations = 0;                  // allocations asked for (refused ones included)
  size_t refuse_at = 0;                    // 1-based number of the allocation to refuse; 0: none
  size_t refused = 0;                      // allocations refused

  static void* allocate(void* user, size_t size, size_t alignment, VkSystemAllocationScope) {
    auto* self = static_cast<CountingAllocator*>(user);
    {
      std::lock_guard lock(self->mutex);
      ++self->allocations;
      if (self->allocations == self->refuse_at) {
        ++self->refused;
        return nullptr;
      }
    }
    alignment = std::max<size_t>(alignment, alignof(std::max_align_t));
    void* p = std::aligned_alloc(alignment, std::max<size_t>((size + alignment - 1) / alignment * alignment, alignment));
    std::lock_guard lock(self->mutex);
    self->live[p] = size;
    return p;
  }
  static void* reallocate(void* user, void* old, size_t size, size_t alignment, VkSystemAllocationScope scope) {
    auto* self = static_cast<CountingAllocator*>(user);
    if (!old) return allocate(user, size, alignment, scope);
    if (size == 0) {
      release(user, old);
      return nullptr;
    }
    void* p = allocate(user, size, alignment, scope);
    if (!p) return nullptr;  // refused: the old block stays the caller's
    size_t old_size = 0;
    {
      std::lock_guard lock(self->mutex);
      old_size = self->live.at(old);
    }
    std::memcpy(p, old, std::min(old_size, size));
    release(user, old);
    return p;
  }
  static void release(void* user, void* p) {
    if (!p) return;
    auto* self = static_cast<CountingAllocator*>(user);
    {
      std::lock_guard lock(self->mutex);
      self->live.erase(p);
    }
    std::free(p);
  }
  VkAllocationCallbacks callbacks() {
    VkAllocationCallbacks cb{};
    cb.pUserData = this;
    cb.pfnAllocation = allocate;
    cb.pfnReallocation = reallocate;
    cb.pfnFree = release;
    return cb;
  }
  size_t outstanding() {
    std::lock_guard lock(mutex);
    return live.size();
  }
  // Counts afresh, refusing allocation number `at` (0: none).
  void restart(size_t at) {
    std::lock_guard lock(mutex);
    allocations = 0;
    refused = 0;
    refuse_at = at;
  }
};

}  // namespace tvt
