#pragma once
// Free indices handed out lowest first (BlockMapPoolGL's tiles and pages): what is in use gathers at the bottom, so
// the top of a store empties as its users leave and can be given back.
#include <algorithm>
#include <cstdint>
#include <functional>
#include <vector>

namespace seasonview::city {

class LowestFree {
public:
    std::size_t size() const { return m_heap.size(); }
    bool empty() const { return m_heap.empty(); }
    /// The lowest free index, taken (not empty()).
    std::uint32_t take() {
        std::pop_heap(m_heap.begin(), m_heap.end(), std::greater<>());
        const std::uint32_t i = m_heap.back();
        m_heap.pop_back();
        return i;
    }
    void release(std::uint32_t i) {
        m_heap.push_back(i);
        std::push_heap(m_heap.begin(), m_heap.end(), std::greater<>());
    }
    /// Indices [begin, end) free (a store grown).
    void add(std::uint32_t begin, std::uint32_t end) {
        for (std::uint32_t i = begin; i < end; ++i) m_heap.push_back(i);
        std::make_heap(m_heap.begin(), m_heap.end(), std::greater<>());
    }
    /// The free indices at or past `end` forgotten (a store cut to `end`, nothing in use past it).
    void keepBelow(std::uint32_t end) {
        m_heap.erase(std::remove_if(m_heap.begin(), m_heap.end(), [&](std::uint32_t i) { return i >= end; }),
                     m_heap.end());
        std::make_heap(m_heap.begin(), m_heap.end(), std::greater<>());
    }

private:
    std::vector<std::uint32_t> m_heap; // a min-heap
};

} // namespace seasonview::city
