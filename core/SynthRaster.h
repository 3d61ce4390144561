#pragma once
// Rasterised class maps of a synthetic scene, computed once and shared by both seasons: the ground record under
// every imagery pixel, and the topmost object (tree crown, roof, car) with its surface height on the imagery grid
// extended by a margin, so that objects outside the scene still cast their shadows into it.
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

/// What covers each pixel. Object ids: 0 none, 1..trees = tree index + 1, then buildings, then cars.
/// Where crowns overlap, the higher surface wins (ties: the lower id), so truth masks and pixels agree.
struct SceneMaps {
    PixelGrid grid;
    std::vector<std::uint32_t> ground;   // size²: ground record index per imagery pixel
    std::vector<std::uint32_t> object;   // extSize²: topmost object id
    std::vector<std::uint16_t> objectZ;  // extSize²: its surface height above the ground, centimetres
    std::uint32_t firstBuilding = 0, firstCar = 0, endId = 0;

    bool isTree(std::uint32_t id) const { return id > 0 && id < firstBuilding; }
    bool isBuilding(std::uint32_t id) const { return id >= firstBuilding && id < firstCar; }
    bool isCar(std::uint32_t id) const { return id >= firstCar && id < endId; }
};

/// Fills maps.ground (maps.grid must be set).
void rasterizeGround(const Layout& layout, SceneMaps& maps, int threads);
/// Fills maps.object and maps.objectZ (maps.grid must be set). Cars are rasterised whatever their seasons.
void rasterizeObjects(const Layout& layout, const Objects& objects, SceneMaps& maps, int threads);

} // namespace seasonview::synth
