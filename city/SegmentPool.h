#pragma once
// Storage of one kind (BlockMapPoolGL's tiles, or its pages of wall words) as segments that are never resized, and the
// policy that keeps it compact without copying what is resident when it grows. Units are handed out to owners (the
// maps), all of an owner's units in one segment, the lowest free units of the lowest segment with room: what is in
// use gathers at the bottom, and the top segments empty as owners leave. grow() adds a segment of what is needed and
// up to half the units held more, within the room the caller allows; at kMaxSegments it merges the two least used
// into the segment it adds instead. shrink() gives segments back: each time the one with the most free units whose
// owners the others' free room can take, those owners moved. No segment's size is a power of two (llvmpipe builds a
// shader variant for each kind of texture buffer bound, power-of-two sizes apart: a first draw with the other kind
// waited 340 ms for it).
//
// Plain C++: the storage is the caller's (Storage: add a segment, move an owner's units, drop a segment), so the
// policy is tested without a GL (SegmentPoolTest).
#include "LowestFree.h"
#include "Result.h"

#include <cstdint>
#include <functional>
#include <vector>

namespace seasonview::city {

class SegmentPool {
public:
    /// Segments at most: the two least used are merged into the next one added (each pair of segments a draw's maps
    /// lie in is a draw call).
    static constexpr int kMaxSegments = 8;

    /// What the pool asks of the storage behind it.
    struct Storage {
        virtual ~Storage() = default;
        /// A segment of `units` units added after the others.
        virtual Status addSegment(std::size_t units) = 0;
        /// Owner `owner`'s units `from` in segment `fromSegment` copied to `to` in segment `toSegment`, in order (the
        /// pool has already given it the new ones: unitsOf(owner) is `to`).
        virtual void moveOwner(int owner, int fromSegment, const std::vector<std::uint32_t>& from, int toSegment,
                               const std::vector<std::uint32_t>& to) = 0;
        /// Segment `segment` dropped (nothing in it is in use); the ones after it move down one.
        virtual void eraseSegment(int segment) = 0;
    };

    /// `maxUnits`: the most one segment may hold (the GL's limit); `minUnits`: the least a growth adds in all.
    SegmentPool(Storage& storage, std::size_t maxUnits, std::size_t minUnits);

    int segments() const { return int(m_segments.size()); }
    std::size_t segmentUnits(int segment) const { return m_segments[std::size_t(segment)].units; }
    std::size_t segmentUsed(int segment) const { return m_segments[std::size_t(segment)].used; }
    std::size_t held() const;      // units in all segments
    std::size_t inUse() const { return m_inUse; }
    std::size_t freeUnits() const; // in all segments
    std::size_t maxUnits() const { return m_maxUnits; }

    /// `n` units for `owner` (which holds none) in the lowest segment with room for all of them, the lowest free ones;
    /// false, and nothing changed, when no segment has room (grow() first).
    bool place(int owner, std::size_t n);
    /// Owner `owner`'s units freed for others (nothing when it holds none).
    void release(int owner);
    /// The segment owner `owner`'s units lie in (-1: none), and the units, in the order placed.
    int segmentOf(int owner) const;
    const std::vector<std::uint32_t>& unitsOf(int owner) const;

    /// Room for `need` more units, an owner's worth of them in one segment (`need` at most maxUnits()): a segment of
    /// `need` and up to half the units held more (at least minUnits in all), of which at most `room` beyond `need`
    /// (the caller's limit); at kMaxSegments, the two least used segments and that room made one new segment (their
    /// owners moved), where it fits maxUnits(). Errors: the storage's; `need` over maxUnits().
    Status grow(std::size_t need, std::size_t room);
    /// Gives segments back while the others hold `need` units, and a quarter more unless `over` (the caller is over
    /// its limit: then only while `stillOver()` says so after each): each time the segment with the most free units
    /// whose owners fit, each whole, in the others' free room; those owners moved there.
    void shrink(std::size_t need, bool over, const std::function<bool()>& stillOver);

private:
    struct Segment {
        std::size_t units = 0, used = 0;
        LowestFree free;
    };
    struct Owner {
        int segment = -1;
        std::vector<std::uint32_t> units;
    };
    Status addSegment(std::size_t units);
    /// Owner `owner` moved into segment `to`'s free units (room checked by the caller).
    void move(int owner, int to);
    /// Segment `segment` (nothing of it in use) dropped; the owners' segments after it renumbered.
    void erase(int segment);
    /// Segments a < b made one new segment with `extra` more units, their owners moved.
    Status merge(int a, int b, std::size_t extra);

    Storage& m_storage;
    std::size_t m_maxUnits = 1, m_minUnits = 1, m_inUse = 0;
    std::vector<Segment> m_segments;
    std::vector<Owner> m_owners; // by owner
};

} // namespace seasonview::city
