// city/RangeAllocator.h: first fit, merging freed neighbours, growth.
#include "RangeAllocator.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

using seasonview::city::RangeAllocator;

TEST(RangeAllocatorTest, FirstFitMergesAndGrows) {
    RangeAllocator a(100);
    EXPECT_EQ(a.allocate(30), 0u);
    EXPECT_EQ(a.allocate(30), 30u);
    EXPECT_EQ(a.allocate(30), 60u);
    EXPECT_FALSE(a.allocate(11)) << "10 units left";
    EXPECT_FALSE(a.allocate(0));
    a.release(0, 30);
    a.release(60, 30);
    EXPECT_EQ(a.freeRanges(), 2u); // [0, 30) and [60, 100)
    EXPECT_EQ(a.largestFree(), 40u);
    EXPECT_EQ(a.allocate(35), 60u) << "the first range that holds it";
    EXPECT_EQ(a.allocate(20), 0u);
    a.release(30, 30); // merges with [20, 30)
    EXPECT_EQ(a.largestFree(), 40u);
    EXPECT_EQ(a.allocate(40), 20u);
    EXPECT_FALSE(a.allocate(6));
    a.grow(200); // [95, 100) and the new [100, 200) merge
    EXPECT_EQ(a.largestFree(), 105u);
    EXPECT_EQ(a.allocate(105), 95u);
    EXPECT_EQ(a.used(), 200u);
}

// Random allocations and releases never hand out overlapping ranges, and everything freed merges back into one.
TEST(RangeAllocatorTest, RandomUseNeverOverlapsAndMergesBack) {
    RangeAllocator a(1000);
    std::mt19937 rng(5);
    std::vector<std::pair<std::size_t, std::size_t>> live;
    std::vector<int> owner(4000, -1);
    for (int step = 0; step < 5000; ++step) {
        if (live.empty() || rng() % 3 != 0) {
            const std::size_t size = 1 + rng() % 50;
            auto off = a.allocate(size);
            if (!off) {
                a.grow(a.capacity() + 100);
                owner.resize(std::max(owner.size(), a.capacity()), -1);
                continue;
            }
            ASSERT_LE(*off + size, a.capacity());
            for (std::size_t i = *off; i < *off + size; ++i) {
                ASSERT_EQ(owner[i], -1) << "unit " << i << " handed out twice";
                owner[i] = step;
            }
            live.emplace_back(*off, size);
        } else {
            const std::size_t k = rng() % live.size();
            for (std::size_t i = live[k].first; i < live[k].first + live[k].second; ++i) owner[i] = -1;
            a.release(live[k].first, live[k].second);
            live.erase(live.begin() + std::ptrdiff_t(k));
        }
    }
    for (const auto& [off, size] : live) a.release(off, size);
    EXPECT_EQ(a.used(), 0u);
    EXPECT_EQ(a.freeRanges(), 1u);
    EXPECT_EQ(a.largestFree(), a.capacity());
}
