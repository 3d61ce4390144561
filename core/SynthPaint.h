#pragma once
// Pixel colours of one season of a synthetic scene: ground materials, shaded crowns (lit side brighter; leafless
// crowns as grey-brown branches over the ground), roofs, cars, cast shadows, terrain shading, then the camera
// (exposure, white balance, haze, flight strips, tone curve, sensor noise).
#include "SynthCamera.h"
#include "SynthLayout.h"
#include "SynthObjects.h"
#include "SynthRaster.h"
#include "SynthTerrain.h"

#include <cstdint>
#include <vector>

namespace seasonview::synth {

struct PaintInput {
    const Layout& layout;
    const Objects& objects;
    const SceneMaps& maps;
    const Terrain& terrain;
    const std::vector<float>& terrainShade;   // per terrain sample, terrainShading() for this season's sun
    const std::vector<std::uint8_t>& shadow;  // per imagery pixel, castShadows() for this season
};

/// Paints the season into `rgb` (size² * 3 bytes, interleaved, row 0 north). Each pixel is a pure function of
/// the inputs and its position, so the result does not depend on `threads`.
void paintSeason(const PaintInput& in, const SeasonLook& look, std::vector<std::uint8_t>& rgb, int threads);

} // namespace seasonview::synth
