#include "BlockMap.h"

#include "AtlasTree.h"
#include "AtomicFile.h"
#include "TextureSource.h"

#include <libdeflate.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <thread>

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>

namespace seasonview::city {

namespace {

constexpr int kMaxSize = 4096;
constexpr int kMaxWallTexels = 1024;
// Wall columns a map may have: 1 + the index shares a tile word with the foot (BlockMapPacked::tile).
constexpr int kMaxColumns = (1 << 24) - 2;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kFitPoints = 4; // per side of a part, where a texel's roof is fitted with a plane

// Sides of a texel: the neighbour's offset and the side's outward normal (-x, +x, -y, +y).
constexpr std::array<glm::ivec2, 4> kSides{glm::ivec2(-1, 0), glm::ivec2(1, 0), glm::ivec2(0, -1), glm::ivec2(0, 1)};

// Möller–Trumbore: t along the ray where it meets the triangle, and the barycentric coordinates; false if it misses.
bool rayTriangle(const glm::dvec3& o, const glm::dvec3& d, const std::array<glm::dvec3, 3>& v, double& t,
                 glm::dvec3& bary) {
    const glm::dvec3 e1 = v[1] - v[0], e2 = v[2] - v[0];
    const glm::dvec3 p = glm::cross(d, e2);
    const double det = glm::dot(e1, p);
    if (std::abs(det) < 1e-15) return false;
    const double inv = 1.0 / det;
    const glm::dvec3 s = o - v[0];
    const double u = glm::dot(s, p) * inv;
    if (u < 0.0 || u > 1.0) return false;
    const glm::dvec3 q = glm::cross(s, e1);
    const double w = glm::dot(d, q) * inv;
    if (w < 0.0 || u + w > 1.0) return false;
    t = glm::dot(e2, q) * inv;
    bary = glm::dvec3(1.0 - u - w, u, w);
    return true;
}

// The part of a triangle over the square [lo, hi] (x and y; z interpolated, exact for its plane): Sutherland–Hodgman
// against the square's four sides. Returns the polygon's vertex count (0: none over it).
int clipToSquare(const std::array<glm::dvec3, 3>& tri, glm::dvec2 lo, glm::dvec2 hi, std::array<glm::dvec3, 8>& out) {
    std::array<glm::dvec3, 8> a{}, b{};
    int n = 3;
    for (int i = 0; i < 3; ++i) a[std::size_t(i)] = tri[std::size_t(i)];
    for (int side = 0; side < 4 && n > 0; ++side) {
        const int axis = side / 2;
        const double bound = side % 2 == 0 ? lo[axis] : hi[axis], sign = side % 2 == 0 ? 1.0 : -1.0;
        int m = 0;
        for (int i = 0; i < n; ++i) {
            const glm::dvec3 &p = a[std::size_t(i)], &q = a[std::size_t((i + 1) % n)];
            const double dp = sign * (p[axis] - bound), dq = sign * (q[axis] - bound);
            if (dp >= 0.0) b[std::size_t(m++)] = p;
            if ((dp >= 0.0) != (dq >= 0.0) && m < 8) b[std::size_t(m++)] = p + (q - p) * (dp / (dp - dq));
        }
        n = m;
        a = b;
    }
    out = a;
    return n >= 3 ? n : 0;
}

// The height map's Chebyshev distance field (two raster passes over the 8-neighbourhood), capped at 255.
void distanceField(BlockMap& m) {
    const int n = m.size;
    std::vector<int> d(std::size_t(n) * std::size_t(n));
    const int far = 1 << 20;
    for (std::size_t i = 0; i < d.size(); ++i) d[i] = m.height[i] > 0 ? 0 : far;
    auto at = [&](int x, int y) -> int& { return d[std::size_t(y) * std::size_t(n) + std::size_t(x)]; };
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            int& v = at(x, y);
            if (x > 0) v = std::min(v, at(x - 1, y) + 1);
            if (y > 0) {
                v = std::min(v, at(x, y - 1) + 1);
                if (x > 0) v = std::min(v, at(x - 1, y - 1) + 1);
                if (x + 1 < n) v = std::min(v, at(x + 1, y - 1) + 1);
            }
        }
    for (int y = n - 1; y >= 0; --y)
        for (int x = n - 1; x >= 0; --x) {
            int& v = at(x, y);
            if (x + 1 < n) v = std::min(v, at(x + 1, y) + 1);
            if (y + 1 < n) {
                v = std::min(v, at(x, y + 1) + 1);
                if (x + 1 < n) v = std::min(v, at(x + 1, y + 1) + 1);
                if (x > 0) v = std::min(v, at(x - 1, y + 1) + 1);
            }
        }
    m.distance.resize(d.size());
    for (std::size_t i = 0; i < d.size(); ++i) m.distance[i] = std::uint8_t(std::min(d[i], 255));
}

// The prisms' feet (BlockMap::foot): a boundary texel's, the lowest of the triangles over it and its 8 neighbours
// (`cells` lists per texel indices into `tris`; the wall a prism's side stands for may lie in the next texel, whose
// centre is outside the building) of the buildings whose roofs lie over it (`owners`; all where it names none: a
// neighbour across a street may stand lower down a slope), to the nearest height step (rounded down, the walls would
// stand up to a step below their polygons' where no terrain hides their feet); an inner texel's, the lowest of its
// building neighbours' whose buildings are all its own (two sweeps).
void feet(BlockMap& m, const CityModel& model, const std::vector<std::size_t>& tris,
          const std::vector<std::vector<std::uint32_t>>& cells, const std::vector<std::vector<std::uint32_t>>& owners,
          double step) {
    const int n = m.size;
    m.foot.assign(std::size_t(n) * std::size_t(n), 0);
    auto at = [n](int x, int y) { return std::size_t(y) * std::size_t(n) + std::size_t(x); };
    auto boundary = [&](int x, int y) {
        for (const glm::ivec2 s : kSides) {
            const int nx = x + s.x, ny = y + s.y;
            if (nx < 0 || ny < 0 || nx >= n || ny >= n || m.heightAt(nx, ny) < m.heightAt(x, y)) return true;
        }
        return false;
    };
    // Texel j's buildings all texel i's (either naming none: any two): a texel where another building meets this
    // one does not pass that building's foot on to this one's inner texels.
    auto sameOwners = [&](std::size_t i, std::size_t j) {
        const auto &a = owners[i], &b = owners[j];
        if (a.empty() || b.empty()) return true;
        for (const std::uint32_t o : b)
            if (std::find(a.begin(), a.end(), o) == a.end()) return false;
        return true;
    };
    std::vector<int> inner;
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            if (m.heightAt(x, y) == 0) continue;
            double lowest = m.topAt(x, y);
            const auto& own = owners[at(x, y)];
            for (int ny = std::max(y - 1, 0); ny <= std::min(y + 1, n - 1); ++ny)
                for (int nx = std::max(x - 1, 0); nx <= std::min(x + 1, n - 1); ++nx)
                    for (const std::uint32_t k : cells[at(nx, ny)]) {
                        if (!own.empty() && std::find(own.begin(), own.end(), model.building[tris[k]]) == own.end())
                            continue; // another building's (across a street, standing lower down a slope)
                        const auto& v = model.triangles[tris[k]].v;
                        lowest = std::min({lowest, v[0].z, v[1].z, v[2].z});
                    }
            m.foot[at(x, y)] =
                std::uint16_t(std::clamp(std::round((lowest - m.zBase) / step), 0.0,
                                        double(m.height2At(x, y) > 0 ? std::min(m.heightAt(x, y), m.height2At(x, y))
                                                                     : m.heightAt(x, y))));
            if (!boundary(x, y)) inner.push_back(int(at(x, y)));
        }
    for (int pass = 0; pass < 2; ++pass)
        for (std::size_t j = 0; j < inner.size(); ++j) {
            const int i = inner[pass == 0 ? j : inner.size() - 1 - j], x = i % n, y = i / n;
            for (const glm::ivec2 s : kSides) {
                const int nx = x + s.x, ny = y + s.y; // within the map: an inner texel is not on its edge
                if (m.heightAt(nx, ny) > 0 && sameOwners(std::size_t(i), at(nx, ny)))
                    m.foot[std::size_t(i)] = std::min(m.foot[std::size_t(i)], m.foot[at(nx, ny)]);
            }
        }
}

} // namespace

glm::dvec3 BlockMap::roofNormalAt(int x, int y) const {
    if (roofNormal.empty()) return {0.0, 0.0, 1.0};
    const std::size_t i = (std::size_t(y) * std::size_t(size) + std::size_t(x)) * 2;
    glm::dvec2 n(roofNormal[i], roofNormal[i + 1]);
    n = n / 255.0 * 2.0 - 1.0;
    for (int c = 0; c < 2; ++c)
        if (std::abs(n[c]) < 0.005) n[c] = 0.0; // 0 is not a byte's: 127.5
    return {n, std::sqrt(std::max(1.0 - glm::dot(n, n), 1e-6))};
}

Result<BlockMap> buildBlockMap(const CityModel& model, glm::dvec2 origin, double side, const BlockMapOptions& options,
                               const TriangleColour& colour) {
    std::vector<std::uint32_t> all(model.triangles.size());
    for (std::size_t i = 0; i < all.size(); ++i) all[i] = std::uint32_t(i);
    return buildBlockMap(model, all, origin, side, options, colour);
}

