#include "vt/slot_allocator.h"

#include "vt/result.h"

namespace tvt {

SlotAllocator::SlotAllocator(uint32_t slot_count) : allocated_(slot_count, 0) {
  TVT_CHECK(slot_count >= 1);
  free_.reserve(slot_count);
  // Push in reverse so that the first allocations return 0, 1, 2, ... (readable dumps).
  for (uint32_t i = slot_count; i-- > 0;) free_.push_back(i);
}

std::optional<uint32_t> SlotAllocator::allocate() {
  if (free_.empty()) return std::nullopt;
  const uint32_t slot = free_.back();
  free_.pop_back();
  TVT_CHECK(allocated_[slot] == 0);
  allocated_[slot] = 1;
  return slot;
}

void SlotAllocator::free(uint32_t slot) {
  TVT_CHECK(slot < allocated_.size());
  TVT_CHECK(allocated_[slot] == 1);  // double free or a slot never allocated
  allocated_[slot] = 0;
  free_.push_back(slot);
}

bool SlotAllocator::is_allocated(uint32_t slot) const {
  return slot < allocated_.size() && allocated_[slot] == 1;
}

}  // namespace tvt
