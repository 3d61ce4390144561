#include "AtlasLayout.h"

#include <glm/geometric.hpp>

#define STB_RECT_PACK_IMPLEMENTATION
#include <stb/stb_rect_pack.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>

namespace seasonview::city {

double projectionFactor(double dmin, double fovXDeg, int screenWidth) {
    return double(screenWidth) / (2.0 * dmin * std::tan(fovXDeg * M_PI / 360.0));
}

double triangleArea(const TexturedTriangle& tri) {
    return 0.5 * glm::length(glm::cross(tri.v[1] - tri.v[0], tri.v[2] - tri.v[0]));
}

WorldScale textureWorldScale(const TexturedTriangle& tri) {
    WorldScale w;
    if (triangleArea(tri) <= 0.0) return w;
    const glm::dvec2 t1 = tri.t[1] - tri.t[0], t2 = tri.t[2] - tri.t[0];
    const double det = t1.x * t2.y - t1.y * t2.x;
    // Scale of the texture coordinates, to judge degeneracy relative to them.
    const double scale = std::max({glm::length(t1), glm::length(t2), glm::length(tri.t[2] - tri.t[1])});
    if (scale <= 0.0) {
        w.singleColour = true; // t0 = t1 = t2: one colour
        return w;
    }
    if (std::abs(det) <= 1e-12 * scale * scale) {
        // Collinear texture coordinates: the stretch of the longest texture-space edge.
        double best = -1.0, stretch = 0.0;
        for (int i = 0; i < 3; ++i) {
            const int j = (i + 1) % 3;
            const double lt = glm::length(tri.t[size_t(j)] - tri.t[size_t(i)]);
            if (lt > best) {
                best = lt;
                stretch = glm::length(tri.v[size_t(j)] - tri.v[size_t(i)]) / lt;
            }
        }
        w.s = w.t = stretch;
        return w;
    }
    // P_T(a, b) = a v1 + b v2, Tex_T(a, b) = a t1 + b t2 (v0 = 0, t0 = 0): s_world = P_T(Tex_T^-1 (1, 0)).
    const glm::dvec3 v1 = tri.v[1] - tri.v[0], v2 = tri.v[2] - tri.v[0];
    const glm::dvec2 ab_s(t2.y / det, -t1.y / det); // Tex_T^-1 (1, 0)
    const glm::dvec2 ab_t(-t2.x / det, t1.x / det); // Tex_T^-1 (0, 1)
    w.s = glm::length(ab_s.x * v1 + ab_s.y * v2);
    w.t = glm::length(ab_t.x * v1 + ab_t.y * v2);
    return w;
}

glm::ivec2 requiredTextureSize(const TexturedTriangle& tri, double fproj) {
    const WorldScale w = textureWorldScale(tri);
    if (w.singleColour) return {1, 1};
    return {std::max(1, int(std::ceil(w.s * fproj - 1e-9))), std::max(1, int(std::ceil(w.t * fproj - 1e-9)))};
}

AtlasArea requiredAtlasArea(const std::vector<const TexturedTriangle*>& tris, double fproj, int border,
                            glm::dvec2 maxTexels) {
    AtlasArea a;
    if (tris.empty()) return a;
    a.texture = tris.front()->texture;
    // Texels per repetition (not rounded yet: rounding each repetition would add up over many of them).
    glm::dvec2 tex(0.0), wanted(0.0);
    glm::dvec2 lo(INFINITY), hi(-INFINITY);
    for (const TexturedTriangle* t : tris) {
        const WorldScale w = textureWorldScale(*t);
        const glm::dvec2 want = glm::dvec2(w.s, w.t) * fproj;
        tex = glm::max(tex, want);
        glm::dvec2 tlo(INFINITY), thi(-INFINITY);
        for (const glm::dvec2& c : t->t) {
            lo = glm::min(lo, c);
            hi = glm::max(hi, c);
            tlo = glm::min(tlo, c);
            thi = glm::max(thi, c);
        }
        // What the view could really use, for capFactor: nothing from a triangle under a pixel at dmin (a sliver's
        // s_world is huge and meaningless), and never more texels across than its longest edge spans in pixels.
        const double area = triangleArea(*t);
        if (area * fproj * fproj >= 1.0) {
            const double edge = std::max({glm::length(t->v[1] - t->v[0]), glm::length(t->v[2] - t->v[1]),
                                          glm::length(t->v[0] - t->v[2])});
            const glm::dvec2 ext = thi - tlo;
            wanted = glm::max(wanted, glm::dvec2(ext.x > 0.0 ? std::min(want.x, edge * fproj / ext.x) : want.x,
                                                 ext.y > 0.0 ? std::min(want.y, edge * fproj / ext.y) : want.y));
        }
    }
    tex = glm::min(tex, maxTexels);
    a.capFactor = std::max({1.0, tex.x > 0.0 ? wanted.x / tex.x : 1.0, tex.y > 0.0 ? wanted.y / tex.y : 1.0});
    // The area's texels for the bounding rectangle's repetitions (at least one texel each way), then the border.
    // Every size a multiple of the border b, so packed areas (and the textures inside their borders) start on
    // multiples of b: the atlas's mips 1..log2(b) average whole b×b blocks of each area. Where the original caps
    // the size (stored at its own resolution), the rectangle also snaps outwards to the original's b-texel grid:
    // each atlas texel is then one original texel (a copy, not a resampling: no half-texel blur), and the atlas's
    // mips average the same blocks as the original's own, so the atlas looks like the original at every level the
    // border protects (§4.5.2's border b = 8 covers mips 1–3).
    const int align = std::max(1, border);
    glm::ivec2 n(0);
    for (int d = 0; d < 2; ++d) {
        const double W = maxTexels[d];
        if (std::isfinite(W) && tex[d] >= W) {
            const double a0 = std::floor(lo[d] * W / align + 1e-9) * align;
            const double a1 = std::max(a0 + align, std::ceil(hi[d] * W / align - 1e-9) * align);
            lo[d] = a0 / W;
            hi[d] = a1 / W;
            n[d] = int(a1 - a0);
        } else {
            const int t = std::max(1, int(std::ceil(tex[d] * (hi[d] - lo[d]) - 1e-9)));
            n[d] = (t + align - 1) / align * align;
        }
    }
    const glm::dvec2 extent = hi - lo;
    const int w = n.x, h = n.y;
    tex = glm::max(tex, glm::dvec2(1.0));
    a.size = {w + 2 * border, h + 2 * border};
    // Grow A_tex about its centre so the border texels show the texture's own neighbourhood. A rectangle of zero
    // extent (one colour, or one line) grows by the texture-space size of `border` texels at the texture's size.
    const glm::dvec2 centre = 0.5 * (lo + hi);
    const glm::dvec2 half(extent.x > 0.0 ? 0.5 * extent.x * double(a.size.x) / double(w) : 0.5 * double(a.size.x) / tex.x,
                          extent.y > 0.0 ? 0.5 * extent.y * double(a.size.y) / double(h) : 0.5 * double(a.size.y) / tex.y);
    a.srcMin = centre - half;
    a.srcMax = centre + half;
    return a;
}

const char* atlasPackerName(AtlasPacker p) {
    switch (p) {
    case AtlasPacker::MaxRects: return "maxrects";
    case AtlasPacker::Skyline: return "skyline";
    }
    return "?";
}

std::optional<AtlasPacker> parseAtlasPacker(const std::string& name) {
    if (name == "maxrects") return AtlasPacker::MaxRects;
    if (name == "skyline") return AtlasPacker::Skyline;
    return std::nullopt;
}

namespace {

struct Rect {
    int x = 0, y = 0, w = 0, h = 0;
    bool contains(const Rect& o) const { return o.x >= x && o.y >= y && o.x + o.w <= x + w && o.y + o.h <= y + h; }
    bool intersects(const Rect& o) const {
        return o.x < x + w && x < o.x + o.w && o.y < y + h && y < o.y + o.h;
    }
};

/// MAXRECTS-BSSF-GLOBAL with rotation (Jylänki 2010, §3.3 and §3.3.1 "best short side fit").
bool packMaxRects(std::vector<AtlasArea>& areas, int atlasSize) {
    std::vector<Rect> free{{0, 0, atlasSize, atlasSize}};
    std::vector<bool> placed(areas.size(), false);
    for (auto& a : areas) a.rotated = false;
    for (std::size_t step = 0; step < areas.size(); ++step) {
        // The best (short side slack, long side slack) over every unplaced area, free rectangle and orientation;
        // ties: the first found (the earlier area, unturned, the earlier free rectangle).
        struct Best {
            int shortSlack = INT32_MAX, longSlack = INT32_MAX;
            std::size_t area = 0;
            Rect at;
            bool rotated = false;
        } best;
        bool found = false;
        for (std::size_t i = 0; i < areas.size(); ++i) {
            if (placed[i]) continue;
            for (int turn = 0; turn < 2; ++turn) {
                const int w = turn ? areas[i].size.y : areas[i].size.x;
                const int h = turn ? areas[i].size.x : areas[i].size.y;
                if (turn && w == h) continue;
                for (const Rect& f : free) {
                    if (w > f.w || h > f.h) continue;
                    const int dx = f.w - w, dy = f.h - h;
                    const int s = std::min(dx, dy), l = std::max(dx, dy);
                    if (found && (s > best.shortSlack || (s == best.shortSlack && l >= best.longSlack))) continue;
                    best = {s, l, i, Rect{f.x, f.y, w, h}, turn == 1};
                    found = true;
                }
            }
        }
        if (!found) return false;
        AtlasArea& a = areas[best.area];
        a.position = {best.at.x, best.at.y};
        a.rotated = best.rotated;
        placed[best.area] = true;
        // Split every free rectangle the placed one overlaps into the (up to four) maximal ones around it, then
        // drop those inside another.
        std::vector<Rect> next;
        next.reserve(free.size() + 8);
        const Rect& p = best.at;
        for (const Rect& f : free) {
            if (!f.intersects(p)) {
                next.push_back(f);
                continue;
            }
            if (p.x > f.x) next.push_back({f.x, f.y, p.x - f.x, f.h});
            if (p.x + p.w < f.x + f.w) next.push_back({p.x + p.w, f.y, f.x + f.w - (p.x + p.w), f.h});
            if (p.y > f.y) next.push_back({f.x, f.y, f.w, p.y - f.y});
            if (p.y + p.h < f.y + f.h) next.push_back({f.x, p.y + p.h, f.w, f.y + f.h - (p.y + p.h)});
        }
        free.clear();
        for (std::size_t i = 0; i < next.size(); ++i) {
            bool inside = false;
            for (std::size_t j = 0; j < next.size() && !inside; ++j)
                if (i != j && next[j].contains(next[i]) && (!next[i].contains(next[j]) || j < i)) inside = true;
            if (!inside) free.push_back(next[i]);
        }
    }
    return true;
}

bool packSkyline(std::vector<AtlasArea>& areas, int atlasSize) {
    std::vector<stbrp_node> nodes(size_t(atlasSize) * 2);
    stbrp_context ctx;
    stbrp_init_target(&ctx, atlasSize, atlasSize, nodes.data(), int(nodes.size()));
    stbrp_setup_heuristic(&ctx, STBRP_HEURISTIC_Skyline_BL_sortHeight);
    std::vector<stbrp_rect> rects(areas.size());
    for (size_t i = 0; i < areas.size(); ++i) {
        rects[i].id = int(i);
        rects[i].w = areas[i].size.x;
        rects[i].h = areas[i].size.y;
        areas[i].rotated = false;
    }
    const bool all = stbrp_pack_rects(&ctx, rects.data(), int(rects.size())) == 1;
    for (const stbrp_rect& r : rects)
        if (r.was_packed) areas[size_t(r.id)].position = {r.x, r.y};
    return all;
}

} // namespace

bool packAtlas(std::vector<AtlasArea>& areas, int atlasSize, double* fill, AtlasPacker packer) {
    double covered = 0.0;
    for (const auto& a : areas) covered += double(a.size.x) * double(a.size.y);
    if (fill) *fill = covered / (double(atlasSize) * double(atlasSize));
    if (covered > double(atlasSize) * double(atlasSize)) return false;
    return packer == AtlasPacker::Skyline ? packSkyline(areas, atlasSize) : packMaxRects(areas, atlasSize);
}

std::array<std::vector<std::uint32_t>, 4> splitPointsByArea(const std::vector<glm::dvec3>& midpoints,
                                                           const std::vector<double>& areas,
                                                           const std::vector<std::uint32_t>& subset) {
    std::array<std::vector<std::uint32_t>, 4> out;
    if (subset.empty()) return out;
    glm::dvec3 lo(INFINITY), hi(-INFINITY);
    for (std::uint32_t i : subset) {
        lo = glm::min(lo, midpoints[i]);
        hi = glm::max(hi, midpoints[i]);
    }
    const glm::dvec3 d = hi - lo;
    std::array<int, 3> axes = {0, 1, 2};
    std::sort(axes.begin(), axes.end(), [&](int a, int b) { return d[a] > d[b]; });
    // Sorted by midpoint along `axis`, cut where the summed area is closest to half (both sides non-empty).
    auto halve = [&](std::vector<std::uint32_t> ids, int axis) {
        std::stable_sort(ids.begin(), ids.end(),
                         [&](std::uint32_t a, std::uint32_t b) { return midpoints[a][axis] < midpoints[b][axis]; });
        double total = 0.0;
        for (std::uint32_t i : ids) total += areas[i];
        size_t cut = ids.size() / 2;
        double acc = 0.0, best = INFINITY;
        for (size_t k = 1; k < ids.size(); ++k) { // first k items
            acc += areas[ids[k - 1]];
            const double e = std::abs(acc - 0.5 * total);
            if (e < best) {
                best = e;
                cut = k;
            }
        }
        if (ids.size() < 2) cut = ids.size();
        return std::pair{std::vector<std::uint32_t>(ids.begin(), ids.begin() + std::ptrdiff_t(cut)),
                         std::vector<std::uint32_t>(ids.begin() + std::ptrdiff_t(cut), ids.end())};
    };
    auto [a, b] = halve(subset, axes[0]);
    auto [a1, a2] = halve(a, axes[1]);
    auto [b1, b2] = halve(b, axes[1]);
    out = {std::move(a1), std::move(a2), std::move(b1), std::move(b2)};
    return out;
}

std::array<std::vector<std::uint32_t>, 4> splitByArea(const std::vector<TexturedTriangle>& tris,
                                                      const std::vector<std::uint32_t>& subset) {
    std::vector<glm::dvec3> mid(tris.size());
    std::vector<double> area(tris.size());
    for (std::uint32_t i : subset) {
        mid[i] = (tris[i].v[0] + tris[i].v[1] + tris[i].v[2]) / 3.0;
        area[i] = triangleArea(tris[i]);
    }
    return splitPointsByArea(mid, area, subset);
}

glm::dvec2 rootAtlasCoord(glm::dvec2 t, const std::vector<int>& path) {
    // Each step down halves the square and offsets it into the child's quadrant (0 bottom-left, 1 bottom-right,
    // 2 top-left, 3 top-right): r = (t + Σ_i q_i 2^(k-i)) / 2^k with q_i = (P_i mod 2, (P_i and 2) / 2).
    glm::dvec2 r = t;
    for (auto it = path.rbegin(); it != path.rend(); ++it) r = (r + glm::dvec2(*it % 2, (*it & 2) / 2)) * 0.5;
    return r;
}

glm::dvec2 levelAtlasCoord(glm::dvec2 root, int level) {
    const glm::dvec2 s = root * std::ldexp(1.0, level);
    return s - glm::floor(s);
}

} // namespace seasonview::city