Result<BlockMap> buildBlockMap(const CityModel& model, const std::vector<std::uint32_t>& candidates, glm::dvec2 origin,
                               double side, const BlockMapOptions& options, const TriangleColour& colour) {
    const int n = options.size, W = options.wallTexels;
    if (n < 2 || n > kMaxSize) return Error{"BlockMap: size " + std::to_string(n) + " outside 2.." + std::to_string(kMaxSize)};
    if (W < 1 || W > kMaxWallTexels)
        return Error{"BlockMap: wall texels " + std::to_string(W) + " outside 1.." + std::to_string(kMaxWallTexels)};
    if (!(side > 0.0) || !std::isfinite(side) || !std::isfinite(origin.x) || !std::isfinite(origin.y))
        return Error{"BlockMap: the block's side must be a positive number of metres"};
    BlockMap m;
    m.origin = origin;
    m.size = n;
    m.texel = side / double(n);
    m.wallTexels = W;
    const std::size_t cellsCount = std::size_t(n) * std::size_t(n);
    m.height.assign(cellsCount, 0);
    m.column.assign(cellsCount, 0);

    // The triangles over the block, and per texel those whose box overlaps it.
    std::vector<std::size_t> tris;
    double zLo = kInf, zHi = -kInf;
    std::vector<std::vector<std::uint32_t>> cells(cellsCount);
    auto texelRange = [&](double lo, double hi, double o) {
        return glm::ivec2(std::clamp(int(std::floor((lo - o) / m.texel)), 0, n - 1),
                          std::clamp(int(std::floor((hi - o) / m.texel)), 0, n - 1));
    };
    for (const std::uint32_t i : candidates) {
        const auto& v = model.triangles[i].v;
        const glm::dvec3 lo = glm::min(v[0], glm::min(v[1], v[2])), hi = glm::max(v[0], glm::max(v[1], v[2]));
        if (hi.x < origin.x || hi.y < origin.y || lo.x > origin.x + side || lo.y > origin.y + side) continue;
        const std::uint32_t k = std::uint32_t(tris.size());
        tris.push_back(i);
        zLo = std::min(zLo, lo.z);
        zHi = std::max(zHi, hi.z);
        const glm::ivec2 rx = texelRange(lo.x, hi.x, origin.x), ry = texelRange(lo.y, hi.y, origin.y);
        for (int y = ry.x; y <= ry.y; ++y)
            for (int x = rx.x; x <= rx.y; ++x) cells[std::size_t(y) * std::size_t(n) + std::size_t(x)].push_back(k);
    }
    if (tris.empty()) {
        m.roofNormal.assign(cellsCount * 2, 128);
        distanceField(m);
        return m;
    }
    m.zBase = zLo;
    m.zTop = zHi > zLo ? zHi : zLo + 1.0;
    const double step = (m.zTop - m.zBase) / BlockMap::kHeightSteps;

    // Heights: the highest non-vertical triangle over each texel's centre. Pieces: per texel the box of what each
    // non-vertical triangle covers of it, the area it covers, its highest point and the triangle's normal (the
    // texel's parts, below).
    std::vector<double> top(cellsCount, -kInf);
    std::vector<glm::dvec3> topNormal(cellsCount, glm::dvec3(0.0, 0.0, 1.0));
    struct Piece {
        glm::dvec2 lo, hi; // fractions of the texel
        double top;
        glm::dvec3 normal;
        double area; // fraction of the texel
    };
    std::vector<std::vector<Piece>> pieces(cellsCount);
    // Per texel the buildings whose roofs lie over it (model.building; none where the model has no buildings).
    std::vector<std::vector<std::uint32_t>> owners(cellsCount);
    const bool haveOwners = model.building.size() == model.triangles.size();
    std::array<glm::dvec3, 8> clipped;
    for (std::size_t k = 0; k < tris.size(); ++k) {
        const auto& v = model.triangles[tris[k]].v;
        const glm::dvec3 nrm = glm::cross(v[1] - v[0], v[2] - v[0]);
        const double len = glm::length(nrm);
        if (!(len > 0.0) || std::abs(nrm.z) < 1e-6 * len) continue; // vertical: a wall, no height of its own
        const glm::dvec3 up = (nrm.z < 0.0 ? -nrm : nrm) / len;
        const glm::dvec3 lo = glm::min(v[0], glm::min(v[1], v[2])), hi = glm::max(v[0], glm::max(v[1], v[2]));
        const glm::ivec2 rx = texelRange(lo.x, hi.x, origin.x), ry = texelRange(lo.y, hi.y, origin.y);
        const double det = (v[1].x - v[0].x) * (v[2].y - v[0].y) - (v[2].x - v[0].x) * (v[1].y - v[0].y);
        for (int y = ry.x; y <= ry.y; ++y)
            for (int x = rx.x; x <= rx.y; ++x) {
                const std::size_t i = std::size_t(y) * std::size_t(n) + std::size_t(x);
                const glm::dvec2 cellLo = origin + glm::dvec2(x, y) * m.texel, cellHi = cellLo + m.texel;
                const std::size_t piecesBefore = pieces[i].size();
                if (lo.x >= cellLo.x && lo.y >= cellLo.y && hi.x <= cellHi.x && hi.y <= cellHi.y) {
                    // The whole triangle in the texel (most, in the coarse maps): no clipping.
                    if (std::abs(det) > 2e-9 * m.texel * m.texel)
                        pieces[i].push_back(
                            Piece{(glm::dvec2(lo) - cellLo) / m.texel, (glm::dvec2(hi) - cellLo) / m.texel, hi.z, up,
                                  0.5 * std::abs(det) / (m.texel * m.texel)});
                } else if (const int corners = clipToSquare(v, cellLo, cellHi, clipped); corners > 0) {
                    double area = 0.0;
                    for (int c = 0; c < corners; ++c) {
                        const glm::dvec3 &p = clipped[std::size_t(c)], &q = clipped[std::size_t((c + 1) % corners)];
                        area += p.x * q.y - q.x * p.y;
                    }
                    if (std::abs(area) > 1e-9 * m.texel * m.texel) {
                        Piece piece{glm::dvec2(kInf), glm::dvec2(-kInf), -kInf, up, 0.5 * std::abs(area) / (m.texel * m.texel)};
                        for (int c = 0; c < corners; ++c) {
                            const glm::dvec3& p = clipped[std::size_t(c)];
                            const glm::dvec2 f = (glm::dvec2(p) - cellLo) / m.texel;
                            piece.lo = glm::min(piece.lo, f);
                            piece.hi = glm::max(piece.hi, f);
                            piece.top = std::max(piece.top, p.z);
                        }
                        pieces[i].push_back(piece);
                    }
                }
                if (haveOwners && pieces[i].size() > piecesBefore) {
                    const std::uint32_t b = model.building[tris[k]];
                    if (std::find(owners[i].begin(), owners[i].end(), b) == owners[i].end()) owners[i].push_back(b);
                }
                const double cx = origin.x + (double(x) + 0.5) * m.texel, cy = origin.y + (double(y) + 0.5) * m.texel;
                const double b1 = ((cx - v[0].x) * (v[2].y - v[0].y) - (v[2].x - v[0].x) * (cy - v[0].y)) / det;
                const double b2 = ((v[1].x - v[0].x) * (cy - v[0].y) - (cx - v[0].x) * (v[1].y - v[0].y)) / det;
                const double b0 = 1.0 - b1 - b2;
                const double eps = -1e-12;
                if (b0 < eps || b1 < eps || b2 < eps) continue;
                const double z = b0 * v[0].z + b1 * v[1].z + b2 * v[2].z;
                if (z > top[i]) {
                    top[i] = z;
                    topNormal[i] = up;
                }
            }
    }
    // The parts, in sixteenths of a texel to the nearest: the box of the texel's pieces, or, where they leave an empty
    // strip across it at least a sixteenth wide (the widest, of either axis), two prisms, the boxes of the pieces on
    // either side of it (the taller first). A texel whose centre no roof covers is a building's where a part is at
    // least a sixteenth wide both ways (half of one rounds up). Heights: a single prism over the centre, the
    // centre's; any other part, the highest roof over the part's own centre (else its pieces' highest point, level).
    m.rect.assign(cellsCount, BlockMap::kWholeTexel);
    m.rect2.assign(cellsCount, BlockMap::kWholeTexel);
    m.height2.assign(cellsCount, 0);
    std::vector<double> top2(cellsCount, -kInf);
    struct Part {
        glm::ivec2 lo{16}, hi{0}; // sixteenths (round())
        glm::dvec2 box0{kInf}, box1{-kInf}; // the pieces' box, fractions of the texel
        double area = 0.0;                 // the pieces' area, fraction of the texel
        double top = -kInf;
        glm::dvec3 normal{0.0, 0.0, 1.0}; // the roof's there: top is the height of its plane at `at`
        glm::dvec2 at{0.0};
        bool planar = true; // its pieces all of one plane's orientation
        void add(const Piece& p) {
            planar = planar && (area == 0.0 || glm::length(p.normal - normal) < 1e-6);
            box0 = glm::min(box0, p.lo);
            box1 = glm::max(box1, p.hi);
            area += p.area;
            if (p.top > top) {
                top = p.top;
                normal = p.normal;
            }
        }
        // The box to sixteenths, with the area the pieces cover: its sides inside the texel (where the outline is)
        // move in until the box covers no more than they do, so a building at an angle to the grid, whose pieces are
        // trapezoids, ends halfway along its edge across the texel, not at its outermost point (half the error, and
        // none of the growth); sides on the texel's edges (the building goes on into the neighbour) stay.
        void round() {
            if (!(box0.x <= box1.x && box0.y <= box1.y)) return; // no pieces: empty
            glm::dvec2 b0 = box0, b1 = box1;
            const glm::dvec2 ext = b1 - b0;
            const double boxArea = ext.x * ext.y;
            if (ext.x > 0.0 && ext.y > 0.0 && area < boxArea) {
                constexpr double kEdge = 1e-9;
                std::array<bool, 2> freeLo{}, freeHi{};
                for (int a = 0; a < 2; ++a) {
                    freeLo[std::size_t(a)] = b0[a] > kEdge;
                    freeHi[std::size_t(a)] = b1[a] < 1.0 - kEdge;
                }
                const bool fx = freeLo[0] || freeHi[0], fy = freeLo[1] || freeHi[1];
                glm::dvec2 scale(1.0);
                if (fx && fy) scale = glm::dvec2(std::sqrt(area / boxArea));
                else if (fx) scale.x = area / boxArea;
                else if (fy) scale.y = area / boxArea;
                for (int a = 0; a < 2; ++a) {
                    if (scale[a] >= 1.0) continue;
                    const double e = ext[a] * scale[a];
                    const bool l = freeLo[std::size_t(a)], h = freeHi[std::size_t(a)];
                    if (l && h) {
                        const double c = 0.5 * (b0[a] + b1[a]);
                        b0[a] = c - 0.5 * e;
                        b1[a] = c + 0.5 * e;
                    } else if (l) {
                        b0[a] = b1[a] - e;
                    } else {
                        b1[a] = b0[a] + e;
                    }
                }
            }
            for (int a = 0; a < 2; ++a) {
                lo[a] = int(std::clamp(std::lround(b0[a] * 16.0), 0L, 16L));
                hi[a] = int(std::clamp(std::lround(b1[a] * 16.0), 0L, 16L));
            }
        }
        bool empty() const { return hi.x <= lo.x || hi.y <= lo.y; }
        std::uint16_t packed() const { return std::uint16_t(lo.x | (hi.x - 1) << 4 | lo.y << 8 | (hi.y - 1) << 12); }
    };
    // The height of the highest non-vertical triangle of `over` at the point q (-inf where none is over it), and its
    // normal, facing up.
    auto highestRoofAt = [&](glm::dvec2 q, const std::vector<std::uint32_t>& over, glm::dvec3& normal) {
        double best = -kInf;
        normal = glm::dvec3(0.0, 0.0, 1.0);
        for (const std::uint32_t k : over) {
            const auto& v = model.triangles[tris[k]].v;
            const double det = (v[1].x - v[0].x) * (v[2].y - v[0].y) - (v[2].x - v[0].x) * (v[1].y - v[0].y);
            const glm::dvec3 nrm = glm::cross(v[1] - v[0], v[2] - v[0]);
            if (std::abs(det) < 1e-12 || std::abs(nrm.z) < 1e-6 * glm::length(nrm)) continue; // vertical
            const double b1 = ((q.x - v[0].x) * (v[2].y - v[0].y) - (v[2].x - v[0].x) * (q.y - v[0].y)) / det;
            const double b2 = ((v[1].x - v[0].x) * (q.y - v[0].y) - (q.x - v[0].x) * (v[1].y - v[0].y)) / det;
            if (b1 < -1e-12 || b2 < -1e-12 || 1.0 - b1 - b2 < -1e-12) continue;
            const double z = (1.0 - b1 - b2) * v[0].z + b1 * v[1].z + b2 * v[2].z;
            if (z > best) {
                best = z;
                normal = (nrm.z < 0.0 ? -nrm : nrm) / glm::length(nrm);
            }
        }
        return best;
    };
    // The plane z = a + b · (x − centre) that fits the highest roofs over a part best, least squares over 4 × 4 points
    // of it: its height at the texel's centre and its normal (false where fewer than three points have a roof).
    auto fitRoofPlane = [&](const Part& part, glm::dvec2 cellLo, const std::vector<std::uint32_t>& over, double& z,
                            glm::dvec3& normal) {
        const glm::dvec2 c0 = cellLo + 0.5 * m.texel;
        glm::dmat3 A(0.0);
        glm::dvec3 B(0.0);
        int samples = 0;
        for (int sy = 0; sy < kFitPoints; ++sy)
            for (int sx = 0; sx < kFitPoints; ++sx) {
                const glm::dvec2 f =
                    (glm::dvec2(part.lo) + glm::dvec2(part.hi - part.lo) * (glm::dvec2(sx, sy) + 0.5) / double(kFitPoints)) / 16.0;
                const glm::dvec2 q = cellLo + f * m.texel;
                glm::dvec3 unused;
                const double best = highestRoofAt(q, over, unused);
                if (!(best > -kInf)) continue;
                const glm::dvec3 r(1.0, (q - c0) / m.texel);
                A += glm::outerProduct(r, r);
                B += r * best;
                ++samples;
            }
        if (samples < 3 || std::abs(glm::determinant(A)) < 1e-9) return false;
        const glm::dvec3 x = glm::inverse(A) * B;
        z = x[0];
        normal = glm::normalize(glm::dvec3(-x[1] / m.texel, -x[2] / m.texel, 1.0));
        return true;
    };
    std::vector<std::pair<double, double>> spans;
    for (std::size_t i = 0; i < cellsCount; ++i) {
        if (pieces[i].empty()) continue; // no roof over the texel
        // The widest empty strip across the texel between pieces, of either axis.
        int gapAxis = -1;
        double gapLo = 0.0, gapHi = 0.0;
        for (int a = 0; a < 2; ++a) {
            spans.clear();
            for (const Piece& p : pieces[i]) spans.emplace_back(p.lo[a], p.hi[a]);
            std::sort(spans.begin(), spans.end());
            double reach = spans[0].second;
            for (const auto& [lo, hi] : spans) {
                if (lo - reach > std::max(gapHi - gapLo, 1.0 / 16.0)) {
                    gapAxis = a;
                    gapLo = reach;
                    gapHi = lo;
                }
                reach = std::max(reach, hi);
            }
        }
        Part first, second;
        for (const Piece& p : pieces[i]) (gapAxis >= 0 && p.lo[gapAxis] >= gapHi ? second : first).add(p);
        first.round();
        second.round();
        if (first.empty() && !second.empty()) std::swap(first, second);
        if (second.empty() && top[i] > -kInf) // one prism over the centre: at least the sixteenth around it
            for (int a = 0; a < 2; ++a)
                if (first.hi[a] <= first.lo[a]) first.hi[a] = (first.lo[a] = std::min(first.lo[a], 15)) + 1;
        if (first.empty()) continue; // slivers: under half a sixteenth
        // A part that is not over the centre alone: at the height of the highest roof over its own centre (a sloped
        // roof's part at the eaves is not as high as its highest point), else at its highest point.
        const glm::dvec2 cellLo = origin + glm::dvec2(int(i % std::size_t(n)), int(i / std::size_t(n))) * m.texel;
        for (Part* part : {&first, &second})
            if (!part->empty() && !(part == &first && second.empty() && top[i] > -kInf)) {
                const glm::dvec2 c = cellLo + glm::dvec2(part->lo + part->hi) / 32.0 * m.texel;
                glm::dvec3 bestNormal;
                const double best = highestRoofAt(c, cells[i], bestNormal);
                if (best > -kInf) {
                    part->top = best;
                    part->normal = bestNormal;
                    part->at = c;
                } else {
                    part->normal = glm::dvec3(0.0, 0.0, 1.0); // flat at its highest point
                }
            }
        if (!second.empty() && second.top > first.top) std::swap(first, second);
        if (!(second.empty() && top[i] > -kInf)) { // (one prism over the centre: at the centre's height)
            // The first prism's roof is its plane (BlockMap::roofNormal), its height given at the texel's centre.
            const glm::dvec2 slope = -glm::dvec2(first.normal) / first.normal.z;
            top[i] = first.top + glm::dot(slope, cellLo + 0.5 * m.texel - first.at);
            topNormal[i] = first.normal;
        }
        // On roofs of more than one plane (across a ridge or a hip, a flat roof beside a sloped one) the first prism's
        // roof is the plane that fits them best over its part, not one triangle's continued past the ridge. Measured
        // over CityBlockMapGLTest's eight overviews against the atlas mode: 29.96 -> 30.09 dB (6 × 6 points 30.11).
        if (!first.planar) {
            double z;
            glm::dvec3 nrm;
            if (fitRoofPlane(first, cellLo, cells[i], z, nrm)) {
                top[i] = z;
                topNormal[i] = nrm;
            }
        }
        m.rect[i] = first.packed();
        if (!second.empty()) {
            m.rect2[i] = second.packed();
            top2[i] = second.top;
        }
    }
    m.roofNormal.assign(cellsCount * 2, 128);
    for (std::size_t i = 0; i < cellsCount; ++i)
        for (int c = 0; c < 2; ++c)
            m.roofNormal[i * 2 + std::size_t(c)] =
                std::uint8_t(std::clamp(std::lround((topNormal[i][c] * 0.5 + 0.5) * 255.0), 0L, 255L));
    for (std::size_t i = 0; i < cellsCount; ++i) {
        const auto steps = [&](double z) {
            return std::uint16_t(std::clamp(std::lround((z - m.zBase) / step), 1L, long(BlockMap::kHeightSteps)));
        };
        if (top[i] > -kInf) m.height[i] = steps(top[i]);
        if (top2[i] > -kInf) m.height2[i] = steps(top2[i]);
    }
    distanceField(m);
    feet(m, model, tris, cells, owners, step);

    // Wall columns of the boundary texels (§3.3, Fig. 4): per exposed side, horizontal rays into the texel. A side is
    // hidden up to the neighbour's top where a prism of the neighbour covers all of the texel's prisms along it, else
    // not at all (the walls of a part that ends inside its texel show, and so do those beside a neighbour's part that
    // ends short of the side or covers only some of it). A texel with two prisms has a column too, for the walls on
    // either side of the strip between them.
    struct TexelPrism {
        TexelPart part;
        double top;
    };
    auto prismsAt = [&](int x, int y, std::array<TexelPrism, 2>& out) {
        if (m.heightAt(x, y) == 0) return 0;
        out[0] = {texelPart(m.rectAt(x, y)), m.topAt(x, y)};
        if (m.height2At(x, y) == 0) return 1;
        out[1] = {texelPart(m.rect2At(x, y)), m.top2At(x, y)};
        return 2;
    };
    auto reachesSide = [](const TexelPart& part, int s) {
        return s == 0 ? part.lo.x == 0.0 : s == 1 ? part.hi.x == 1.0 : s == 2 ? part.lo.y == 0.0 : part.hi.y == 1.0;
    };
    // Along side s of texel (x, y): the across-range of its prisms that reach the side (empty: none does).
    auto sideRange = [&](int x, int y, int s) {
        std::array<TexelPrism, 2> own;
        const int count = prismsAt(x, y, own);
        const int acrossAxis = s < 2 ? 1 : 0;
        glm::dvec2 range(1.0, 0.0);
        for (int k = 0; k < count; ++k)
            if (reachesSide(own[std::size_t(k)].part, s)) {
                range.x = std::min(range.x, own[std::size_t(k)].part.lo[acrossAxis]);
                range.y = std::max(range.y, own[std::size_t(k)].part.hi[acrossAxis]);
            }
        return range;
    };
    auto neighbourTop = [&](int x, int y, int s) {
        const int nx = x + kSides[std::size_t(s)].x, ny = y + kSides[std::size_t(s)].y;
        const glm::dvec2 range = sideRange(x, y, s);
        if (nx < 0 || ny < 0 || nx >= n || ny >= n || range.x >= range.y) return m.zBase;
        std::array<TexelPrism, 2> other;
        const int count = prismsAt(nx, ny, other);
        const int acrossAxis = s < 2 ? 1 : 0;
        double hidden = m.zBase;
        for (int k = 0; k < count; ++k) {
            const TexelPrism& p = other[std::size_t(k)];
            if (reachesSide(p.part, s ^ 1) && p.part.lo[acrossAxis] <= range.x && p.part.hi[acrossAxis] >= range.y)
                hidden = std::max(hidden, p.top);
        }
        return hidden;
    };
    std::vector<glm::dvec3> sums;    // per column texel: colour sum of the rays that met walls
    std::vector<int> counts;         // per column texel: rays that met a triangle
    std::vector<int> wallCounts;     // per column texel: of those, rays that met walls (not roofs)
    std::vector<glm::dvec2> metNormal; // per column: the sum of the met walls' horizontal unit normals
    // A triangle that faces up or down by more than about 12° is a roof here (its steps are drawn as roof).
    auto roofLike = [&](std::size_t tri) {
        const auto& v = model.triangles[tri].v;
        const glm::dvec3 nrm = glm::cross(v[1] - v[0], v[2] - v[0]);
        return std::abs(nrm.z) > 0.2 * glm::length(nrm);
    };
    constexpr int kRaysPerSide = 4;
    // Rays from `start` in direction `s` reversed (into the texel), spread over `across` (metres, centred on start),
    // at each column texel's height of the texel's top `ownTop` from `hiddenTo` up, into column `col`.
    auto castRays = [&](int col, glm::dvec2 start, glm::ivec2 s, glm::dvec2 across, double ownTop, double hiddenTo,
                        const std::vector<std::uint32_t>& near, const std::vector<std::uint32_t>& own) {
        const glm::dvec3 dir(-s.x, -s.y, 0.0);
        for (int j = 0; j < W; ++j) {
            const double z = m.zBase + (double(j) + 0.5) / double(W) * (ownTop - m.zBase);
            if (z < hiddenTo) continue; // the neighbour's prism covers this side here
            for (int r = 0; r < kRaysPerSide; ++r) {
                const double a = (double(r) + 0.5) / kRaysPerSide - 0.5;
                const glm::dvec3 o(start + across * a, z);
                double best = 1.5 * m.texel;
                std::size_t bestTri = 0;
                glm::dvec3 bestBary(0.0);
                bool found = false;
                for (const std::uint32_t k : near) {
                    if (!own.empty() && std::find(own.begin(), own.end(), model.building[tris[k]]) == own.end())
                        continue; // another building's (across a street narrower than the ray's start outside)
                    double t;
                    glm::dvec3 b;
                    if (rayTriangle(o, dir, model.triangles[tris[k]].v, t, b) && t >= 0.0 && t < best) {
                        best = t;
                        bestTri = tris[k];
                        bestBary = b;
                        found = true;
                    }
                }
                if (!found) continue;
                const std::size_t at = std::size_t(col) * std::size_t(W) + std::size_t(j);
                ++counts[at];
                if (roofLike(bestTri)) continue;
                sums[at] += colour(bestTri, bestBary);
                ++wallCounts[at];
                // A wall more than 10° off the side takes the column off the grid; else the first puts it on.
                const auto& tv = model.triangles[bestTri].v;
                const glm::dvec3 tn = glm::cross(tv[1] - tv[0], tv[2] - tv[0]);
                const double facing = std::abs(tn.x * double(s.x) + tn.y * double(s.y));
                // The column's normal: the mean of the walls' it met, facing out of the side (a wall at an angle
                // to the grid is shaded as its polygons are, not by the steps its texels make).
                if (const double h = std::hypot(tn.x, tn.y); h > 0.0)
                    metNormal[std::size_t(col)] +=
                        (tn.x * double(s.x) + tn.y * double(s.y) < 0.0 ? -1.0 : 1.0) * glm::dvec2(tn.x, tn.y) / h;
                std::uint8_t& g = m.wallOnGrid[std::size_t(col)];
                g = facing < 0.985 * std::hypot(tn.x, tn.y) ? 0 : g == 2 ? 1 : g;
            }
        }
    };
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            std::array<TexelPrism, 2> own;
            const int prisms = prismsAt(x, y, own);
            if (prisms == 0) continue;
            const double ownTop = m.topAt(x, y);
            glm::dvec3 normal(0.0);
            bool exposed = prisms == 2;
            for (int k = 0; k < 4; ++k)
                if (neighbourTop(x, y, k) < ownTop) {
                    exposed = true;
                    normal += glm::dvec3(kSides[std::size_t(k)], 0.0);
                }
            if (!exposed) continue;
            const int col = m.columns();
            m.column[std::size_t(y) * std::size_t(n) + std::size_t(x)] = std::uint32_t(col + 1);
            m.wallNormal.push_back(glm::length(normal) > 0.0 ? glm::vec3(glm::normalize(normal)) : glm::vec3(0.0f));
            m.wallOnGrid.push_back(2); // no wall met yet
            metNormal.push_back(glm::dvec2(0.0));
            sums.resize(sums.size() + std::size_t(W), glm::dvec3(0.0));
            counts.resize(counts.size() + std::size_t(W), 0);
            wallCounts.resize(wallCounts.size() + std::size_t(W), 0);
            const glm::dvec2 texelLo = origin + glm::dvec2(x, y) * m.texel;
            const std::vector<std::uint32_t>& here = cells[std::size_t(y) * std::size_t(n) + std::size_t(x)];
            const std::vector<std::uint32_t>& texelOwners = owners[std::size_t(y) * std::size_t(n) + std::size_t(x)];
            for (int sideIndex = 0; sideIndex < 4; ++sideIndex) {
                const glm::ivec2 s = kSides[std::size_t(sideIndex)];
                const double nTop = neighbourTop(x, y, sideIndex);
                if (nTop >= ownTop) continue;
                // Looking in across the prisms' width there, from the neighbour's centre line where a prism reaches
                // the side (the steps of a sloped roof lie between the two texels' centres), else from a twentieth
                // of a texel outside it (the walls of a part that ends inside the texel lie in it: the part is where
                // its roofs are, and what is beyond the side may be another building); candidates from both texels'
                // lists.
                const int alongAxis = s.x != 0 ? 0 : 1, acrossAxis = 1 - alongAxis;
                glm::dvec2 range = sideRange(x, y, sideIndex);
                const double outside = range.x < range.y ? 0.5 : 0.05;
                if (range.x >= range.y) { // no prism reaches the side: all of them
                    range = {1.0, 0.0};
                    for (int k = 0; k < prisms; ++k) {
                        range.x = std::min(range.x, own[std::size_t(k)].part.lo[acrossAxis]);
                        range.y = std::max(range.y, own[std::size_t(k)].part.hi[acrossAxis]);
                    }
                }
                glm::dvec2 start = texelLo;
                start[alongAxis] += (s[alongAxis] > 0 ? 1.0 + outside : -outside) * m.texel;
                start[acrossAxis] += 0.5 * (range.x + range.y) * m.texel;
                glm::dvec2 across(0.0);
                across[acrossAxis] = (range.y - range.x) * m.texel;
                std::vector<std::uint32_t> near = here;
                if (x + s.x >= 0 && y + s.y >= 0 && x + s.x < n && y + s.y < n) {
                    const auto& other = cells[std::size_t(y + s.y) * std::size_t(n) + std::size_t(x + s.x)];
                    near.insert(near.end(), other.begin(), other.end());
                }
                castRays(col, start, s, across, ownTop, nTop, near, texelOwners);
            }
            if (prisms == 2) {
                // The walls on either side of the strip between the two prisms, from its middle.
                const TexelPart &a = own[0].part, &b = own[1].part;
                const int axis = a.hi.x <= b.lo.x || b.hi.x <= a.lo.x ? 0 : 1, acrossAxis = 1 - axis;
                const bool aBelow = a.hi[axis] <= b.lo[axis];
                const double middle = aBelow ? 0.5 * (a.hi[axis] + b.lo[axis]) : 0.5 * (b.hi[axis] + a.lo[axis]);
                for (int k = 0; k < 2; ++k) {
                    const TexelPart& p = own[std::size_t(k)].part;
                    const bool below = (k == 0) == aBelow; // the prism lies below the strip along the axis
                    glm::ivec2 s(0);
                    s[axis] = below ? 1 : -1; // its wall faces across the strip
                    glm::dvec2 start = texelLo;
                    start[axis] += middle * m.texel;
                    start[acrossAxis] += 0.5 * (p.lo[acrossAxis] + p.hi[acrossAxis]) * m.texel;
                    glm::dvec2 across(0.0);
                    across[acrossAxis] = (p.hi[acrossAxis] - p.lo[acrossAxis]) * m.texel;
                    castRays(col, start, s, across, ownTop, m.zBase, here, texelOwners);
                }
            }
        }

    for (std::uint8_t& g : m.wallOnGrid) g = g == 1; // a column that met no wall: by its normal
    for (std::size_t c = 0; c < metNormal.size(); ++c) // a column that met no wall keeps its sides' mean
        if (glm::length(metNormal[c]) > 1e-6) m.wallNormal[c] = glm::vec3(glm::normalize(metNormal[c]), 0.0f);
    if (m.columns() > kMaxColumns)
        return Error{"BlockMap: " + std::to_string(m.columns()) + " wall columns, more than " + std::to_string(kMaxColumns)};
    // Column texels no ray saw: the nearest seen one in the column; a column that saw nothing: the block's mean.
    // The colour is the walls' (the nearest texel that saw walls where this one saw only roofs), A the walls' share.
    glm::dvec3 mean(0.0);
    int seen = 0;
    for (std::size_t i = 0; i < sums.size(); ++i)
        if (wallCounts[i] > 0) {
            mean += sums[i] / double(wallCounts[i]);
            ++seen;
        }
    mean = seen > 0 ? mean / double(seen) : glm::dvec3(0.5);
    m.wallRgba.assign(sums.size() * 4, 0);
    auto nearest = [&](std::size_t base, int j, const std::vector<int>& by) -> std::optional<std::size_t> {
        for (int dj = 0; dj < W; ++dj) { // below first at equal distance
            const int below = j - dj, above = j + dj;
            if (below >= 0 && by[base + std::size_t(below)] > 0) return base + std::size_t(below);
            if (above < W && by[base + std::size_t(above)] > 0) return base + std::size_t(above);
        }
        return std::nullopt;
    };
    for (int c = 0; c < m.columns(); ++c) {
        const std::size_t base = std::size_t(c) * std::size_t(W);
        for (int j = 0; j < W; ++j) {
            const auto w = nearest(base, j, wallCounts);
            const glm::dvec3 rgb = w ? sums[*w] / double(wallCounts[*w]) : mean;
            const auto any = nearest(base, j, counts);
            const double wallShare = any ? double(wallCounts[*any]) / double(counts[*any]) : 1.0;
            std::uint8_t* out = &m.wallRgba[(base + std::size_t(j)) * 4];
            for (int ch = 0; ch < 3; ++ch) out[ch] = std::uint8_t(std::clamp(std::lround(rgb[ch] * 255.0), 0L, 255L));
            out[3] = std::uint8_t(std::lround(wallShare * 255.0));
        }
    }
    return m;
}

