// A fixed pool of physical cache slots 0 .. N-1 (docs/virtual-texture.md).
//
// Contract:
// - allocate() and free() are O(1): a LIFO stack of free slots plus one state byte per slot.
// - Freeing a slot that is not allocated (double free, or a slot never handed out) or a slot
//   >= N is a programming error and stops the program with a fatal check: a slot
//   handed to two pages would make two pages share texels, which no test could later trace.
// - Running out of slots is not an error: allocate() returns std::nullopt and the caller
//   (the residency policy) decides what to evict.
// - Slots come back in LIFO order, so a freshly freed slot is reused first (its texels are
//   the most likely to still be in a GPU cache; nothing relies on the order).
// Not thread-safe: one owner (the residency policy) calls it from one thread.
#pragma once
#include <cstdint>
#include <optional>
#include <vector>

namespace tvt {

class SlotAllocator {
 public:
  // `slot_count` = N, the number of slots of the physical cache; N >= 1.
  explicit SlotAllocator(uint32_t slot_count);

  // A free slot, or std::nullopt when all N slots are allocated.
  std::optional<uint32_t> allocate();

  // Returns `slot` to the pool. Fatal if `slot` >= N or is not currently allocated.
  void free(uint32_t slot);

  bool is_allocated(uint32_t slot) const;  // false for slot >= N

  uint32_t capacity() const { return uint32_t(allocated_.size()); }
  uint32_t allocated_count() const { return capacity() - free_count(); }
  uint32_t free_count() const { return uint32_t(free_.size()); }

 private:
  std::vector<uint32_t> free_;      // stack of free slots; top = back()
  std::vector<uint8_t> allocated_;  // 1 if slot i is handed out
};

}  // namespace tvt
