#include "SynthShadow.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

namespace seasonview::synth {

void castShadows(const SceneMaps& maps, const Objects& objects, const Terrain& terrain, glm::vec3 sun, bool leafOn,
                 std::vector<std::uint8_t>& out) {
    assert(std::abs(sun.x) <= std::abs(sun.y) + 1e-6f && sun.z > 0.0f &&
           "castShadows(): the sun must be within 45 degrees of north or south in azimuth and above the horizon");
    const PixelGrid& g = maps.grid;
    const int e = g.extSize();
    const size_t ne = size_t(e), ni = size_t(g.size);
    out.assign(ni * ni, 0);

    // Away from the sun, one row at a time: north-south sign, columns per row, height drop per row.
    const int rowStep = sun.y > 0.0f ? 1 : -1;       // sun in the north: shadows fall south (increasing rows)
    const double k = -double(sun.x) / std::abs(double(sun.y));
    const double horiz = std::sqrt(double(sun.x) * sun.x + double(sun.y) * sun.y);
    const double drop = double(g.gsd) * std::sqrt(1.0 + k * k) * double(sun.z) / horiz;
    // Tolerance (metres): one step's drop plus a little keeps curved sunlit surfaces (crowns, slopes) from
    // shadowing themselves in stripes where the integer ray shift rounds.
    const double eps = 0.05 + drop;

    // Ray state, "lifted" by step * drop so that nothing decays per step: a caster of height z seen at step s has
    // lifted height z + s*drop; a point at step t is shadowed when the ray's lifted height exceeds z + t*drop.
    const double none = -std::numeric_limits<double>::max();
    std::vector<double> top(3 * ne, none), weakLo(3 * ne, none), weakHi(3 * ne, none);

    const float tz = float(terrain.halfExtent);
    for (int t = 0; t < e; ++t) {
        const int row = rowStep > 0 ? t : e - 1 - t;
        const long shift = std::lround(double(t) * k);
        const double lift = double(t) * drop;
        const float fy = (tz - g.centreExt(0, row).y) / terrain.spacing - 0.5f;
        const bool interiorRow = row >= g.margin && row < g.margin + g.size;
        for (int col = 0; col < e; ++col) {
            const size_t ray = size_t(long(col) - shift + long(ne));
            const size_t i = size_t(row) * ne + size_t(col);
            const glm::vec2 p = g.centreExt(col, row);
            const double ground = terrain.bilinear(terrain.z, (p.x + tz) / terrain.spacing - 0.5f, fy);
            double surface = ground, caster = ground;
            bool weakCaster = false;
            double wLo = 0.0, wHi = 0.0;
            const std::uint32_t id = maps.object[i];
            if (id != 0) {
                const double objTop = ground + double(maps.objectZ[i]) * 0.01;
                bool opaque = true;
                if (maps.isTree(id)) {
                    const Tree& tr = objects.trees[id - 1];
                    if (!tr.conifer && !leafOn) {
                        // Leafless: the ground shows through and receives the light; the trunk blocks the sun,
                        // the crown volume only dims it.
                        opaque = false;
                        weakCaster = true;
                        wLo = ground + double(tr.crownBase) + lift;
                        wHi = objTop + lift;
                        const float trunk = 0.08f + 0.01f * tr.height; // SynthPaint's trunkRadius()
                        if (glm::length(p - tr.centre) < trunk) caster = ground + 0.6 * double(tr.height);
                    }
                } else if (maps.isCar(id)) {
                    const Car& car = objects.cars[id - maps.firstCar];
                    opaque = (car.seasons & (leafOn ? 1 : 2)) != 0;
                }
                if (opaque) surface = caster = objTop;
            }
            const double s = surface + lift;
            std::uint8_t bits = 0;
            if (top[ray] > s + eps) bits = kShadowOpaque;
            else if (weakHi[ray] >= s && weakLo[ray] <= s) bits = kShadowWeak;
            top[ray] = std::max(top[ray], caster + lift);
            if (weakCaster) {
                if (weakHi[ray] < wLo) {
                    weakLo[ray] = wLo;
                    weakHi[ray] = wHi;
                } else {
                    weakLo[ray] = std::min(weakLo[ray], wLo);
                    weakHi[ray] = std::max(weakHi[ray], wHi);
                }
            }
            if (interiorRow && col >= g.margin && col < g.margin + g.size)
                out[size_t(row - g.margin) * ni + size_t(col - g.margin)] = bits;
        }
    }
}

} // namespace seasonview::synth