BlockMapHit traceBlockMap(const BlockMap& m, const glm::dvec3& o, const glm::dvec3& d, bool leap) {
    BlockMapHit hit;
    const int n = m.size;
    if (n <= 0 || (d.x == 0.0 && d.y == 0.0 && d.z == 0.0)) return hit;
    const double side = double(n) * m.texel;
    // The box: [t0, t1] of the ray inside it; the face it enters by (axis, or -1 when it starts inside).
    double t0 = 0.0, t1 = kInf;
    int enterAxis = -1;
    for (int a = 0; a < 3; ++a) {
        const double lo = a < 2 ? m.origin[a] : m.zBase, hi = a < 2 ? m.origin[a] + side : m.zTop;
        if (d[a] == 0.0) {
            if (o[a] < lo || o[a] > hi) return hit;
            continue;
        }
        double ta = (lo - o[a]) / d[a], tb = (hi - o[a]) / d[a];
        if (ta > tb) std::swap(ta, tb);
        if (ta > t0) {
            t0 = ta;
            enterAxis = a;
        }
        t1 = std::min(t1, tb);
    }
    if (t0 > t1) return hit;
    if (enterAxis == 2 && d.z > 0.0) return hit; // from under the block's floor: the terrain is in the way
    auto cellOf = [&](double t, int axis) {
        return std::clamp(int(std::floor((o[axis] + t * d[axis] - m.origin[axis]) / m.texel)), 0, n - 1);
    };
    int cx = cellOf(t0, 0), cy = cellOf(t0, 1);
    // The face the current texel was entered by: 0..3 its -x, +x, -y, +y side, 4 the box's top, -1 none.
    int face = enterAxis == 0 ? (d.x > 0.0 ? 0 : 1) : enterAxis == 1 ? (d.y > 0.0 ? 2 : 3) : enterAxis == 2 ? 4 : -1;
    const int stepX = d.x > 0.0 ? 1 : -1, stepY = d.y > 0.0 ? 1 : -1;
    const double deltaX = d.x != 0.0 ? m.texel / std::abs(d.x) : kInf, deltaY = d.y != 0.0 ? m.texel / std::abs(d.y) : kInf;
    auto nextCrossing = [&](int c, int axis, int stepSign) {
        if (d[axis] == 0.0) return kInf;
        const double boundary = m.origin[axis] + double(c + (stepSign > 0 ? 1 : 0)) * m.texel;
        return (boundary - o[axis]) / d[axis];
    };
    double tCell = t0;
    double nextX = nextCrossing(cx, 0, stepX), nextY = nextCrossing(cy, 1, stepY);
    for (;;) {
        ++hit.texelsVisited;
        const double tOut = std::min({nextX, nextY, t1});
        if (m.heightAt(cx, cy) > 0) {
            const double foot = m.footAt(cx, cy);
            // The ray against each prism's box within the texel: [tEnter, tExit], and the axis of the face it enters
            // by (-1: the face it entered the texel by). A part's sides bound it where they lie inside the texel (a
            // whole texel is bounded by the texel's, where the ray is already). The nearest prism entered counts.
            const int cell[2] = {cx, cy};
            double tEnter = kInf, top = 0.0;
            int axis = -1;
            const int prisms = m.height2At(cx, cy) > 0 ? 2 : 1;
            for (int k = 0; k < prisms; ++k) {
                const double prismTop =
                    k == 0 ? m.topAt(cx, cy) : m.top2At(cx, cy);
                const TexelPart part = texelPart(k == 0 ? m.rectAt(cx, cy) : m.rect2At(cx, cy));
                double enter = tCell, exit = tOut;
                int entryAxis = -1;
                bool miss = false;
                auto slab = [&](int a, bool hasLo, double lo, bool hasHi, double hi) {
                    if (d[a] == 0.0) {
                        miss = miss || (hasLo && o[a] < lo) || (hasHi && o[a] > hi);
                        return;
                    }
                    const bool inc = d[a] > 0.0;
                    if (inc ? hasLo : hasHi) {
                        const double t = ((inc ? lo : hi) - o[a]) / d[a];
                        if (t > enter) {
                            enter = t;
                            entryAxis = a;
                        }
                    }
                    if (inc ? hasHi : hasLo) exit = std::min(exit, ((inc ? hi : lo) - o[a]) / d[a]);
                };
                for (int a = 0; a < 2; ++a)
                    slab(a, part.lo[a] > 0.0, m.origin[a] + (double(cell[a]) + part.lo[a]) * m.texel, part.hi[a] < 1.0,
                         m.origin[a] + (double(cell[a]) + part.hi[a]) * m.texel);
                slab(2, true, foot, false, 0.0);
                if (entryAxis == 2) entryAxis = 3; // up through the foot
                // The top: the roof's plane through prismTop at the texel's centre (the second prism's is level),
                // z <= prismTop + slope · (p - centre); entered through it, a roof (axis 2).
                const glm::dvec2 slope = k == 0 ? m.roofSlopeAt(cx, cy) : glm::dvec2(0.0);
                const glm::dvec2 centre = m.origin + (glm::dvec2(cx, cy) + 0.5) * m.texel;
                const double num = prismTop + glm::dot(slope, glm::dvec2(o) - centre) - o.z;
                const double den = d.z - glm::dot(slope, glm::dvec2(d));
                if (den < 0.0) {
                    if (num / den > enter) {
                        enter = num / den;
                        entryAxis = 2;
                    }
                } else if (den > 0.0) {
                    exit = std::min(exit, num / den);
                } else if (num < 0.0) {
                    miss = true;
                }
                if (!miss && enter <= exit && enter < tEnter) {
                    tEnter = enter;
                    axis = entryAxis;
                    top = prismTop;
                }
            }
            BlockMapHit::Kind kind = BlockMapHit::Kind::None;
            if (tEnter < kInf) {
                // Rising into the prism from below its foot (from under the ground) the ray meets nothing, as one
                // that reaches the block's floor; below its foot it passes under the prism (in the ground there).
                if (axis == 3) {
                    BlockMapHit none;
                    none.texelsVisited = hit.texelsVisited;
                    return none;
                }
                if (axis == 0) face = d.x > 0.0 ? 0 : 1;
                else if (axis == 1) face = d.y > 0.0 ? 2 : 3;
                else if (axis == 2) face = 4; // down through the roof's plane
                kind = face == 4 ? BlockMapHit::Kind::Roof : BlockMapHit::Kind::Wall;
            }
            const double t = tEnter;
            if (kind != BlockMapHit::Kind::None) {
                hit.kind = kind;
                hit.t = t;
                hit.point = o + t * d;
                hit.texel = {cx, cy};
                if (kind == BlockMapHit::Kind::Roof) {
                    hit.normal = {0.0, 0.0, 1.0};
                } else {
                    if (face >= 0 && face < 4) hit.normal = glm::dvec3(kSides[std::size_t(face)], 0.0);
                    hit.column = int(m.column[std::size_t(cy) * std::size_t(n) + std::size_t(cx)]) - 1;
                    hit.v = std::clamp((hit.point.z - m.zBase) / std::max(top - m.zBase, 1e-12), 0.0, 1.0);
                }
                return hit;
            }
        } else if (leap) {
            const int r = int(m.distance[std::size_t(cy) * std::size_t(n) + std::size_t(cx)]) - 1;
            if (r >= 1) {
                // Every texel within r of this one (Chebyshev) is empty: go to where the ray leaves that square.
                const double exitX = d.x != 0.0 ? (m.origin.x + double(cx + (stepX > 0 ? r + 1 : -r)) * m.texel - o.x) / d.x : kInf;
                const double exitY = d.y != 0.0 ? (m.origin.y + double(cy + (stepY > 0 ? r + 1 : -r)) * m.texel - o.y) / d.y : kInf;
                const double tExit = std::min(exitX, exitY);
                if (tExit >= t1) return hit; // leaves the box, or reaches its floor, over empty texels
                const int lox = cx - r, hix = cx + r, loy = cy - r, hiy = cy + r;
                if (exitX <= exitY) {
                    cx = stepX > 0 ? hix + 1 : lox - 1;
                    cy = std::clamp(cellOf(tExit, 1), loy, hiy);
                    face = stepX > 0 ? 0 : 1;
                } else {
                    cy = stepY > 0 ? hiy + 1 : loy - 1;
                    cx = std::clamp(cellOf(tExit, 0), lox, hix);
                    face = stepY > 0 ? 2 : 3;
                }
                if (cx < 0 || cy < 0 || cx >= n || cy >= n) return hit;
                tCell = tExit;
                nextX = nextCrossing(cx, 0, stepX);
                nextY = nextCrossing(cy, 1, stepY);
                continue;
            }
        }
        if (tOut >= t1) return hit; // leaves the box, or reaches its floor
        if (nextX <= nextY) {
            cx += stepX;
            tCell = nextX;
            nextX += deltaX;
            face = stepX > 0 ? 0 : 1;
        } else {
            cy += stepY;
            tCell = nextY;
            nextY += deltaY;
            face = stepY > 0 ? 2 : 3;
        }
        if (cx < 0 || cy < 0 || cx >= n || cy >= n) return hit;
    }
}

