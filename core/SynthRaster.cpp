#include "SynthRaster.h"

#include "SynthParallel.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>

namespace seasonview::synth {

void rasterizeGround(const Layout& layout, SceneMaps& maps, int threads) {
    const PixelGrid& g = maps.grid;
    const size_t n = size_t(g.size);
    maps.ground.assign(n * n, 0);
    parallelChunks(g.size, 16, threads, [&](int r0, int r1) {
        for (int r = r0; r < r1; ++r)
            for (int c = 0; c < g.size; ++c)
                maps.ground[size_t(r) * n + size_t(c)] = layout.groundAt(g.centreExt(c + g.margin, r + g.margin));
    });
}

namespace {

struct PixelBox {
    int c0, c1, r0, r1; // inclusive, clamped to the extended grid; empty when c0 > c1 or r0 > r1
};

PixelBox boxOf(const PixelGrid& g, glm::vec2 lo, glm::vec2 hi) {
    const int e = g.extSize();
    const float x0 = (lo.x + g.halfExtent) / g.gsd + float(g.margin), x1 = (hi.x + g.halfExtent) / g.gsd + float(g.margin);
    const float y0 = (g.halfExtent - hi.y) / g.gsd + float(g.margin), y1 = (g.halfExtent - lo.y) / g.gsd + float(g.margin);
    return {std::max(0, int(std::floor(x0)) - 1), std::min(e - 1, int(std::floor(x1)) + 1),
            std::max(0, int(std::floor(y0)) - 1), std::min(e - 1, int(std::floor(y1)) + 1)};
}

// Local-frame bounding box of an oriented layout-space rectangle.
PixelBox rectBox(const Layout& l, const PixelGrid& g, glm::vec2 c, glm::vec2 axis, glm::vec2 half) {
    glm::vec2 lo(1e30f), hi(-1e30f);
    for (int sx = -1; sx <= 1; sx += 2)
        for (int sy = -1; sy <= 1; sy += 2) {
            const glm::vec2 p = l.warp.toLocal(c + axis * (half.x * float(sx)) + perpLeft(axis) * (half.y * float(sy)));
            lo = glm::min(lo, p);
            hi = glm::max(hi, p);
        }
    return boxOf(g, lo - glm::vec2(0.5f), hi + glm::vec2(0.5f));
}

std::uint16_t toCm(float z) { return static_cast<std::uint16_t>(std::clamp(std::lround(z * 100.0f), 1L, 65535L)); }

} // namespace

void rasterizeObjects(const Layout& layout, const Objects& objects, SceneMaps& maps, int threads) {
    const PixelGrid& g = maps.grid;
    const int e = g.extSize();
    const size_t n = size_t(e);
    maps.object.assign(n * n, 0);
    maps.objectZ.assign(n * n, 0);
    maps.firstBuilding = static_cast<std::uint32_t>(objects.trees.size() + 1);
    maps.firstCar = maps.firstBuilding + static_cast<std::uint32_t>(objects.buildings.size());
    maps.endId = maps.firstCar + static_cast<std::uint32_t>(objects.cars.size());

    // Bucket objects by bands of rows so that threads own disjoint rows; within a band objects go in id order.
    constexpr int kBand = 32;
    const int bands = (e + kBand - 1) / kBand;
    std::vector<PixelBox> boxes(maps.endId);
    std::vector<std::vector<std::uint32_t>> inBand(static_cast<size_t>(bands));
    for (std::uint32_t id = 1; id < maps.endId; ++id) {
        PixelBox& b = boxes[id];
        if (maps.isTree(id)) {
            const Tree& t = objects.trees[id - 1];
            b = boxOf(g, t.centre - glm::vec2(t.radius), t.centre + glm::vec2(t.radius));
        } else if (maps.isBuilding(id)) {
            const Building& bd = objects.buildings[id - maps.firstBuilding];
            b = rectBox(layout, g, bd.centre, bd.axis, bd.half);
        } else {
            const Car& c = objects.cars[id - maps.firstCar];
            b = rectBox(layout, g, c.centre, c.axis, glm::vec2(Car::kHalfLength, Car::kHalfWidth));
        }
        if (b.c0 > b.c1 || b.r0 > b.r1) continue;
        for (int k = b.r0 / kBand; k <= b.r1 / kBand; ++k) inBand[size_t(k)].push_back(id);
    }

    parallelChunks(bands, 1, threads, [&](int k0, int k1) {
        for (int k = k0; k < k1; ++k) {
            const int bandR0 = k * kBand, bandR1 = std::min(e, bandR0 + kBand) - 1;
            for (std::uint32_t id : inBand[size_t(k)]) {
                const PixelBox& b = boxes[id];
                for (int r = std::max(b.r0, bandR0); r <= std::min(b.r1, bandR1); ++r)
                    for (int c = b.c0; c <= b.c1; ++c) {
                        const glm::vec2 p = g.centreExt(c, r);
                        float z = -1.0f;
                        if (maps.isTree(id)) {
                            const Tree& t = objects.trees[id - 1];
                            const glm::vec2 d = p - t.centre;
                            const float d2 = glm::dot(d, d);
                            if (d2 < t.radius * t.radius) z = t.surface(d2);
                        } else if (maps.isBuilding(id)) {
                            const Building& bd = objects.buildings[id - maps.firstBuilding];
                            const glm::vec2 d = layout.warp.toLayout(p) - bd.centre;
                            const float u = glm::dot(d, bd.axis), v = glm::dot(d, perpLeft(bd.axis));
                            if (std::abs(u) < bd.half.x && std::abs(v) < bd.half.y) z = bd.roofHeight(u, v);
                        } else {
                            const Car& car = objects.cars[id - maps.firstCar];
                            const glm::vec2 d = layout.warp.toLayout(p) - car.centre;
                            const float u = glm::dot(d, car.axis), v = glm::dot(d, perpLeft(car.axis));
                            if (std::abs(u) < Car::kHalfLength && std::abs(v) < Car::kHalfWidth)
                                z = std::abs(u) < 1.3f ? Car::kHeight : 1.0f; // cabin, bonnet and boot
                        }
                        if (z < 0.0f) continue;
                        const size_t i = size_t(r) * n + size_t(c);
                        const std::uint16_t zc = toCm(z);
                        // Strictly higher wins; ties keep the lower id (processed first).
                        if (maps.object[i] == 0 || zc > maps.objectZ[i]) {
                            maps.object[i] = id;
                            maps.objectZ[i] = zc;
                        }
                    }
            }
        }
    });
}

} // namespace seasonview::synth
