#pragma once
// Convex polygons for the synthetic scene layout: counter-clockwise vertex lists in metres, each edge i
// (v[i] -> v[i+1]) carrying a tag (the cut that created it). Small and header-only; used by the parcel partition
// and by object placement inside parcels.
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <vector>

namespace seasonview::synth {

inline glm::vec2 perpLeft(glm::vec2 d) { return glm::vec2(-d.y, d.x); }

/// Signed area, positive for counter-clockwise polygons (square metres).
inline float polygonArea(const std::vector<glm::vec2>& p) {
    double a = 0.0;
    for (size_t i = 0, n = p.size(); i < n; ++i) {
        const glm::vec2 u = p[i], v = p[(i + 1) % n];
        a += double(u.x) * double(v.y) - double(v.x) * double(u.y);
    }
    return static_cast<float>(0.5 * a);
}

inline glm::vec2 polygonCentroid(const std::vector<glm::vec2>& p) {
    double cx = 0.0, cy = 0.0, a = 0.0;
    for (size_t i = 0, n = p.size(); i < n; ++i) {
        const glm::vec2 u = p[i], v = p[(i + 1) % n];
        const double c = double(u.x) * double(v.y) - double(v.x) * double(u.y);
        a += c;
        cx += (double(u.x) + double(v.x)) * c;
        cy += (double(u.y) + double(v.y)) * c;
    }
    if (a == 0.0) return p.empty() ? glm::vec2(0.0f) : p[0];
    return glm::vec2(static_cast<float>(cx / (3.0 * a)), static_cast<float>(cy / (3.0 * a)));
}

/// Distance from q to the nearest edge line of a convex counter-clockwise polygon: positive inside, negative outside
/// (exact inside, a lower bound of the true distance outside).
inline float insideDistance(const std::vector<glm::vec2>& p, glm::vec2 q) {
    float d = std::numeric_limits<float>::max();
    for (size_t i = 0, n = p.size(); i < n; ++i) {
        const glm::vec2 e = p[(i + 1) % n] - p[i];
        const float len = glm::length(e);
        if (len <= 0.0f) continue;
        d = std::min(d, glm::dot(perpLeft(e) / len, q - p[i]));
    }
    return d;
}

/// [min, max] of the polygon's vertices projected on `axis`.
inline glm::vec2 projectExtent(const std::vector<glm::vec2>& p, glm::vec2 axis) {
    glm::vec2 r(std::numeric_limits<float>::max(), -std::numeric_limits<float>::max());
    for (const glm::vec2& v : p) {
        const float t = glm::dot(v, axis);
        r = glm::vec2(std::min(r.x, t), std::max(r.y, t));
    }
    return r;
}

/// Keeps the part of a convex polygon where side * (dot(n, x) - offset) >= 0. The edge created along the cut
/// line gets `cutTag`; other edges keep their tags.
inline void clipPolygon(const std::vector<glm::vec2>& poly, const std::vector<std::int32_t>& tags, glm::vec2 n,
                        float offset, float side, std::vector<glm::vec2>& out, std::vector<std::int32_t>& outTags,
                        std::int32_t cutTag) {
    out.clear();
    outTags.clear();
    const size_t count = poly.size();
    for (size_t i = 0; i < count; ++i) {
        const glm::vec2 a = poly[i], b = poly[(i + 1) % count];
        const float fa = side * (glm::dot(n, a) - offset), fb = side * (glm::dot(n, b) - offset);
        const bool ina = fa >= 0.0f, inb = fb >= 0.0f;
        if (ina) {
            out.push_back(a);
            outTags.push_back(tags[i]);
        }
        if (ina != inb) {
            const float t = fa / (fa - fb);
            out.push_back(a + (b - a) * t);
            outTags.push_back(ina ? cutTag : tags[i]);
        }
    }
}

/// Whether the oriented rectangle (centre, unit long axis, half extents along axis / across) lies inside the
/// convex polygon with at least `inset` metres to spare.
inline bool rectInside(const std::vector<glm::vec2>& poly, glm::vec2 centre, glm::vec2 axis, glm::vec2 half,
                       float inset) {
    const glm::vec2 across = perpLeft(axis);
    for (int sx = -1; sx <= 1; sx += 2)
        for (int sy = -1; sy <= 1; sy += 2) {
            const glm::vec2 c = centre + axis * (half.x * float(sx)) + across * (half.y * float(sy));
            if (insideDistance(poly, c) < inset) return false;
        }
    return true;
}

} // namespace seasonview::synth
