#include "ClipmapSchedule.h"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace seasonview {

int ClipmapLayout::clipLevels() const {
    int n = 0;
    for (const glm::ivec2& s : levelSizes)
        if (s.x > size || s.y > size) ++n;
    return n;
}

ClipmapLayout makeClipmapLayout(int width, int height, int size, int block) {
    assert(width > 0 && height > 0 && size % block == 0 && "makeClipmapLayout(): bad sizes");
    ClipmapLayout l;
    l.size = size;
    l.block = block;
    glm::ivec2 s(width, height);
    l.levelSizes.push_back(s);
    while (s.x > 1 || s.y > 1) {
        s = glm::ivec2((s.x + 1) / 2, (s.y + 1) / 2);
        l.levelSizes.push_back(s);
    }
    return l;
}

ClipmapSchedule::ClipmapSchedule(ClipmapLayout layout) : m_layout(std::move(layout)) {
    const int n = m_layout.clipLevels();
    m_windows.assign(size_t(n), TexelRect{});
    m_tags.assign(size_t(n), std::vector<std::int32_t>(size_t(slotsPerSide()) * size_t(slotsPerSide()), kEmptyTag));
}

std::int32_t ClipmapSchedule::tagOf(int bx, int by) {
    assert(bx >= 0 && by >= 0 && bx < 32768 && by < 32768 && "ClipmapSchedule::tagOf(): block out of range");
    return std::int32_t(bx | (by << 16));
}

long long ClipmapSchedule::setCenters(const std::vector<glm::dvec2>& centres) {
    assert(centres.size() >= m_windows.size() && "ClipmapSchedule::setCenters(): one centre per clip level");
    long long exposed = 0;
    for (size_t l = 0; l < m_windows.size(); ++l) {
        const double scale = std::ldexp(1.0, -int(l));
        const TexelRect next = windowAround(centres[l] * scale, m_layout.size, m_layout.block);
        const glm::ivec2 s = m_layout.levelSizes[l];
        const TexelRect image{0, 0, s.x, s.y};
        for (const TexelRect& r : exposedRects(m_windows[l], next)) exposed += intersect(r, image).area();
        m_windows[l] = next;
    }
    return exposed;
}

TexelRect ClipmapSchedule::blockTexels(const BlockKey& k) const {
    const int b = m_layout.block;
    const glm::ivec2 s = m_layout.levelSizes[size_t(k.level)];
    return intersect(TexelRect{k.bx * b, k.by * b, (k.bx + 1) * b, (k.by + 1) * b}, TexelRect{0, 0, s.x, s.y});
}

bool ClipmapSchedule::holds(const BlockKey& k) const {
    const int n = slotsPerSide();
    return m_tags[size_t(k.level)][size_t(wrapTexel(k.by, n)) * size_t(n) + size_t(wrapTexel(k.bx, n))] ==
           tagOf(k.bx, k.by);
}

void ClipmapSchedule::markStored(const BlockKey& k) {
    const int n = slotsPerSide();
    m_tags[size_t(k.level)][size_t(wrapTexel(k.by, n)) * size_t(n) + size_t(wrapTexel(k.bx, n))] = tagOf(k.bx, k.by);
}

std::vector<BlockKey> ClipmapSchedule::missingBlocks(size_t limit) const {
    std::vector<BlockKey> out;
    const int b = m_layout.block;
    for (size_t l = 0; l < m_windows.size() && out.size() < limit; ++l) {
        const TexelRect w = intersect(m_windows[l], TexelRect{0, 0, m_layout.levelSizes[l].x, m_layout.levelSizes[l].y});
        if (w.empty()) continue;
        const double cx = 0.5 * (m_windows[l].x0 + m_windows[l].x1) / b, cy = 0.5 * (m_windows[l].y0 + m_windows[l].y1) / b;
        std::vector<std::pair<double, BlockKey>> level;
        for (int by = w.y0 / b; by * b < w.y1; ++by)
            for (int bx = w.x0 / b; bx * b < w.x1; ++bx) {
                const BlockKey k{int(l), bx, by};
                if (holds(k)) continue;
                const double dx = bx + 0.5 - cx, dy = by + 0.5 - cy;
                level.push_back({dx * dx + dy * dy, k});
            }
        std::stable_sort(level.begin(), level.end(), [](const auto& a, const auto& c) { return a.first < c.first; });
        for (const auto& [d, k] : level) {
            if (out.size() >= limit) break;
            out.push_back(k);
        }
    }
    return out;
}

} // namespace seasonview
