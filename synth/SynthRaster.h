#pragma once
// Rasterised class maps of a synthetic scene, computed band by band and shared by both seasons: the ground record
// under every imagery pixel, and the topmost object (tree crown, roof, car) with its surface height on the imagery
// grid extended by a margin, so that objects outside the scene still cast their shadows into it. Objects are
// bucketed once by the rows they touch, so a band finds its objects without looking at the others.
#include "SynthLayout.h"
#include "SynthObjects.h"

#include <glm/vec2.hpp>

#include <cstdint>
#include <vector>

namespace seasonview::synth {

/// The imagery grid (pixel-is-area, row 0 north) and its margin.
struct PixelGrid {
    int size = 0;            // imagery pixels per side
    int margin = 0;          // extra pixels on every side of the object maps
    float gsd = 0.25f;       // metres per pixel
    float halfExtent = 0.0f; // the imagery covers [-halfExtent, halfExtent]² of the local frame

    int extSize() const { return size + 2 * margin; }
    /// Local-frame centre of pixel (col, row) of the extended grid (0 <= col, row < extSize()).
    glm::vec2 centreExt(int col, int row) const {
        return glm::vec2(-halfExtent + (float(col - margin) + 0.5f) * gsd, halfExtent - (float(row - margin) + 0.5f) * gsd);
    }
};

/// Object ids: 0 none, 1..trees = tree index + 1, then buildings, then cars.
struct ObjectIds {
    std::uint32_t firstBuilding = 0, firstCar = 0, endId = 0;

    ObjectIds() = default;
    explicit ObjectIds(const Objects& o)
        : firstBuilding(static_cast<std::uint32_t>(o.trees.size() + 1)),
          firstCar(firstBuilding + static_cast<std::uint32_t>(o.buildings.size())),
          endId(firstCar + static_cast<std::uint32_t>(o.cars.size())) {}
    bool isTree(std::uint32_t id) const { return id > 0 && id < firstBuilding; }
    bool isBuilding(std::uint32_t id) const { return id >= firstBuilding && id < firstCar; }
    bool isCar(std::uint32_t id) const { return id >= firstCar && id < endId; }
};

/// Rows [row0, row0 + rows) of the extended grid, every column of it: what covers each pixel.
struct ObjectRows {
    int row0 = 0, rows = 0, width = 0;   // width = PixelGrid::extSize()
    std::vector<std::uint32_t> object;   // rows × width: topmost object id
    std::vector<std::uint16_t> objectZ;  // rows × width: its surface height above the ground, centimetres

    /// Index of extended pixel (col, row); row0 <= row < row0 + rows.
    size_t at(int col, int row) const { return size_t(row - row0) * size_t(width) + size_t(col); }
};

/// Pixels of the extended grid an object may cover: columns c0..c1, rows r0..r1 (inclusive, clamped to the grid;
/// empty when c0 > c1 or r0 > r1).
struct PixelBox {
    int c0, c1, r0, r1;
};

/// The objects of a scene bucketed by the 32-row slabs of the extended grid their pixel boxes touch.
class ObjectRasterizer {
public:
    /// Keeps references to `layout` and `objects`, which must outlive it.
    ObjectRasterizer(const Layout& layout, const Objects& objects, const PixelGrid& grid);

    const ObjectIds& ids() const { return m_ids; }

    /// Fills `out` with extended rows [r0, r1) (0 <= r0 < r1 <= extSize()). Where objects overlap, the higher
    /// surface wins (ties: the lower id), so truth masks and pixels agree. Cars are rasterised whatever their
    /// seasons. Each pixel is a pure function of the objects and its position: the result does not depend on
    /// `threads` or on how the grid is split into bands.
    void rasterize(int r0, int r1, ObjectRows& out, int threads) const;

private:
    static constexpr int kSlab = 32;

    const Layout& m_layout;
    const Objects& m_objects;
    PixelGrid m_grid;
    ObjectIds m_ids;
    std::vector<PixelBox> m_boxes;                  // per id
    std::vector<std::vector<std::uint32_t>> m_slabs; // per slab: ids touching it, ascending
};

/// Ground record index per imagery pixel of imagery rows [row0, row0 + rows) into `out` (rows × grid.size).
void rasterizeGround(const Layout& layout, const PixelGrid& grid, int row0, int rows, std::vector<std::uint32_t>& out,
                     int threads);

} // namespace seasonview::synth
