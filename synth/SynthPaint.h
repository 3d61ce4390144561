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

/// What one band of imagery rows is painted from. The maps are band-sized; pixel hashes use global pixel indices,
/// so a band's pixels are the same whatever the band split.
struct PaintInput {
    const Layout& layout;
    const Objects& objects;
    const ObjectIds& ids;
    const PixelGrid& grid;
    const Terrain& terrain;
    int row0 = 0, rows = 0;                   // the band: imagery rows [row0, row0 + rows)
    const std::vector<std::uint32_t>& ground; // rows × size: rasterizeGround() of the band
    const ObjectRows& objectRows;             // covers extended rows [row0 + margin, row0 + rows + margin)
    const std::vector<float>& terrainShade;   // terrainShadingRows() for this season's sun, from sample row shadeRow0,
    int shadeRow0 = 0;                        // covering every row Terrain::rowsRead() gives for the band's pixels
    const std::vector<std::uint8_t>& shadow;  // rows × size: this season's ShadowSweep bits of the band
};

/// Paints the band of the season into `rgb` (rows × size × 3 bytes, interleaved, first band row first). Each pixel
/// is a pure function of the inputs and its position, so the result does not depend on `threads` or the band split.
void paintRows(const PaintInput& in, const SeasonLook& look, std::vector<std::uint8_t>& rgb, int threads);

} // namespace seasonview::synth
