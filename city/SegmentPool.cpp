#include "SegmentPool.h"

#include <algorithm>
#include <numeric>

namespace seasonview::city {

SegmentPool::SegmentPool(Storage& storage, std::size_t maxUnits, std::size_t minUnits)
    : m_storage(storage), m_maxUnits(std::max<std::size_t>(maxUnits, 1)), m_minUnits(minUnits) {}

std::size_t SegmentPool::held() const {
    std::size_t n = 0;
    for (const Segment& s : m_segments) n += s.units;
    return n;
}

std::size_t SegmentPool::freeUnits() const {
    std::size_t n = 0;
    for (const Segment& s : m_segments) n += s.free.size();
    return n;
}

int SegmentPool::segmentOf(int owner) const {
    return std::size_t(owner) < m_owners.size() ? m_owners[std::size_t(owner)].segment : -1;
}

const std::vector<std::uint32_t>& SegmentPool::unitsOf(int owner) const {
    static const std::vector<std::uint32_t> none;
    return std::size_t(owner) < m_owners.size() ? m_owners[std::size_t(owner)].units : none;
}

bool SegmentPool::place(int owner, std::size_t n) {
    if (std::size_t(owner) >= m_owners.size()) m_owners.resize(std::size_t(owner) + 1);
    Owner& o = m_owners[std::size_t(owner)];
    if (n == 0) return true;
    for (int i = 0; i < segments(); ++i) {
        Segment& s = m_segments[std::size_t(i)];
        if (s.free.size() < n) continue;
        o.segment = i;
        o.units.clear();
        for (std::size_t j = 0; j < n; ++j) o.units.push_back(s.free.take());
        s.used += n;
        m_inUse += n;
        return true;
    }
    return false;
}

void SegmentPool::release(int owner) {
    if (std::size_t(owner) >= m_owners.size()) return;
    Owner& o = m_owners[std::size_t(owner)];
    if (o.segment >= 0) {
        Segment& s = m_segments[std::size_t(o.segment)];
        for (const std::uint32_t u : o.units) s.free.release(u);
        s.used -= o.units.size();
        m_inUse -= o.units.size();
    }
    o = Owner{};
}

Status SegmentPool::addSegment(std::size_t units) {
    Segment s;
    s.units = std::clamp<std::size_t>(units, 1, m_maxUnits);
    // Never a power of two, as no other segment is (the header's llvmpipe shader variants).
    while ((s.units & (s.units - 1)) == 0 && s.units < m_maxUnits) ++s.units;
    if (auto st = m_storage.addSegment(s.units); !st) return st;
    s.free.add(0, std::uint32_t(s.units));
    m_segments.push_back(std::move(s));
    return Ok{};
}

void SegmentPool::move(int owner, int to) {
    Owner& o = m_owners[std::size_t(owner)];
    Segment &from = m_segments[std::size_t(o.segment)], &dst = m_segments[std::size_t(to)];
    const std::vector<std::uint32_t> old = o.units;
    for (std::uint32_t& u : o.units) {
        from.free.release(u);
        u = dst.free.take();
    }
    from.used -= old.size();
    dst.used += old.size();
    const int fromSegment = o.segment;
    o.segment = to;
    m_storage.moveOwner(owner, fromSegment, old, to, o.units);
}

void SegmentPool::erase(int segment) {
    m_storage.eraseSegment(segment);
    m_segments.erase(m_segments.begin() + segment);
    for (Owner& o : m_owners)
        if (o.segment > segment) --o.segment;
}

Status SegmentPool::merge(int a, int b, std::size_t extra) {
    if (auto st = addSegment(m_segments[std::size_t(a)].used + m_segments[std::size_t(b)].used + extra); !st) return st;
    const int into = segments() - 1;
    for (int k = 0; k < int(m_owners.size()); ++k)
        if (m_owners[std::size_t(k)].segment == a || m_owners[std::size_t(k)].segment == b) move(k, into);
    erase(b);
    erase(a);
    return Ok{};
}

Status SegmentPool::grow(std::size_t need, std::size_t room) {
    // What is needed, and up to half the units held more (at least minUnits in all) within the caller's room: nothing
    // resident moves, so a generous segment costs only the memory the limit allows.
    const std::size_t wanted = std::max(held() / 2, need < m_minUnits ? m_minUnits - need : 0);
    std::size_t n = need + std::min(wanted, room);
    if (n > m_maxUnits && need <= m_maxUnits) n = m_maxUnits;
    if (segments() >= kMaxSegments && n <= m_maxUnits) {
        // The two segments with the fewest units in use, the lower index first.
        std::vector<int> order(m_segments.size());
        std::iota(order.begin(), order.end(), 0);
        std::stable_sort(order.begin(), order.end(), [&](int x, int y) {
            return m_segments[std::size_t(x)].used < m_segments[std::size_t(y)].used;
        });
        const int a = std::min(order[0], order[1]), b = std::max(order[0], order[1]);
        if (m_segments[std::size_t(a)].used + m_segments[std::size_t(b)].used + n <= m_maxUnits) return merge(a, b, n);
    }
    while (n > 0) { // more than one segment holds only when `need` alone is over maxUnits (owners of few units each)
        const std::size_t part = std::min(n, m_maxUnits);
        if (auto st = addSegment(part); !st) return st;
        n -= part;
    }
    return Ok{};
}

void SegmentPool::shrink(std::size_t need, bool over, const std::function<bool()>& stillOver) {
    for (bool gave = true; gave && !m_segments.empty();) {
        gave = false;
        const std::size_t total = held();
        int pick = -1;
        std::vector<int> owners, target;
        for (int i = 0; i < segments(); ++i) {
            const Segment& s = m_segments[std::size_t(i)];
            if (total - s.units < (over ? need : need + need / 4)) continue;
            if (pick >= 0 && s.free.size() <= m_segments[std::size_t(pick)].free.size()) continue;
            // Each of its owners whole into the first other segment with room left for it.
            std::vector<std::size_t> room(m_segments.size());
            for (std::size_t j = 0; j < room.size(); ++j) room[j] = int(j) == i ? 0 : m_segments[j].free.size();
            std::vector<int> its, to;
            bool fits = true;
            for (int k = 0; k < int(m_owners.size()) && fits; ++k) {
                if (m_owners[std::size_t(k)].segment != i) continue;
                const std::size_t n = m_owners[std::size_t(k)].units.size();
                int j = 0;
                while (j < int(room.size()) && room[std::size_t(j)] < n) ++j;
                fits = j < int(room.size());
                if (!fits) break;
                room[std::size_t(j)] -= n;
                its.push_back(k);
                to.push_back(j);
            }
            if (!fits) continue;
            pick = i;
            owners = std::move(its);
            target = std::move(to);
        }
        if (pick < 0) return;
        for (std::size_t k = 0; k < owners.size(); ++k) move(owners[k], target[k]);
        erase(pick);
        gave = !over || stillOver();
    }
}

} // namespace seasonview::city
