#include "SynthShadow.h"

#include "SynthParallel.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

namespace seasonview::synth {

namespace {

constexpr double kNone = -std::numeric_limits<double>::max();

} // namespace

ShadowSweep::ShadowSweep(const PixelGrid& grid, const ObjectIds& ids, const Objects& objects, const Terrain& terrain,
                         glm::vec3 sun, bool leafOn)
    : m_grid(grid), m_ids(ids), m_objects(objects), m_terrain(terrain), m_leafOn(leafOn) {
    assert(std::abs(sun.x) <= std::abs(sun.y) + 1e-6f && sun.z > 0.0f &&
           "ShadowSweep(): the sun must be within 45 degrees of north or south in azimuth and above the horizon");
    // Away from the sun, one row at a time: north-south sign, columns per row, height drop per row.
    m_rowStep = sun.y > 0.0f ? 1 : -1; // sun in the north: shadows fall south (increasing rows)
    m_k = -double(sun.x) / std::abs(double(sun.y));
    const double horiz = std::sqrt(double(sun.x) * sun.x + double(sun.y) * sun.y);
    m_drop = double(grid.gsd) * std::sqrt(1.0 + m_k * m_k) * double(sun.z) / horiz;
    // Tolerance (metres): one step's drop plus a little keeps curved sunlit surfaces (crowns, slopes) from
    // shadowing themselves in stripes where the integer ray shift rounds.
    m_eps = 0.05 + m_drop;
    // Ray state, "lifted" by step * drop so that nothing decays per step: a caster of height z seen at step s has
    // lifted height z + s*drop; a point at step t is shadowed when the ray's lifted height exceeds z + t*drop.
    const size_t rays = 3 * size_t(grid.extSize());
    m_top.assign(rays, kNone);
    m_weakLo.assign(rays, kNone);
    m_weakHi.assign(rays, kNone);
}

long ShadowSweep::shiftOf(int step) const { return std::lround(double(step) * m_k); }

void ShadowSweep::rayRange(int r0, int r1, size_t& first, size_t& end) const {
    const long ne = m_grid.extSize();
    const long s0 = shiftOf(stepOf(r0)), s1 = shiftOf(stepOf(r1 - 1));
    first = size_t(0 - std::max(s0, s1) + ne);
    end = size_t(ne - 1 - std::min(s0, s1) + ne) + 1;
}

ShadowSweep::Checkpoint ShadowSweep::save(int r0, int r1) const {
    Checkpoint c;
    size_t end = 0;
    rayRange(r0, r1, c.firstRay, end);
    const auto from = std::ptrdiff_t(c.firstRay), to = std::ptrdiff_t(end);
    c.top.assign(m_top.begin() + from, m_top.begin() + to);
    if (!m_leafOn) {
        c.weakLo.assign(m_weakLo.begin() + from, m_weakLo.begin() + to);
        c.weakHi.assign(m_weakHi.begin() + from, m_weakHi.begin() + to);
    }
    return c;
}

void ShadowSweep::restore(const Checkpoint& c) {
    std::copy(c.top.begin(), c.top.end(), m_top.begin() + std::ptrdiff_t(c.firstRay));
    std::copy(c.weakLo.begin(), c.weakLo.end(), m_weakLo.begin() + std::ptrdiff_t(c.firstRay));
    std::copy(c.weakHi.begin(), c.weakHi.end(), m_weakHi.begin() + std::ptrdiff_t(c.firstRay));
}

void ShadowSweep::sweep(const ObjectRows& rows, std::uint8_t* bits, int threads) {
    const PixelGrid& g = m_grid;
    const int e = g.extSize();
    const long ne = e;
    const size_t ni = size_t(g.size);
    const Terrain& terrain = m_terrain;
    const float tz = float(terrain.halfExtent);
    size_t firstRay = 0, endRay = 0;
    rayRange(rows.row0, rows.row0 + rows.rows, firstRay, endRay);

    // Threads own disjoint ranges of rays and walk all rows in sweep order: every ray sees the same updates in the
    // same order as in a one-threaded sweep.
    parallelChunks(int(endRay - firstRay), 2048, threads, [&](int a, int b) {
        const long rayLo = long(firstRay) + a, rayHi = long(firstRay) + b; // [rayLo, rayHi)
        for (int i = 0; i < rows.rows; ++i) {
            const int row = m_rowStep > 0 ? rows.row0 + i : rows.row0 + rows.rows - 1 - i;
            const int t = stepOf(row);
            const long shift = shiftOf(t);
            const double lift = double(t) * m_drop;
            const float fy = (tz - g.centreExt(0, row).y) / terrain.spacing - 0.5f;
            const int c0 = int(std::max(0L, rayLo + shift - ne)), c1 = int(std::min(ne, rayHi + shift - ne));
            for (int col = c0; col < c1; ++col) {
                const size_t ray = size_t(long(col) - shift + ne);
                const size_t i0 = rows.at(col, row);
                const glm::vec2 p = g.centreExt(col, row);
                const double ground = terrain.bilinear(terrain.z, (p.x + tz) / terrain.spacing - 0.5f, fy);
                double surface = ground, caster = ground;
                bool weakCaster = false;
                double wLo = 0.0, wHi = 0.0;
                const std::uint32_t id = rows.object[i0];
                if (id != 0) {
                    const double objTop = ground + double(rows.objectZ[i0]) * 0.01;
                    bool opaque = true;
                    if (m_ids.isTree(id)) {
                        const Tree& tr = m_objects.trees[id - 1];
                        if (!tr.conifer && !m_leafOn) {
                            // Leafless: the ground shows through and receives the light; the trunk blocks the sun,
                            // the crown volume only dims it.
                            opaque = false;
                            weakCaster = true;
                            wLo = ground + double(tr.crownBase) + lift;
                            wHi = objTop + lift;
                            const float trunk = 0.08f + 0.01f * tr.height; // SynthPaint's trunkRadius()
                            if (glm::length(p - tr.centre) < trunk) caster = ground + 0.6 * double(tr.height);
                        }
                    } else if (m_ids.isCar(id)) {
                        const Car& car = m_objects.cars[id - m_ids.firstCar];
                        opaque = (car.seasons & (m_leafOn ? 1 : 2)) != 0;
                    }
                    if (opaque) surface = caster = objTop;
                }
                const double s = surface + lift;
                std::uint8_t out = 0;
                if (m_top[ray] > s + m_eps) out = kShadowOpaque;
                else if (m_weakHi[ray] >= s && m_weakLo[ray] <= s) out = kShadowWeak;
                m_top[ray] = std::max(m_top[ray], caster + lift);
                if (weakCaster) {
                    if (m_weakHi[ray] < wLo) {
                        m_weakLo[ray] = wLo;
                        m_weakHi[ray] = wHi;
                    } else {
                        m_weakLo[ray] = std::min(m_weakLo[ray], wLo);
                        m_weakHi[ray] = std::max(m_weakHi[ray], wHi);
                    }
                }
                if (bits && col >= g.margin && col < g.margin + g.size)
                    bits[size_t(row - rows.row0) * ni + size_t(col - g.margin)] = out;
            }
        }
    });
}

} // namespace seasonview::synth