namespace {

// Wall colours through an atlas tree's atlases (Buchholz & Döllner 2005; thesis §4.5.4: the atlas of a node at level
// k holds its triangles at fract(root · 2^k)), for the model modelOfTree made of the tree: its tree triangles first,
// tree by tree, in the trees' order. A sample `footprint` metres wide is read from the coarsest node on the
// triangle's path from the root whose atlas texels are no wider (AtlasTraversal draws the coarsest node its view
// allows), trilinearly over `blur` footprints, as the atlas mode's sampler reads it; nullopt where the leaf's atlas is
// coarser (the atlas mode draws the original texture there) or the triangle is not a tree's. The atlases, decoded
// with their mips, through a TextureCache.
class AtlasColours {
public:
    AtlasColours(const AtlasTreeFile& file, std::uint64_t capacityBytes)
        : m_file(file), m_cache([this](int id) { return read(id); }, capacityBytes) {
        std::size_t first = 0;
        int nodes = 0;
        for (const AtlasTreeData& t : file.trees) {
            m_first.push_back(first);
            first += t.vertices.size() / 3;
            m_firstNode.push_back(nodes);
            nodes += int(t.nodes.size());
        }
        m_end = first;
    }
    AtlasColours(const AtlasColours&) = delete; // its cache's reader holds `this`
    AtlasColours& operator=(const AtlasColours&) = delete;
    std::uint64_t reads() const { return m_cache.reads(); }
    std::optional<glm::dvec3> colour(std::size_t tri, const glm::dvec3& b, double footprint, double blur,
                                     std::string& failure) {
        if (tri >= m_end || !(footprint > 0.0)) return std::nullopt;
        int tree = int(m_first.size()) - 1;
        while (tree > 0 && tri < m_first[std::size_t(tree)]) --tree;
        const AtlasTreeData& td = m_file.trees[std::size_t(tree)];
        const std::size_t local = tri - m_first[std::size_t(tree)];
        const TreeVertex* v = &td.vertices[local * 3];
        // Root-atlas texels per metre on this triangle: the square root of its areas' ratio.
        const glm::dvec2 r1 = glm::dvec2(v[1].root - v[0].root), r2 = glm::dvec2(v[2].root - v[0].root);
        const double rootArea = std::abs(r1.x * r2.y - r1.y * r2.x) * double(m_file.info.atlasSize) *
                                double(m_file.info.atlasSize);
        const double area = glm::length(glm::cross(glm::dvec3(v[1].position - v[0].position),
                                                   glm::dvec3(v[2].position - v[0].position)));
        if (!(rootArea > 0.0) || !(area > 0.0)) return std::nullopt;
        const double rootPerMetre = std::sqrt(rootArea / area);
        // The coarsest level whose texels are at most the footprint: 2^k · rootPerMetre ≥ 1 / footprint.
        const int level = std::max(0, int(std::ceil(std::log2(1.0 / (footprint * rootPerMetre)) - 1e-9)));
        int node = 0;
        for (int l = 0; l < level; ++l) {
            const AtlasNode& n = td.nodes[std::size_t(node)];
            if (n.leaf()) return std::nullopt; // even the leaves' atlases are coarser: the original texture
            int next = -1;
            for (int c : n.children)
                if (c >= 0) {
                    const AtlasNode& cn = td.nodes[std::size_t(c)];
                    if (local >= cn.first && local < std::size_t(cn.first) + cn.count) next = c;
                }
            if (next < 0) return std::nullopt;
            node = next;
        }
        auto atlas = m_cache.get(m_firstNode[std::size_t(tree)] + node);
        if (!atlas) {
            if (failure.empty()) failure = atlas.message();
            return glm::dvec3(0.5);
        }
        const double scale = std::ldexp(1.0, level);
        const glm::dvec2 root = b.x * glm::dvec2(v[0].root) + b.y * glm::dvec2(v[1].root) + b.z * glm::dvec2(v[2].root);
        // The node's quadrant of the root atlas from the triangle's centre (fract of a point on its edge could be
        // the neighbouring quadrant's).
        const glm::dvec2 centre = (glm::dvec2(v[0].root) + glm::dvec2(v[1].root) + glm::dvec2(v[2].root)) / 3.0;
        const glm::dvec2 uv = glm::clamp(root * scale - glm::floor(centre * scale), 0.0, 1.0);
        const double texelsPerMetre = scale * rootPerMetre;
        return glm::dvec3((*atlas)->sample(uv, std::max(1.0, blur * footprint * texelsPerMetre))) / 255.0;
    }

private:
    // The atlas of node `id` (the trees' nodes numbered on from one tree to the next), with its mips.
    Result<SourceTexture> read(int id) const {
        int tree = int(m_firstNode.size()) - 1;
        while (tree > 0 && id < m_firstNode[std::size_t(tree)]) --tree;
        auto rgba = m_file.readAtlasRgba(tree, id - m_firstNode[std::size_t(tree)]);
        if (!rgba) return rgba.error();
        SourceTexture t;
        t.repeat = false;
        t.channels = m_file.trees[std::size_t(tree)].alpha ? 4 : 3;
        t.mips.push_back(std::move(*rgba));
        t.sizes.push_back(glm::ivec2(m_file.info.atlasSize));
        addBoxMips(t);
        return t;
    }
    const AtlasTreeFile& m_file;
    TextureCache m_cache;
    std::vector<std::size_t> m_first; // per tree its first triangle in the model
    std::vector<int> m_firstNode;     // per tree the id of its root
    std::size_t m_end = 0;
};

} // namespace

