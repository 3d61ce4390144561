#include "CrownSearch.h"

#include <algorithm>
#include <cmath>

namespace seasonview {

std::vector<glm::vec4> findCrownCentres(const CrownSearchLevel& in, float minRadius, int maxRadius) {
    const int n = in.size, slots = in.size / in.block;
    const TexelRect& w = in.window;
    const auto inWindow = [&](int x, int y) { return x >= w.x0 && x < w.x1 && y >= w.y0 && y < w.y1; };
    const auto wrap = [&](int v) { return ((v % n) + n) % n; };
    // -1: unknown (outside the window or the level's image, or not derived), else the canopy value.
    const auto valueAt = [&](int x, int y) -> int {
        if (!inWindow(x, y) || x < 0 || y < 0) return -1;
        const int bx = x / in.block, by = y / in.block;
        if (in.tags[size_t(by % slots) * size_t(slots) + size_t(bx % slots)] != (bx | (by << 16))) return -1;
        return int(in.values[size_t(wrap(y)) * size_t(n) + size_t(wrap(x))]);
    };
    // Per window texel (row-major from the window's first), as trunk_find.comp's images.
    std::vector<float> zeroAt(size_t(n) * size_t(n)), unknownAt(zeroAt.size()), dist(zeroAt.size());
    const auto at = [&](int x, int y) { return size_t(y - w.y0) * size_t(n) + size_t(x - w.x0); };

    // Pass 0, along each column: the nearest texel outside the canopy up or down (0 on one), and the nearest unknown
    // one met before it, both clamped past maxRadius (trunk_find.comp; one scan of the whole column instead of the
    // shader's runs of 64 rows: only events within maxRadius count, the same either way).
    const int none = -(1 << 20);
    const float far = float(maxRadius + 1);
    std::vector<int> value(static_cast<size_t>(n)), upRow(static_cast<size_t>(n));
    for (int x = w.x0; x < w.x1; ++x) {
        int lastRow = none, lastValue = 0;
        for (int y = w.y0 - maxRadius; y < w.y1; ++y) {
            const int v = valueAt(x, y);
            if (y >= w.y0) {
                value[size_t(y - w.y0)] = v;
                upRow[size_t(y - w.y0)] = lastRow == none ? none : (lastValue == 0 ? lastRow : -1 - lastRow);
            }
            if (v <= 0) {
                lastRow = y;
                lastValue = v;
            }
        }
        lastRow = none;
        for (int y = w.y1 - 1 + maxRadius; y >= w.y0; --y) {
            const int v = y < w.y1 ? value[size_t(y - w.y0)] : valueAt(x, y);
            if (y < w.y1) {
                float zero = far, unknown = far;
                if (v < 0) {
                    zero = -1.0f;
                } else if (v == 0) {
                    zero = 0.0f;
                } else {
                    const int u = upRow[size_t(y - w.y0)];
                    const bool upSeen = u != none && (u >= 0 ? y - u : y - (-1 - u)) <= maxRadius;
                    const float du = upSeen ? float(u >= 0 ? y - u : y - (-1 - u)) : far;
                    const bool upZero = upSeen && u >= 0;
                    const bool downSeen = lastRow != none && lastRow - y <= maxRadius;
                    const float dd = downSeen ? float(lastRow - y) : far;
                    const bool downZero = downSeen && lastValue == 0;
                    zero = std::min(upZero ? du : far, downZero ? dd : far);
                    if (upSeen && !upZero && du <= (downZero ? dd : far)) unknown = std::min(unknown, du);
                    if (downSeen && !downZero && dd < (upZero ? du : far)) unknown = std::min(unknown, dd);
                }
                zeroAt[at(x, y)] = zero;
                unknownAt[at(x, y)] = unknown;
            }
            if (v <= 0) {
                lastRow = y;
                lastValue = v;
            }
        }
    }

    // Pass 1, along the rows: the distance (exact within maxRadius), -1 where an unknown texel could be nearer.
    for (int y = w.y0; y < w.y1; ++y)
        for (int x = w.x0; x < w.x1; ++x) {
            const float cr = zeroAt[at(x, y)], cg = unknownAt[at(x, y)];
            float d = 0.0f;
            if (cr < 0.0f) {
                d = -1.0f;
            } else if (cr > 0.0f) {
                float best2 = float(maxRadius * maxRadius), unknown2 = cg * cg;
                best2 = std::min(best2, cr * cr);
                for (int dx = 1; dx <= maxRadius && float(dx * dx) < best2; ++dx)
                    for (int side = -1; side <= 1; side += 2) {
                        const int ox = x + side * dx;
                        if (!inWindow(ox, y)) {
                            unknown2 = std::min(unknown2, float(dx * dx));
                            continue;
                        }
                        const float wr = zeroAt[at(ox, y)], wg = unknownAt[at(ox, y)];
                        if (wr < 0.0f) {
                            unknown2 = std::min(unknown2, float(dx * dx));
                            continue;
                        }
                        best2 = std::min(best2, float(dx * dx) + wr * wr);
                        unknown2 = std::min(unknown2, float(dx * dx) + wg * wg);
                    }
                d = unknown2 < best2 ? -1.0f : std::sqrt(best2);
            }
            dist[at(x, y)] = d;
        }

    // Pass 2: the maxima, each the largest within 0.75 × its distance (ties: the first in row order).
    const auto distanceAt = [&](int x, int y) { return inWindow(x, y) ? dist[at(x, y)] : -1.0f; };
    const float scale = std::ldexp(1.0f, in.level);
    std::vector<glm::vec4> out;
    for (int y = w.y0; y < w.y1; ++y)
        for (int x = w.x0; x < w.x1; ++x) {
            const float d = dist[at(x, y)];
            const float radius = std::max(0.5f, d - 0.5f);
            if (d <= 0.0f || radius < minRadius) continue;
            const auto beaten = [&](int dx, int dy) {
                const float o = distanceAt(x + dx, y + dy);
                if (o < 0.0f) return true; // not known there yet: decide when it is
                const bool before = dy < 0 || (dy == 0 && dx < 0);
                return o > d || (before && o == d);
            };
            bool keep = true;
            for (int dy = -1; dy <= 1 && keep; ++dy)
                for (int dx = -1; dx <= 1 && keep; ++dx)
                    if ((dx != 0 || dy != 0) && beaten(dx, dy)) keep = false;
            const int s = std::max(1, int(std::ceil(0.75f * d)));
            for (int dy = -s; dy <= s && keep; ++dy)
                for (int dx = -s; dx <= s && keep; ++dx)
                    if ((dx != 0 || dy != 0) && beaten(dx, dy)) keep = false;
            if (!keep) continue;
            out.push_back({(float(x) + 0.5f) * scale, (float(y) + 0.5f) * scale, radius * scale, float(valueAt(x, y))});
        }
    return out;
}

} // namespace seasonview
