#pragma once
// The trunks' crown search on the CPU (foliage/TrunksGL.h when the canopy layer is derived on the CPU): what
// shaders/trunk_find.comp computes over one toroidal clip level of the derived canopy layer, with the same arithmetic
// and the same treatment of texels not derived yet, so both find the same centres (TrunksGLTest). Plain C++: TrunksGL
// runs it on a worker thread over a copy of the level, so no frame waits for a search (Ropinski et al. 2007 Fig. 6c).
#include "ToroidalWindow.h"

#include <glm/vec4.hpp>

#include <cstdint>
#include <vector>

namespace seasonview {

/// One clip level of the canopy layer as the GPU holds it: N×N values stored toroidally (texel q at q mod N), valid
/// per block through its slot's tag (ClipmapSchedule::tagOf), and the level's window.
struct CrownSearchLevel {
    int size = 0;                       // N
    int block = 64;                     // texels per block side (divides N)
    int level = 0;                      // the clip level (centres are returned in level-0 texels)
    TexelRect window;                   // the level's window (N × N level texels)
    std::vector<std::uint8_t> values;   // N × N
    std::vector<std::int32_t> tags;     // (N / block)² slots, row-major: the block derived there
};

/// Crown centres of the window: maxima of each canopy texel's Euclidean distance to the nearest texel outside the
/// canopy (value 0; clamped at maxRadius texels), each the largest within 0.75 × its distance (ties: the first in
/// row order) and at least minRadius texels (the distance less half a texel); where a texel not derived yet could be
/// nearer or larger, no decision (as the GPU). Each as (level-0 texel x, y of its centre, crown radius in level-0
/// texels, canopy value), in row order of the window.
std::vector<glm::vec4> findCrownCentres(const CrownSearchLevel& level, float minRadius, int maxRadius);

} // namespace seasonview