Result<CityBlockMapReport> buildCityBlockMaps(const CityModel& model, const CityBlockMapSettings& s,
                                              const std::filesystem::path& out) {
    if (model.triangles.empty()) return Error{model.source + ": no triangles to build BlockMaps of"};
    if (!(s.leafTexel > 0.0) || !std::isfinite(s.leafTexel)) return Error{"BlockMaps: the leaf texel must be positive"};
    const glm::dvec3 lo = model.boundsMin(), hi = model.boundsMax();
    const double extent = std::max({hi.x - lo.x, hi.y - lo.y, 1e-6});
    // At most kMaxDepth levels below the root (a city wider than 2^kMaxDepth leaves gets wider leaves).
    constexpr int kMaxDepth = 10;
    double leafSide = double(s.map.size) * s.leafTexel;
    int depth = 0;
    while (leafSide * std::ldexp(1.0, depth) < extent && depth < kMaxDepth) ++depth;
    leafSide = std::max(leafSide, extent / std::ldexp(1.0, depth));
    const double rootSide = leafSide * std::ldexp(1.0, depth);
    const glm::dvec2 root(lo.x, lo.y);
    // Triangles per leaf square (by their boxes), so a node gathers its own from its leaves.
    const int leaves = 1 << depth;
    std::vector<std::vector<std::uint32_t>> buckets(std::size_t(leaves) * std::size_t(leaves));
    for (std::size_t i = 0; i < model.triangles.size(); ++i) {
        const auto& v = model.triangles[i].v;
        const glm::dvec3 a = glm::min(v[0], glm::min(v[1], v[2])), b = glm::max(v[0], glm::max(v[1], v[2]));
        const int x0 = std::clamp(int(std::floor((a.x - root.x) / leafSide)), 0, leaves - 1);
        const int x1 = std::clamp(int(std::floor((b.x - root.x) / leafSide)), 0, leaves - 1);
        const int y0 = std::clamp(int(std::floor((a.y - root.y) / leafSide)), 0, leaves - 1);
        const int y1 = std::clamp(int(std::floor((b.y - root.y) / leafSide)), 0, leaves - 1);
        for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x) buckets[std::size_t(y) * std::size_t(leaves) + std::size_t(x)].push_back(std::uint32_t(i));
    }
    TextureCache cache(model.textures, s.cacheBytes);
    // Every map samples a texture at least leafTexel metres per sample: the cache keeps only the mips that can be
    // read (a 512² facade over 16 m seen at 1 m per texel needs its 16² level and coarser), so it holds the whole
    // city's facades and reads each once, on all cores, before the maps are built.
    {
        std::vector<int> finest(model.textures.size(), 1 << 20);
        std::vector<int> used;
        for (const TexturedTriangle& t : model.triangles) {
            if (t.texture < 0 || std::size_t(t.texture) >= model.textures.size()) continue;
            const WorldScale ws = textureWorldScale(t);
            const int width = model.textures[std::size_t(t.texture)].width;
            const double texelsPerMetre = ws.s > 0.0 && width > 0 ? double(width) / ws.s : 1.0;
            const int level = int(std::floor(std::log2(std::max(1.0, s.leafTexel * texelsPerMetre))));
            int& f = finest[std::size_t(t.texture)];
            if (f == 1 << 20) used.push_back(t.texture);
            f = std::min(f, width > 0 ? level : 0);
        }
        for (int& f : finest) f = f == 1 << 20 ? 0 : f;
        cache.setFinestLevels(finest);
        const int threads = int(std::max(1u, std::thread::hardware_concurrency()));
        for (std::size_t first = 0; first < used.size(); first += 256) {
            const std::vector<int> batch(used.begin() + std::ptrdiff_t(first),
                                         used.begin() + std::ptrdiff_t(std::min(used.size(), first + 256)));
            if (auto st = cache.prefetch(batch, threads); !st) return st.error();
            if (s.progress) s.progress(0.5 * double(first + batch.size()) / double(used.size()), "textures");
        }
    }
    std::string failure;
    double nodeTexel = 1.0; // metres per texel of the map being built
    std::optional<AtlasColours> atlases;
    if (s.atlasTree) atlases.emplace(*s.atlasTree, s.cacheBytes / 2);
    const TriangleColour colour = [&](std::size_t tri, const glm::dvec3& b) -> glm::dvec3 {
        const TexturedTriangle& t = model.triangles[tri];
        if (t.texture < 0) return glm::dvec3(0.72, 0.70, 0.66); // CityRendererGL's plain colour
        // From the node the atlas mode draws where a pixel covers √2 of the map's texels (one to two where the map is
        // drawn, below), filtered over 1.7 times that: the atlas mode's sampler (trilinear between two of the atlas's
        // mips, its level from the longer of a pixel's derivatives on walls seen at an angle) blurs them more than a
        // box of the pixel does. Measured against the atlas mode (CityBlockMapGLTest: the eight overviews together,
        // and above the street at the switch distance): filtered over √2 texels 29.64 / 42.6 dB, 1.7 · √2 29.96 /
        // 42.0, 2√2 29.97 / 41.6, 4√2 29.78 / 40.4 (the originals over √2: 29.70 / 42.0).
        if (atlases)
            if (auto c = atlases->colour(tri, b, std::sqrt(2.0) * nodeTexel, 1.7, failure)) return *c;
        auto tex = cache.get(t.texture);
        if (!tex) {
            if (failure.empty()) failure = tex.message();
            return glm::dvec3(0.5);
        }
        const glm::dvec2 uv = b.x * t.t[0] + b.y * t.t[1] + b.z * t.t[2];
        const WorldScale ws = textureWorldScale(t);
        const double texelsPerMetre = ws.s > 0.0 ? double((*tex)->sizes[0].x) / ws.s : 1.0;
        // The texture's texels under one sample: what a pixel covers where the map is drawn. A map is drawn where
        // its texel covers at most a pixel and its parent's more (BlockMapTraversal), so a pixel covers one to two of
        // its texels: √2, their geometric middle (one texel blurs less than the polygons' mipmaps do at an overview;
        // two, more than they do at the switch distance).
        const glm::vec4 c = (*tex)->sample(uv, std::max(1.0, std::sqrt(2.0) * nodeTexel * texelsPerMetre));
        return glm::dvec3(c) / 255.0;
    };
    std::size_t total = 0;
    for (int l = 0; l <= depth; ++l) total += std::size_t(1) << (2 * l);
    auto writer = BlockMapWriter::open(out);
    if (!writer) return writer.error();
    CityBlockMapReport report;
    std::vector<std::uint32_t> mark(model.triangles.size(), 0);
    std::uint32_t stamp = 0;
    std::size_t done = 0;
    for (int l = 0; l <= depth; ++l) {
        const int perSide = 1 << l, span = leaves / perSide; // leaf squares per node side
        const double side = rootSide / double(perSide);
        nodeTexel = side / double(s.map.size);
        const BlockMapOptions mo = s.map;
        for (int j = 0; j < perSide; ++j)
            for (int i = 0; i < perSide; ++i, ++done) {
                std::vector<std::uint32_t> tris;
                ++stamp;
                for (int y = j * span; y < (j + 1) * span; ++y)
                    for (int x = i * span; x < (i + 1) * span; ++x)
                        for (std::uint32_t t : buckets[std::size_t(y) * std::size_t(leaves) + std::size_t(x)])
                            if (mark[t] != stamp) {
                                mark[t] = stamp;
                                tris.push_back(t);
                            }
                if (s.progress) s.progress(0.5 + 0.5 * double(done) / double(total), "BlockMaps");
                if (tris.empty()) continue;
                auto m = buildBlockMap(model, tris, root + glm::dvec2(i, j) * side, side, mo, colour);
                if (!m) return m.error();
                if (!failure.empty()) return Error{failure};
                report.columns += std::size_t(m->columns());
                if (auto st = writer->add(*m); !st) return st.error();
            }
    }
    if (s.progress) s.progress(1.0, "BlockMaps");
    report.maps = writer->count();
    if (auto st = writer->finish(); !st) return st.error();
    report.depth = depth;
    report.rootSide = rootSide;
    std::error_code ec;
    report.fileBytes = std::uint64_t(std::filesystem::file_size(out, ec));
    report.textureReads = cache.reads();
    report.atlasReads = atlases ? atlases->reads() : 0;
    return report;
}

