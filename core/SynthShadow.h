#pragma once
// Cast shadows of one season: terrain, buildings, cars and crowns on a height field, swept along the sun's azimuth.
#include "SynthObjects.h"
#include "SynthRaster.h"
#include "SynthTerrain.h"

#include <glm/vec3.hpp>

#include <cstdint>
#include <vector>

namespace seasonview::synth {

enum ShadowBits : std::uint8_t {
    kShadowOpaque = 1, // the sun is blocked (terrain, roofs, cars, conifers, leaf-on crowns, leaf-off trunks)
    kShadowWeak = 2,   // the sun ray passes through a leafless crown: thin, weak shadow
};

/// Shadow bits for every imagery pixel (size², row 0 north) in `out`. `towardSun` is the unit vector to the sun
/// (x east, y north, z up) and must lie within 45° of due north or south in azimuth (|x| <= |y|), as for midday
/// survey flights. In leaf-off, deciduous crowns block the sun only at their trunk and cast a weak shadow otherwise;
/// the ground under a leafless crown is what receives light there.
///
/// A sheared sweep: rows are processed away from the sun and every pixel belongs to exactly one ray
/// (ray = column - round(step * k)), so each ray carries its running shadow height with no diffusion, O(pixels).
void castShadows(const SceneMaps& maps, const Objects& objects, const Terrain& terrain, glm::vec3 towardSun,
                 bool leafOn, std::vector<std::uint8_t>& out);

} // namespace seasonview::synth
