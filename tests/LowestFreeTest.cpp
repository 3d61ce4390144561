// city/LowestFree.h: the lowest free index first, releases, growth and cuts.
#include "LowestFree.h"

#include <gtest/gtest.h>

using seasonview::city::LowestFree;

TEST(LowestFreeTest, HandsOutTheLowestFirst) {
    LowestFree f;
    f.add(0, 6);
    EXPECT_EQ(f.take(), 0u);
    EXPECT_EQ(f.take(), 1u);
    EXPECT_EQ(f.take(), 2u);
    f.release(1);
    EXPECT_EQ(f.take(), 1u) << "a released index before the higher free ones";
    f.add(6, 8);
    EXPECT_EQ(f.size(), 5u); // 3, 4, 5, 6, 7
    f.release(0);
    f.keepBelow(5); // a store cut to 5: 5, 6, 7 forgotten
    EXPECT_EQ(f.size(), 3u);
    EXPECT_EQ(f.take(), 0u);
    EXPECT_EQ(f.take(), 3u);
    EXPECT_EQ(f.take(), 4u);
    EXPECT_TRUE(f.empty());
}