// ---- files ----

namespace {

constexpr char kMagic[8] = {'S', 'V', 'B', 'L', 'O', 'C', 'K', 'M'};
// 2: wall texels RGBA (A: walls' share), per-texel roof normals; 3: prisms' feet, walls on the grid; 4: texels' parts
// and second prisms; 5: heights, feet and second prisms' tops of 16 bits
constexpr std::uint32_t kVersion = 5;
constexpr std::size_t kMapHeaderBytes = 5 * 8 + 3 * 4;

template <typename T> void put(std::vector<std::uint8_t>& out, const T& v) {
    const auto* p = reinterpret_cast<const std::uint8_t*>(&v);
    out.insert(out.end(), p, p + sizeof(T));
}
template <typename T> T get(const std::uint8_t* p) {
    T v;
    std::memcpy(&v, p, sizeof(T));
    return v;
}

std::size_t dataBytes(std::size_t n, std::size_t W, std::size_t columns) {
    return n * n * (2 + 1 + 4 + 2 + 2 + 2 + 2 + 2) + columns * W * 4 + columns * (3 * 4 + 1);
}

std::vector<std::uint8_t> serializeMap(const BlockMap& m) {
    std::vector<std::uint8_t> out;
    for (double v : {m.origin.x, m.origin.y, m.texel, m.zBase, m.zTop}) put(out, v);
    put(out, std::int32_t(m.size));
    put(out, std::int32_t(m.wallTexels));
    put(out, std::int32_t(m.columns()));
    for (std::uint16_t h : m.height) put(out, h);
    out.insert(out.end(), m.distance.begin(), m.distance.end());
    for (std::uint32_t c : m.column) put(out, c);
    out.insert(out.end(), m.roofNormal.begin(), m.roofNormal.end());
    out.insert(out.end(), m.wallRgba.begin(), m.wallRgba.end());
    for (const glm::vec3& nrm : m.wallNormal)
        for (int i = 0; i < 3; ++i) put(out, float(nrm[i]));
    for (std::size_t i = 0; i < m.height.size(); ++i) put(out, m.foot.empty() ? std::uint16_t(0) : m.foot[i]);
    for (int c = 0; c < m.columns(); ++c) put(out, std::uint8_t(m.wallOnGrid.empty() ? 0 : m.wallOnGrid[std::size_t(c)]));
    for (std::size_t i = 0; i < m.height.size(); ++i) put(out, m.rect.empty() ? BlockMap::kWholeTexel : m.rect[i]);
    for (std::size_t i = 0; i < m.height.size(); ++i) put(out, m.rect2.empty() ? BlockMap::kWholeTexel : m.rect2[i]);
    for (std::size_t i = 0; i < m.height.size(); ++i) put(out, m.height2.empty() ? std::uint16_t(0) : m.height2[i]);
    put(out, std::uint32_t(libdeflate_crc32(0, out.data(), out.size())));
    return out;
}

} // namespace

