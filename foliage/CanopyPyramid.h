#pragma once
// The derived canopy layer precomputed once per imagery pair and canopy parameters (`seasonview prepare`, the demo;
// `bench --compare canopy-pyramid=off,on` builds it for its parameters): a pyramid in the cache like the imagery's
// (clipmap/ImagePyramid.h: keys, manifest, validation, atomic rename, rebuilt when damaged), one tiled 8-bit TIFF per
// level holding what deriveCanopyTexels() gives for that level of the two seasons' pyramids (a texel's value: how many
// layers it belongs to). The canopy clipmap's loader then reads a byte per texel where its workers would read both
// seasons around each block and derive it on the frame's cores (CanopyClipmapGL.h, CanopyOptions::precomputed): the
// same bytes (CanopyPyramidTest). Ropinski et al. 2007 §4.1-4.2's rule, run before the flight instead of during it.
#include "CanopyDerive.h"
#include "ImagePyramid.h"
#include "Result.h"
#include "Segmentation.h"
#include "SegmentationStats.h"

namespace seasonview {

/// The canopy parameters a precomputed layer is made for (CanopyOptions's params, layers and resolved top k).
struct CanopyPyramidParams {
    SegmentationParams params;
    int layers = 16;
    int topK = 0; // resolved (canopyTopK())
};

/// The top layer's k a canopy of `params` and `requestedTopK` (0 = min(kSegMaxK, 3 k)) uses: odd, in [k, kSegMaxK];
/// 1 for the pixel method.
int canopyTopK(const SegmentationParams& params, int requestedTopK);

/// The recipe of the canopy pyramid of `on` and `off` (the pair's prepared pyramids, no streamed level, the same level
/// sizes; both must outlive it) for `params` and the pair's `stats`. Its identity holds both pyramids' source keys,
/// the method, k, layers, top k and the statistics, so any change makes another pyramid. The builder derives each
/// level in bands of tile rows, tiles in parallel on every core.
PyramidSource canopyPyramidSource(const ImagePyramid& on, const ImagePyramid& off, const CanopyPyramidParams& params,
                                  const SegmentationStats& stats);

} // namespace seasonview
