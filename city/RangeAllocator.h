#pragma once
// Ranges of a linear store handed out and taken back (first fit; a freed range merges with free neighbours), for GPU
// pools whose items differ in size: BlockMapPoolGL's wall words. Plain C++.
#include <cstddef>
#include <map>
#include <optional>

namespace seasonview::city {

class RangeAllocator {
public:
    /// A store of `capacity` units, all free.
    explicit RangeAllocator(std::size_t capacity = 0);
    /// The first free range of `size` units (size > 0), its offset; none when no free range is that long.
    std::optional<std::size_t> allocate(std::size_t size);
    /// Returns [offset, offset + size), handed out by allocate(size).
    void release(std::size_t offset, std::size_t size);
    /// The store grows to `capacity` units (>= capacity()): the new units are free.
    void grow(std::size_t capacity);
    std::size_t capacity() const { return m_capacity; }
    std::size_t used() const { return m_used; }
    /// The longest free range.
    std::size_t largestFree() const;
    /// Free ranges (fragments), for tests.
    std::size_t freeRanges() const { return m_free.size(); }

private:
    void insertFree(std::size_t offset, std::size_t size);
    std::map<std::size_t, std::size_t> m_free; // offset -> size, no two adjacent
    std::size_t m_capacity = 0, m_used = 0;
};

} // namespace seasonview::city