struct BlockMapWriter::File {
    std::ofstream out;
};

Result<BlockMapWriter> BlockMapWriter::open(const std::filesystem::path& path) {
    BlockMapWriter w;
    w.m_path = path;
    w.m_tmp = temporaryPathFor(path);
    w.m_file = std::make_unique<File>();
    w.m_file->out.open(w.m_tmp, std::ios::binary | std::ios::trunc);
    std::vector<std::uint8_t> header(kMagic, kMagic + 8);
    put(header, kVersion);
    put(header, std::uint32_t(0)); // the count, written by finish()
    w.m_file->out.write(reinterpret_cast<const char*>(header.data()), std::streamsize(header.size()));
    if (!w.m_file->out) {
        discardTemporary(w.m_tmp);
        return fileError(path.string(), "cannot write the BlockMap file");
    }
    return w;
}

BlockMapWriter::BlockMapWriter() = default;
BlockMapWriter::BlockMapWriter(BlockMapWriter&&) noexcept = default;
BlockMapWriter& BlockMapWriter::operator=(BlockMapWriter&&) noexcept = default;

BlockMapWriter::~BlockMapWriter() {
    if (m_file && !m_done) {
        m_file->out.close();
        discardTemporary(m_tmp);
    }
}

Status BlockMapWriter::add(const BlockMap& map) {
    const std::vector<std::uint8_t> bytes = serializeMap(map);
    m_file->out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    if (!m_file->out) return fileError(m_path.string(), "cannot write the BlockMap file");
    ++m_count;
    m_bytes += bytes.size();
    return Ok{};
}

Status BlockMapWriter::finish() {
    m_file->out.seekp(12);
    put(m_countBytes, m_count);
    m_file->out.write(reinterpret_cast<const char*>(m_countBytes.data()), 4);
    m_file->out.close();
    if (!m_file->out) {
        discardTemporary(m_tmp);
        m_done = true;
        return fileError(m_path.string(), "cannot write the BlockMap file");
    }
    std::string error;
    m_done = true;
    if (!commitTemporary(m_tmp, m_path, error)) return fileError(m_path.string(), error);
    return Ok{};
}

Status writeBlockMaps(const std::filesystem::path& path, const std::vector<BlockMap>& maps) {
    auto w = BlockMapWriter::open(path);
    if (!w) return w.error();
    for (const BlockMap& m : maps)
        if (auto st = w->add(m); !st) return st;
    return w->finish();
}

int wallSpan(int wallTexels) {
    int span = 0;
    for (int w = std::max(wallTexels, 1);; w = (w + 1) / 2) {
        span += w;
        if (w == 1) break;
    }
    return span;
}

BlockMapPacked packBlockMap(const BlockMap& map) {
    BlockMapPacked p;
    const std::size_t n2 = std::size_t(map.size) * std::size_t(map.size);
    p.tile.resize(n2 * 4);
    for (std::size_t i = 0; i < n2; ++i) {
        std::uint32_t* t = &p.tile[i * 4];
        t[0] = std::uint32_t(map.height[i]) | std::uint32_t(map.roofNormal[i * 2]) << 16 |
               std::uint32_t(map.roofNormal[i * 2 + 1]) << 24;
        t[1] = map.column[i] | std::uint32_t(map.distance[i]) << 24;
        t[2] = std::uint32_t(map.rect.empty() ? BlockMap::kWholeTexel : map.rect[i]) |
               std::uint32_t(map.rect2.empty() ? BlockMap::kWholeTexel : map.rect2[i]) << 16;
        t[3] = std::uint32_t(map.foot.empty() ? 0u : map.foot[i]) |
               std::uint32_t(map.height2.empty() ? 0u : map.height2[i]) << 16;
    }
    const int columns = map.columns(), W = map.wallTexels;
    p.span = wallSpan(W);
    p.words.assign(std::size_t(columns) * std::size_t(1 + p.span), 0u);
    auto rgba = [](const float* f) {
        std::uint32_t w = 0;
        for (int k = 0; k < 4; ++k) w |= std::uint32_t(std::lround(std::clamp(f[k], 0.0f, 255.0f))) << (8 * k);
        return w;
    };
    std::vector<float> level, next;
    for (int c = 0; c < columns; ++c) {
        std::uint32_t normal = 0;
        for (int i = 0; i < 3; ++i)
            normal |= std::uint32_t(std::lround((map.wallNormal[std::size_t(c)][i] * 0.5f + 0.5f) * 255.0f)) << (8 * i);
        if (!map.wallOnGrid.empty() && map.wallOnGrid[std::size_t(c)]) normal |= 1u << 24;
        p.words[std::size_t(c)] = normal;
        std::uint32_t* out = &p.words[std::size_t(columns) + std::size_t(c) * std::size_t(p.span)];
        level.assign(&map.wallRgba[std::size_t(c) * std::size_t(W) * 4], &map.wallRgba[std::size_t(c + 1) * std::size_t(W) * 4]);
        for (int w = W;;) {
            for (int j = 0; j < w; ++j) *out++ = rgba(&level[std::size_t(j) * 4]);
            if (w == 1) break;
            const int half = (w + 1) / 2;
            next.assign(std::size_t(half) * 4, 0.0f);
            for (int j = 0; j < half; ++j)
                for (int k = 0; k < 4; ++k) {
                    const float a = level[std::size_t(2 * j) * 4 + std::size_t(k)];
                    const float e = 2 * j + 1 < w ? level[std::size_t(2 * j + 1) * 4 + std::size_t(k)] : a;
                    next[std::size_t(j) * 4 + std::size_t(k)] = 0.5f * (a + e);
                }
            level.swap(next);
            w = half;
        }
    }
    return p;
}

