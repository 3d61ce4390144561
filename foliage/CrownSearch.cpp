#include "CrownSearch.h"

#include <algorithm>
#include <cmath>

namespace seasonview {

std::vector<glm::vec4> findCrownCentres(const CrownSearchLevel& in, float minRadius, int maxRadius) {
    const int n = in.size, slots = in.size / in.block;
    const TexelRect& w = in.window;
    const auto inWindow = [&](int x, int y) { return x >= w.x0 && x < w.x1 && y >= w.y0 && y < w.y1; };
    const auto wrap = [&](int v) { return ((v % n) + n) % n; };
    const int width = w.x1 - w.x0, height = w.y1 - w.y0;
    // Per window texel (row-major from the window's first), as trunk_find.comp's images; every pass below walks them
    // row by row (a column-major walk misses the cache at every texel).
    const auto at = [&](int x, int y) { return size_t(y - w.y0) * size_t(n) + size_t(x - w.x0); };
    // -1: unknown (outside the level's image, or not derived), else the canopy value; one tag check per block and row.
    std::vector<std::int16_t> value(size_t(n) * size_t(std::max(height, 0)), -1);
    for (int y = std::max(w.y0, 0); y < w.y1; ++y) {
        const int by = y / in.block;
        const std::uint8_t* row = in.values.data() + size_t(wrap(y)) * size_t(n);
        std::int16_t* out = value.data() + at(w.x0, y);
        for (int x = std::max(w.x0, 0); x < w.x1;) {
            const int bx = x / in.block, end = std::min(w.x1, (bx + 1) * in.block);
            const bool derived = in.tags[size_t(by % slots) * size_t(slots) + size_t(bx % slots)] == (bx | (by << 16));
            for (; x < end; ++x) out[x - w.x0] = derived ? std::int16_t(row[wrap(x)]) : std::int16_t(-1);
        }
    }
    const auto valueAt = [&](int x, int y) -> int { return inWindow(x, y) ? int(value[at(x, y)]) : -1; };
    std::vector<float> zeroAt(size_t(n) * size_t(n)), unknownAt(zeroAt.size()), dist(zeroAt.size());

    // Pass 0, along each column: the nearest texel outside the canopy up or down (0 on one), and the nearest unknown
    // one met before it, both clamped past maxRadius (trunk_find.comp; one scan of the whole column instead of the
    // shader's runs of 64 rows: only events within maxRadius count, the same either way). The rows beyond the window
    // are unknown, so each column's scan starts with an unknown texel just outside. All columns at once, row by row:
    // last[x] is the row of the last texel <= 0 met in column x, lastValue[x] its value; upRow the one met going down
    // the rows (its row, or -1 - its row where it was unknown).
    const float far = float(maxRadius + 1);
    std::vector<int> upRow(value.size()), last(size_t(std::max(width, 0)), w.y0 - 1);
    std::vector<std::int16_t> lastValue(last.size(), -1);
    for (int y = w.y0; y < w.y1; ++y) {
        const std::int16_t* v = value.data() + at(w.x0, y);
        int* up = upRow.data() + at(w.x0, y);
        for (int i = 0; i < width; ++i) {
            up[i] = lastValue[size_t(i)] == 0 ? last[size_t(i)] : -1 - last[size_t(i)];
            if (v[i] <= 0) {
                last[size_t(i)] = y;
                lastValue[size_t(i)] = v[i];
            }
        }
    }
    std::fill(last.begin(), last.end(), w.y1);
    std::fill(lastValue.begin(), lastValue.end(), std::int16_t(-1));
    for (int y = w.y1 - 1; y >= w.y0; --y) {
        const std::int16_t* v = value.data() + at(w.x0, y);
        const int* up = upRow.data() + at(w.x0, y);
        float* zeroRow = zeroAt.data() + at(w.x0, y);
        float* unknownRow = unknownAt.data() + at(w.x0, y);
        for (int i = 0; i < width; ++i) {
            float zero = far, unknown = far;
            if (v[i] < 0) {
                zero = -1.0f;
            } else if (v[i] == 0) {
                zero = 0.0f;
            } else {
                const int u = up[i];
                const int upDistance = u >= 0 ? y - u : y - (-1 - u);
                const bool upSeen = upDistance <= maxRadius;
                const float du = upSeen ? float(upDistance) : far;
                const bool upZero = upSeen && u >= 0;
                const bool downSeen = last[size_t(i)] - y <= maxRadius;
                const float dd = downSeen ? float(last[size_t(i)] - y) : far;
                const bool downZero = downSeen && lastValue[size_t(i)] == 0;
                zero = std::min(upZero ? du : far, downZero ? dd : far);
                if (upSeen && !upZero && du <= (downZero ? dd : far)) unknown = std::min(unknown, du);
                if (downSeen && !downZero && dd < (upZero ? du : far)) unknown = std::min(unknown, dd);
            }
            zeroRow[i] = zero;
            unknownRow[i] = unknown;
            if (v[i] <= 0) {
                last[size_t(i)] = y;
                lastValue[size_t(i)] = v[i];
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
