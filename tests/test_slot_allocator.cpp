// SlotAllocator: O(1) pool of N slots; every slot handed out once until freed, and a double
// free is a fatal check (the program stops, naming the expression).
#include <gtest/gtest.h>

#include <random>
#include <set>

#include "vt/slot_allocator.h"

using namespace tvt;

TEST(SlotAllocator, HandsOutEverySlotOnceThenRunsOut) {
  SlotAllocator a(5);
  std::set<uint32_t> got;
  for (int i = 0; i < 5; ++i) {
    const auto s = a.allocate();
    ASSERT_TRUE(s.has_value());
    EXPECT_LT(*s, 5u);
    EXPECT_TRUE(got.insert(*s).second);
    EXPECT_TRUE(a.is_allocated(*s));
  }
  EXPECT_FALSE(a.allocate().has_value());
  EXPECT_EQ(a.allocated_count(), 5u);
  EXPECT_EQ(a.free_count(), 0u);
  a.free(3);
  EXPECT_FALSE(a.is_allocated(3));
  EXPECT_EQ(a.allocate(), std::optional<uint32_t>(3));  // LIFO reuse
  EXPECT_FALSE(a.is_allocated(5));                      // out of range is simply not allocated
}

TEST(SlotAllocator, RandomStreamsNeverHandOutAnAllocatedSlot) {
  std::mt19937 rng(12345);
  for (uint32_t n : {1u, 7u, 64u, 1000u}) {
    SlotAllocator a(n);
    std::set<uint32_t> held;
    for (int op = 0; op < 20000; ++op) {
      if (rng() % 2 == 0) {
        const auto s = a.allocate();
        ASSERT_EQ(s.has_value(), held.size() < n);
        if (s) {
          ASSERT_TRUE(held.insert(*s).second) << "slot " << *s << " handed out twice";
        }
      } else if (!held.empty()) {
        auto it = held.begin();
        std::advance(it, rng() % held.size());
        a.free(*it);
        held.erase(it);
      }
      ASSERT_EQ(a.allocated_count(), held.size());
      ASSERT_EQ(a.free_count() + a.allocated_count(), n);
    }
  }
}

TEST(SlotAllocatorDeathTest, DoubleFreeAndForeignSlotAreFatal) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_DEATH(
      {
        SlotAllocator a(4);
        const auto s = a.allocate();
        a.free(*s);
        a.free(*s);
      },
      "allocated_\\[slot\\] == 1");
  EXPECT_DEATH(
      {
        SlotAllocator a(4);
        a.free(2);  // never allocated
      },
      "fatal");
  EXPECT_DEATH(
      {
        SlotAllocator a(4);
        a.free(4);  // out of range
      },
      "slot < allocated_.size\\(\\)");
}