std::uint64_t BlockMapRecord::gpuBytes() const {
    const auto n = std::uint64_t(size), c = std::uint64_t(columns);
    const std::size_t words = std::size_t(c) * std::size_t(1 + wallSpan(wallTexels));
    return n * n * (4 + 4 + 4 + 4) + std::uint64_t(blockMapPages(words)) * kBlockMapPageWords * 4;
}

namespace {

/// The record header at `h` (kMapHeaderBytes), checked; empty message when it is sound.
std::string parseHeader(const std::uint8_t* h, BlockMapRecord& r) {
    r.origin = {get<double>(h), get<double>(h + 8)};
    r.texel = get<double>(h + 16);
    r.zBase = get<double>(h + 24);
    r.zTop = get<double>(h + 32);
    r.size = get<std::int32_t>(h + 40);
    r.wallTexels = get<std::int32_t>(h + 44);
    r.columns = get<std::int32_t>(h + 48);
    if (r.size < 2 || r.size > kMaxSize || r.wallTexels < 1 || r.wallTexels > kMaxWallTexels || r.columns < 0 ||
        std::int64_t(r.columns) > std::int64_t(r.size) * r.size || r.columns > kMaxColumns || !std::isfinite(r.origin.x) ||
        !std::isfinite(r.origin.y) || !(r.texel > 0.0) || !std::isfinite(r.texel) || !std::isfinite(r.zBase) ||
        !std::isfinite(r.zTop) || !(r.zTop > r.zBase))
        return "impossible header";
    r.bytes = kMapHeaderBytes + dataBytes(std::size_t(r.size), std::size_t(r.wallTexels), std::size_t(r.columns)) + 4;
    return {};
}

} // namespace

Result<BlockMapFile> BlockMapFile::open(const std::filesystem::path& path) {
    const std::string name = path.string();
    std::ifstream f(path, std::ios::binary);
    if (!f) return fileError(name, "cannot open the BlockMap file");
    f.seekg(0, std::ios::end);
    const std::uint64_t fileBytes = std::uint64_t(std::max<std::streamoff>(f.tellg(), 0));
    f.seekg(0);
    std::uint8_t head[16] = {};
    if (fileBytes < 16 || !f.read(reinterpret_cast<char*>(head), 16) || std::memcmp(head, kMagic, 8) != 0)
        return fileError(name, "not a BlockMap file");
    const std::uint32_t version = get<std::uint32_t>(head + 8);
    if (version != kVersion)
        return fileError(name, "BlockMap file version " + std::to_string(version) + ", expected " + std::to_string(kVersion));
    const std::uint32_t count = get<std::uint32_t>(head + 12);
    BlockMapFile out;
    out.m_path = path;
    std::uint64_t at = 16;
    std::uint8_t h[kMapHeaderBytes];
    for (std::uint32_t k = 0; k < count; ++k) {
        const std::string which = "BlockMap " + std::to_string(k) + " of " + std::to_string(count);
        if (fileBytes - at < kMapHeaderBytes) return fileError(name, "truncated (" + which + ")");
        f.seekg(std::streamoff(at));
        if (!f.read(reinterpret_cast<char*>(h), std::streamsize(kMapHeaderBytes)))
            return fileError(name, "cannot read (" + which + ")");
        BlockMapRecord r;
        if (std::string why = parseHeader(h, r); !why.empty()) return fileError(name, "damaged (" + which + ": " + why + ")");
        if (fileBytes - at < r.bytes) return fileError(name, "truncated (" + which + ")");
        r.offset = at;
        at += r.bytes;
        out.m_records.push_back(r);
    }
    if (at != fileBytes) return fileError(name, "damaged (bytes after the last BlockMap)");
    return out;
}

Result<BlockMap> BlockMapFile::read(std::size_t k) const {
    const std::string name = m_path.string();
    if (k >= m_records.size()) return fileError(name, "no BlockMap " + std::to_string(k));
    const BlockMapRecord& r = m_records[k];
    const std::string which = "BlockMap " + std::to_string(k) + " of " + std::to_string(m_records.size());
    std::ifstream f(m_path, std::ios::binary);
    if (!f) return fileError(name, "cannot open the BlockMap file");
    std::vector<std::uint8_t> bytes(r.bytes);
    f.seekg(std::streamoff(r.offset));
    if (!f.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(bytes.size())))
        return fileError(name, "truncated (" + which + ")");
    const std::uint8_t* h = bytes.data();
    BlockMapRecord again;
    if (std::string why = parseHeader(h, again); !why.empty() || again.bytes != r.bytes)
        return fileError(name, "damaged (" + which + ": changed since it was opened)");
    const std::size_t data = std::size_t(r.bytes) - kMapHeaderBytes - 4;
    const std::uint32_t crc = get<std::uint32_t>(h + kMapHeaderBytes + data);
    if (std::uint32_t(libdeflate_crc32(0, h, kMapHeaderBytes + data)) != crc)
        return fileError(name, "damaged (" + which + ": checksum mismatch)");
    BlockMap m;
    m.origin = r.origin;
    m.texel = r.texel;
    m.zBase = r.zBase;
    m.zTop = r.zTop;
    m.size = r.size;
    m.wallTexels = r.wallTexels;
    const std::size_t cells = std::size_t(r.size) * std::size_t(r.size);
    const std::uint8_t* p = h + kMapHeaderBytes;
    const auto words16 = [&](std::vector<std::uint16_t>& v) {
        v.resize(cells);
        for (std::size_t i = 0; i < cells; ++i, p += 2) v[i] = get<std::uint16_t>(p);
    };
    words16(m.height);
    m.distance.assign(p, p + cells);
    p += cells;
    m.column.resize(cells);
    for (std::size_t i = 0; i < cells; ++i, p += 4) {
        m.column[i] = get<std::uint32_t>(p);
        if (m.column[i] > std::uint32_t(r.columns)) return fileError(name, "damaged (" + which + ": a column past the walls)");
    }
    m.roofNormal.assign(p, p + cells * 2);
    p += cells * 2;
    m.wallRgba.assign(p, p + std::size_t(r.columns) * std::size_t(r.wallTexels) * 4);
    p += std::size_t(r.columns) * std::size_t(r.wallTexels) * 4;
    m.wallNormal.resize(std::size_t(r.columns));
    for (auto& nrm : m.wallNormal) {
        nrm = {get<float>(p), get<float>(p + 4), get<float>(p + 8)};
        p += 12;
    }
    words16(m.foot);
    for (std::size_t i = 0; i < cells; ++i)
        if (m.foot[i] > m.height[i]) return fileError(name, "damaged (" + which + ": a foot above its top)");
    m.wallOnGrid.assign(p, p + r.columns);
    p += r.columns;
    for (const std::uint8_t g : m.wallOnGrid)
        if (g > 1) return fileError(name, "damaged (" + which + ": a wall column neither on the grid nor off it)");
    for (auto* parts : {&m.rect, &m.rect2}) {
        parts->resize(cells);
        for (std::size_t i = 0; i < cells; ++i, p += 2) {
            (*parts)[i] = get<std::uint16_t>(p);
            const TexelPart part = texelPart((*parts)[i]);
            if (part.lo.x >= part.hi.x || part.lo.y >= part.hi.y)
                return fileError(name, "damaged (" + which + ": a texel's part turned inside out)");
        }
    }
    words16(m.height2);
    for (std::size_t i = 0; i < cells; ++i)
        if (m.height2[i] > 0 && (m.height[i] == 0 || m.foot[i] > m.height2[i]))
            return fileError(name, "damaged (" + which + ": a second prism on an empty texel or below its foot)");
    return m;
}

Result<std::vector<BlockMap>> readBlockMaps(const std::filesystem::path& path) {
    auto file = BlockMapFile::open(path);
    if (!file) return file.error();
    std::vector<BlockMap> maps;
    for (std::size_t k = 0; k < file->records().size(); ++k) {
        auto m = file->read(k);
        if (!m) return m.error();
        maps.push_back(std::move(*m));
    }
    return maps;
}

Result<BlockMapQuadtree> BlockMapQuadtree::of(const BlockMapFile& file) {
    const std::string name = file.path().string();
    const auto& recs = file.records();
    if (recs.empty()) return fileError(name, "no BlockMaps");
    BlockMapQuadtree q;
    q.origin = recs[0].origin;
    q.rootSide = recs[0].side();
    std::map<std::pair<int, std::pair<int, int>>, std::int32_t> at;
    q.nodes.resize(recs.size());
    for (std::size_t k = 0; k < recs.size(); ++k) {
        const BlockMapRecord& r = recs[k];
        const std::string which = "BlockMap " + std::to_string(k);
        if (r.size != recs[0].size) return fileError(name, which + " is not the root's size");
        const double levelF = std::log2(q.rootSide / r.side());
        const int level = int(std::lround(levelF));
        const double side = q.rootSide / std::ldexp(1.0, level);
        const glm::dvec2 cellF = (r.origin - q.origin) / side;
        const glm::ivec2 cell(int(std::lround(cellF.x)), int(std::lround(cellF.y)));
        const double tol = 1e-6;
        if (level < 0 || level > 30 || std::abs(levelF - level) > tol || std::abs(cellF.x - cell.x) > tol ||
            std::abs(cellF.y - cell.y) > tol || cell.x < 0 || cell.y < 0 || cell.x >= (1 << level) || cell.y >= (1 << level))
            return fileError(name, which + " is not a square of the root's quadtree");
        if (!at.emplace(std::make_pair(level, std::make_pair(cell.x, cell.y)), std::int32_t(k)).second)
            return fileError(name, which + " repeats a square");
        Node& n = q.nodes[k];
        n.level = level;
        n.cell = cell;
        q.depth = std::max(q.depth, level);
        if (level > 0) {
            const auto p = at.find(std::make_pair(level - 1, std::make_pair(cell.x / 2, cell.y / 2)));
            if (p == at.end()) return fileError(name, which + " has no parent map before it");
            n.parent = p->second;
            q.nodes[std::size_t(p->second)].children[std::size_t((cell.x & 1) + 2 * (cell.y & 1))] = std::int32_t(k);
        }
    }
    return q;
}

} // namespace seasonview::city
