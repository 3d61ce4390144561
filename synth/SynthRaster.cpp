#include "SynthRaster.h"

#include "SynthParallel.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cassert>
#include <cmath>

namespace seasonview::synth {

void rasterizeGround(const Layout& layout, const PixelGrid& g, int row0, int rows, std::vector<std::uint32_t>& out,
                     int threads) {
    const size_t n = size_t(g.size);
    out.resize(size_t(rows) * n);
    parallelChunks(rows, 16, threads, [&](int r0, int r1) {
        for (int r = r0; r < r1; ++r)
            for (int c = 0; c < g.size; ++c)
                out[size_t(r) * n + size_t(c)] = layout.groundAt(g.centreExt(c + g.margin, row0 + r + g.margin));
    });
}

namespace {

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

ObjectRasterizer::ObjectRasterizer(const Layout& layout, const Objects& objects, const PixelGrid& grid)
    : m_layout(layout), m_objects(objects), m_grid(grid), m_ids(objects) {
    const int e = grid.extSize();
    m_boxes.resize(m_ids.endId);
    m_slabs.resize(size_t((e + kSlab - 1) / kSlab));
    for (std::uint32_t id = 1; id < m_ids.endId; ++id) {
        PixelBox& b = m_boxes[id];
        if (m_ids.isTree(id)) {
            const Tree& t = objects.trees[id - 1];
            b = boxOf(grid, t.centre - glm::vec2(t.radius), t.centre + glm::vec2(t.radius));
        } else if (m_ids.isBuilding(id)) {
            const Building& bd = objects.buildings[id - m_ids.firstBuilding];
            b = rectBox(layout, grid, bd.centre, bd.axis, bd.half);
        } else {
            const Car& c = objects.cars[id - m_ids.firstCar];
            b = rectBox(layout, grid, c.centre, c.axis, glm::vec2(Car::kHalfLength, Car::kHalfWidth));
        }
        if (b.c0 > b.c1 || b.r0 > b.r1) continue;
        for (int k = b.r0 / kSlab; k <= b.r1 / kSlab; ++k) m_slabs[size_t(k)].push_back(id);
    }
}

void ObjectRasterizer::rasterize(int r0, int r1, ObjectRows& out, int threads) const {
    const PixelGrid& g = m_grid;
    const int e = g.extSize();
    assert(0 <= r0 && r0 < r1 && r1 <= e && "ObjectRasterizer::rasterize(): rows outside the extended grid");
    out.row0 = r0;
    out.rows = r1 - r0;
    out.width = e;
    const size_t n = size_t(out.rows) * size_t(e);
    out.object.assign(n, 0);
    out.objectZ.assign(n, 0);

    // Threads own disjoint slabs (rows); within a slab objects go in id order, so every pixel sees its objects in
    // the same order whatever the band and thread split.
    const int k0 = r0 / kSlab, k1 = (r1 - 1) / kSlab + 1;
    parallelChunks(k1 - k0, 1, threads, [&](int i0, int i1) {
        for (int k = k0 + i0; k < k0 + i1; ++k) {
            const int slabR0 = std::max(k * kSlab, r0), slabR1 = std::min((k + 1) * kSlab, r1) - 1;
            for (std::uint32_t id : m_slabs[size_t(k)]) {
                const PixelBox& b = m_boxes[id];
                for (int r = std::max(b.r0, slabR0); r <= std::min(b.r1, slabR1); ++r)
                    for (int c = b.c0; c <= b.c1; ++c) {
                        const glm::vec2 p = g.centreExt(c, r);
                        float z = -1.0f;
                        if (m_ids.isTree(id)) {
                            const Tree& t = m_objects.trees[id - 1];
                            const glm::vec2 d = p - t.centre;
                            const float d2 = glm::dot(d, d);
                            if (d2 < t.radius * t.radius) z = t.surface(d2);
                        } else if (m_ids.isBuilding(id)) {
                            const Building& bd = m_objects.buildings[id - m_ids.firstBuilding];
                            const glm::vec2 d = m_layout.warp.toLayout(p) - bd.centre;
                            const float u = glm::dot(d, bd.axis), v = glm::dot(d, perpLeft(bd.axis));
                            if (std::abs(u) < bd.half.x && std::abs(v) < bd.half.y) z = bd.roofHeight(u, v);
                        } else {
                            const Car& car = m_objects.cars[id - m_ids.firstCar];
                            const glm::vec2 d = m_layout.warp.toLayout(p) - car.centre;
                            const float u = glm::dot(d, car.axis), v = glm::dot(d, perpLeft(car.axis));
                            if (std::abs(u) < Car::kHalfLength && std::abs(v) < Car::kHalfWidth)
                                z = std::abs(u) < 1.3f ? Car::kHeight : 1.0f; // cabin, bonnet and boot
                        }
                        if (z < 0.0f) continue;
                        const size_t i = out.at(c, r);
                        const std::uint16_t zc = toCm(z);
                        // Strictly higher wins; ties keep the lower id (processed first).
                        if (out.object[i] == 0 || zc > out.objectZ[i]) {
                            out.object[i] = id;
                            out.objectZ[i] = zc;
                        }
                    }
            }
        }
    });
}

} // namespace seasonview::synth
