#pragma once
// The elevation clipmap's source (Asirvatham & Hoppe 2005 §2.2, "the clipmap pyramid"): the DEM resampled once onto
// a regular grid of the scene's local metric frame, whatever the DEM's own CRS (EPSG:4326 or UTM), then decimated
// by taking every other sample, so a coarser level's samples coincide with the finer level's even samples, as the
// nested geometry grids require. Stored like the imagery: one tiled float TIFF per level in the pyramid cache,
// streamed into an R32F ClipmapGL by the same schedule and loader.
#include "ImagePyramid.h"
#include "Scene.h"

#include <glm/vec2.hpp>

namespace seasonview {

/// The level-0 elevation grid in the local frame. Sample (i, j) sits at origin + (i·spacing, −j·spacing) (i east,
/// j south, like image pixels); level l's sample (i, j) is level 0's (i·2^l, j·2^l).
struct ElevationGrid {
    double spacing = 1.0;   // metres
    glm::dvec2 origin{0.0}; // local position of sample (0, 0): the grid's north-west corner
    int width = 0, height = 0;

    glm::dvec2 samplePosition(double i, double j) const { return {origin.x + i * spacing, origin.y - j * spacing}; }
    /// Fractional level-0 sample coordinates of a local point.
    glm::dvec2 sampleCoords(glm::dvec2 local) const {
        return {(local.x - origin.x) / spacing, (origin.y - local.y) / spacing};
    }
};

/// The grid of `scene` over the imagery extent plus two DEM samples of margin, from its north-west corner: a UTM DEM
/// in the frame's zone at its own spacing; other DEMs (EPSG:4326, other zones) at half their finest spacing in
/// local metres (at most 16384 samples per side). A flat scene (no DEM) gets a grid for the
/// geometry alone: spacing max(gsd, extent / 2048).
ElevationGrid elevationGrid(const Scene& scene);

/// The recipe of the elevation pyramid (cache key: DEM file, its size and mtime, the grid). Needs scene.elevation.
/// The builder resamples the DEM's triangulated surface (Heightfield::sampleCrsTriangulated, the surface of the
/// reference mesh; holes were filled when it was loaded) and writes every level.
PyramidSource elevationPyramidSource(const Scene& scene, const ElevationGrid& grid);

/// Level-0 heights of `grid` from the scene's DEM (row 0 north, its triangulated surface), CRS positions exact every 16 samples and
/// interpolated in between (GeographicLib per sample would dominate on large grids; the error is far below a
/// millimetre at 16 samples).
std::vector<float> resampleElevation(const Scene& scene, const ElevationGrid& grid);

} // namespace seasonview
