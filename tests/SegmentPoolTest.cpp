// city/SegmentPool.h: owners' units in segments never resized: placed lowest first, growth that moves nothing, segments
// given back with only their owners moved, merges at kMaxSegments; the storage behind it a fake that holds a value
// per unit, so every move is checked to carry what the owner wrote.
#include "SegmentPool.h"

#include <gtest/gtest.h>

#include <map>

using namespace seasonview;
using seasonview::city::SegmentPool;

namespace {

struct FakeStorage : SegmentPool::Storage {
    std::vector<std::vector<int>> segments; // per unit: the value written there, -1 none
    int moves = 0;
    std::size_t movedUnits = 0;
    Status addSegment(std::size_t units) override {
        segments.emplace_back(units, -1);
        return Ok{};
    }
    void moveOwner(int, int fromSegment, const std::vector<std::uint32_t>& from, int toSegment,
                   const std::vector<std::uint32_t>& to) override {
        EXPECT_EQ(from.size(), to.size());
        for (std::size_t k = 0; k < from.size(); ++k) {
            EXPECT_EQ(segments[std::size_t(toSegment)][to[k]], -1) << "moved onto a unit in use";
            segments[std::size_t(toSegment)][to[k]] = segments[std::size_t(fromSegment)][from[k]];
            segments[std::size_t(fromSegment)][from[k]] = -1;
        }
        ++moves;
        movedUnits += from.size();
    }
    void eraseSegment(int segment) override {
        for (int v : segments[std::size_t(segment)]) EXPECT_EQ(v, -1) << "a segment given back with a unit in use";
        segments.erase(segments.begin() + segment);
    }
};

bool powerOfTwo(std::size_t n) { return (n & (n - 1)) == 0; }

struct Fixture {
    FakeStorage storage;
    SegmentPool pool;
    std::map<int, std::size_t> owners; // live owners and their unit counts
    explicit Fixture(std::size_t maxUnits = 1000, std::size_t minUnits = 16) : pool(storage, maxUnits, minUnits) {}

    // Places `owner` (growing by `need` with `room` more allowed when nothing has room) and writes its units.
    void add(int owner, std::size_t n, std::size_t room = 0) {
        if (!pool.place(owner, n)) {
            ASSERT_TRUE(pool.grow(n, room));
            ASSERT_TRUE(pool.place(owner, n));
        }
        const auto& units = pool.unitsOf(owner);
        ASSERT_EQ(units.size(), n);
        for (std::size_t k = 0; k < n; ++k)
            storage.segments[std::size_t(pool.segmentOf(owner))][units[k]] = owner * 1000 + int(k);
        owners[owner] = n;
    }
    void remove(int owner) {
        for (std::uint32_t u : pool.unitsOf(owner)) storage.segments[std::size_t(pool.segmentOf(owner))][u] = -1;
        pool.release(owner);
        owners.erase(owner);
    }
    // Every live owner's units in one segment, holding what it wrote; the pool's counts agree with the storage's.
    void check() const {
        ASSERT_EQ(int(storage.segments.size()), pool.segments());
        std::size_t inUse = 0;
        for (const auto& [owner, n] : owners) {
            const int s = pool.segmentOf(owner);
            ASSERT_GE(s, 0);
            const auto& units = pool.unitsOf(owner);
            ASSERT_EQ(units.size(), n);
            for (std::size_t k = 0; k < n; ++k) EXPECT_EQ(storage.segments[std::size_t(s)][units[k]], owner * 1000 + int(k));
            inUse += n;
        }
        EXPECT_EQ(pool.inUse(), inUse);
        for (int s = 0; s < pool.segments(); ++s) {
            EXPECT_EQ(pool.segmentUnits(s), storage.segments[std::size_t(s)].size());
            EXPECT_FALSE(powerOfTwo(pool.segmentUnits(s))) << "segment " << s << ": " << pool.segmentUnits(s);
        }
    }
};

} // namespace

TEST(SegmentPoolTest, PlacesLowestFirstAndGrowsWithoutMovingAnything) {
    Fixture f;
    f.add(0, 3); // no room allowed beyond the need: 3 units
    EXPECT_EQ(f.pool.segments(), 1);
    EXPECT_EQ(f.pool.segmentUnits(0), 3u);
    EXPECT_EQ(f.pool.unitsOf(0), (std::vector<std::uint32_t>{0, 1, 2}));
    f.add(1, 5, 100); // up to the 16 units at least a growth adds: 16, a power of two, so 17
    EXPECT_EQ(f.pool.segmentUnits(1), 17u);
    f.add(2, 4);
    EXPECT_EQ(f.pool.segmentOf(2), 1) << "the lowest segment with room for all of it";
    f.remove(1);
    f.add(3, 2);
    EXPECT_EQ(f.pool.unitsOf(3), (std::vector<std::uint32_t>{0, 1})) << "the lowest free units of that segment";
    for (int k = 4; k < 60; ++k) f.add(k, std::size_t(1 + k % 7), 100);
    EXPECT_LE(f.pool.segments(), SegmentPool::kMaxSegments);
    EXPECT_EQ(f.storage.moves, 0) << "growing below kMaxSegments moves nothing";
    f.check();
}

