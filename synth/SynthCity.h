#pragma once
// The synthetic scene's buildings as a textured 3D model: the same footprints, eaves, ridges and roof
// shapes the imagery painter drew from above, extruded from the terrain into an OBJ+MTL city model whose every
// building has its own facade texture — procedural (plaster or brick, window grid, door) or cut from a folder of
// facade photos — made unique by a painted label, as Buchholz's thesis §4.7.1 did with 300 photos for 10,000
// buildings.
#include "Result.h"
#include "SynthObjects.h"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace seasonview::synth {

class Warp;

struct CityWriteOptions {
    std::filesystem::path facadePhotos; // a folder of JPEG/PNG facade photos; empty: procedural facades
    int textureSize = 256;              // facade texture width and height, texels
    int threads = 1;
};

struct CityWriteReport {
    std::size_t buildings = 0, triangles = 0, textures = 0;
    std::uint64_t textureBytes = 0; // compressed files on disk
    std::size_t photos = 0;         // photos in the pool (0: procedural)
};

/// Writes `dir`/city.obj, city.mtl and `dir`/facades/*.jpg for the buildings whose footprint centre lies in the
/// scene ([-half, half]², local metres). Positions: local metres in OBJ's y-up convention (x east, y up, z south);
/// building bases at the lowest terrain height under the footprint (`groundAt(x, y)`, local) minus 0.5 m so no
/// gap shows on slopes. Walls are textured (u runs on around the building, one repetition per facade width, v = 0
/// at the ground and 1 at the eaves); roofs are untextured (the scene's imagery textures them). Deterministic.
/// Files appear atomically (the OBJ last).
Result<CityWriteReport> writeSynthCity(const std::filesystem::path& dir, const std::vector<Building>& buildings,
                                       const Warp& warp, float half,
                                       const std::function<float(float, float)>& groundAt,
                                       const CityWriteOptions& options);

/// The JPEG/PNG photos in `folder`, sorted by name (so each building's choice is deterministic); an error when it is
/// not a folder or holds none.
Result<std::vector<std::filesystem::path>> facadePhotoPool(const std::filesystem::path& folder);

/// A facade texture (RGB, size², rows top-down): the building's own procedural facade or photo, and its label.
std::vector<std::uint8_t> facadeTexture(const Building& b, std::uint32_t label, int size,
                                        const std::vector<std::uint8_t>* photo = nullptr);

} // namespace seasonview::synth
