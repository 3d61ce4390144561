#include "RangeAllocator.h"

#include <algorithm>
#include <cassert>
#include <iterator>

namespace seasonview::city {

RangeAllocator::RangeAllocator(std::size_t capacity) : m_capacity(capacity) {
    if (capacity > 0) m_free[0] = capacity;
}

std::optional<std::size_t> RangeAllocator::allocate(std::size_t size) {
    if (size == 0) return std::nullopt;
    for (auto it = m_free.begin(); it != m_free.end(); ++it) {
        if (it->second < size) continue;
        const std::size_t offset = it->first, rest = it->second - size;
        m_free.erase(it);
        if (rest > 0) m_free[offset + size] = rest;
        m_used += size;
        return offset;
    }
    return std::nullopt;
}

void RangeAllocator::insertFree(std::size_t offset, std::size_t size) {
    auto next = m_free.lower_bound(offset);
    if (next != m_free.begin()) {
        auto prev = std::prev(next);
        if (prev->first + prev->second == offset) {
            offset = prev->first;
            size += prev->second;
            m_free.erase(prev);
        }
    }
    if (next != m_free.end() && offset + size == next->first) {
        size += next->second;
        m_free.erase(next);
    }
    m_free[offset] = size;
}

void RangeAllocator::release(std::size_t offset, std::size_t size) {
    if (size == 0) return;
    assert(offset + size <= m_capacity && m_used >= size);
    m_used -= size;
    insertFree(offset, size);
}

void RangeAllocator::grow(std::size_t capacity) {
    if (capacity <= m_capacity) return;
    const std::size_t old = m_capacity;
    m_capacity = capacity;
    insertFree(old, capacity - old);
}

std::size_t RangeAllocator::largestFree() const {
    std::size_t best = 0;
    for (const auto& [offset, size] : m_free) best = std::max(best, size);
    return best;
}

} // namespace seasonview::city