TEST(SegmentPoolTest, GivingBackMovesOnlyTheOwnersOfTheSegmentGivenBack) {
    Fixture f;
    for (int k = 0; k < 80; ++k) f.add(k, 4, 30);
    const int before = f.pool.segments();
    ASSERT_GE(before, 3);
    for (int k = 0; k < 80; ++k)
        if (k % 5 != 0) f.remove(k);
    f.check();
    const std::size_t live = f.pool.inUse(), movedBefore = f.storage.movedUnits;
    f.pool.shrink(live, false, [] { return false; });
    EXPECT_LT(f.pool.segments(), before);
    EXPECT_LE(f.storage.movedUnits - movedBefore, live) << "only live owners are moved, each at most once";
    EXPECT_GE(f.pool.held(), live + live / 4) << "a quarter more than needed is kept";
    f.check();
    // Over the limit: one segment given back at a time, while the caller says it is still over.
    Fixture g;
    for (int k = 0; k < 80; ++k) g.add(k, 4, 30);
    for (int k = 0; k < 80; ++k)
        if (k % 5 != 0) g.remove(k);
    const int n = g.pool.segments();
    g.pool.shrink(g.pool.inUse(), true, [] { return false; });
    EXPECT_EQ(g.pool.segments(), n - 1);
    g.check();
}

TEST(SegmentPoolTest, OwnersMoveWholeOrTheSegmentStays) {
    // An empty segment is given back as it is; one whose owners fit in no other's free room, each whole, stays.
    Fixture f(1000, 1);
    ASSERT_TRUE(f.pool.grow(5, 0)); // segment 0: 5 units
    ASSERT_TRUE(f.pool.grow(9, 0)); // segment 1: 9 units
    f.add(0, 5);
    f.add(1, 5);
    f.add(2, 3);
    ASSERT_EQ(f.pool.segmentOf(2), 1) << "segment 1 has room for it";
    f.remove(0); // segment 0: 5 free, the others' 8 units in segment 1
    f.pool.shrink(1, false, [] { return false; });
    EXPECT_EQ(f.pool.segments(), 1) << "segment 0 (empty) given back";
    EXPECT_EQ(f.storage.moves, 0);
    f.check();
    Fixture g(1000, 1);
    ASSERT_TRUE(g.pool.grow(7, 0));
    ASSERT_TRUE(g.pool.grow(6, 0));
    g.add(0, 7);
    g.add(1, 6); // segment 1: 6 units, none free
    g.remove(0);
    g.add(2, 2); // segment 0: 2 in use, 5 free
    g.pool.shrink(1, false, [] { return false; });
    // Segment 0 (5 free) first: its owner (2 units) fits nowhere else, segment 1 has no free unit; segment 1's
    // owner (6 units) does not fit segment 0's 5 free: nothing is given back.
    EXPECT_EQ(g.pool.segments(), 2);
    EXPECT_EQ(g.storage.moves, 0);
    g.check();
}

TEST(SegmentPoolTest, MergesTheTwoLeastUsedAtMaxSegments) {
    Fixture f(1000, 1);
    for (int k = 0; k < SegmentPool::kMaxSegments; ++k) f.add(k, std::size_t(3 + k)); // a full segment each
    ASSERT_EQ(f.pool.segments(), SegmentPool::kMaxSegments);
    f.add(100, 4);
    EXPECT_EQ(f.pool.segments(), SegmentPool::kMaxSegments - 1) << "the two least used and the new room made one";
    EXPECT_EQ(f.storage.moves, 2) << "the owners of segments 0 and 1";
    EXPECT_EQ(f.storage.movedUnits, 3u + 4u);
    EXPECT_EQ(f.pool.segmentOf(0), f.pool.segmentOf(100));
    EXPECT_EQ(f.pool.segmentOf(1), f.pool.segmentOf(100));
    f.check();
}

TEST(SegmentPoolTest, ANeedOverOneSegmentIsSplitAcrossSegments) {
    Fixture f(10, 1); // tiles: one unit an owner, 10 units a segment at most
    ASSERT_TRUE(f.pool.grow(25, 0));
    EXPECT_EQ(f.pool.segments(), 3);
    EXPECT_EQ(f.pool.held(), 25u) << "10 + 10 + 5";
    for (int k = 0; k < 25; ++k) f.add(k, 1);
    EXPECT_EQ(f.storage.moves, 0);
    f.check();
}
