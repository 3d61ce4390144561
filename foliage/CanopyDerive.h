#pragma once
// The derived canopy layer's rule block by block on the CPU (foliage/CanopyClipmapGL.h, `--canopy-derive cpu`): what
// shaders/canopy_derive.comp computes for one block of one clip level, with the same integer arithmetic step for step
// (fetch with the edge texels repeated, unpremultiply, equalisation tables; the default method's 3×3 brightness sums
// and 5×5 texture window; k×k votes per group of layers, tried from the largest k down), so both give the same bytes
// (CanopyClipmapGLTest). Plain C++: the clipmap's block loader runs it on its worker thread as blocks are read
// (Ropinski et al. 2007 §4.1-4.2).
#include "Segmentation.h"
#include "SegmentationStats.h"
#include "ToroidalWindow.h"

#include <glm/vec2.hpp>

#include <cstdint>
#include <vector>

namespace seasonview {

/// Where the canopy layer's clip-level blocks are derived (`--canopy-derive`; CanopyClipmapGL.h). Auto: on the CPU, unless the imagery
/// streams from a service (the derivation's reads would fetch its tiles a second time): on the GPU then. The coarse
/// base is derived on the GPU at create() either way.
enum class CanopyDerivation { Auto, Cpu, Gpu };

/// Layers sharing one neighbourhood size: a k × k majority puts a texel on every layer below `top`.
struct CanopyGroup {
    int k = 1;
    int top = 1;
    bool operator==(const CanopyGroup&) const = default;
};

/// k of canopy layer `layer` of `layers` on clip level `level`: the ground layer's k (effectiveK(params)) growing to
/// `topK` at the top layer (§4.2), odd in between; on coarser levels about the same metres, k / 2^level rounded down
/// to odd. The `pixel` method: 1.
int canopyLayerK(const SegmentationParams& params, int layers, int topK, int layer, int level);

/// The layers grouped by k on `level`, in increasing k (canopy_derive.comp's uGroupK).
std::vector<CanopyGroup> canopyGroups(const SegmentationParams& params, int layers, int topK, int level);

/// Texels beyond an output block the derivation reads on each side: the largest vote's half width, plus the default
/// method's texture halo.
int canopyDeriveHalo(SegmentationMethod method, const std::vector<CanopyGroup>& groups);

/// The canopy values of level texels `out` (inside a level `levelSize` texels wide) into `values` (out.area() bytes,
/// rows of out.width()): how many layers each texel belongs to, 0 where either season covers less than half of it.
/// `on`, `off`: both seasons' premultiplied RGBA8 texels of `read`, which must be `out` grown by canopyDeriveHalo()
/// and clipped to the level (texels beyond the level are its edge texels, as the GPU's clamped fetches read).
void deriveCanopyTexels(const std::uint8_t* on, const std::uint8_t* off, const TexelRect& read, glm::ivec2 levelSize,
                        const TexelRect& out, SegmentationMethod method, const SegmentationStats& stats,
                        const std::vector<CanopyGroup>& groups, std::uint8_t* values);

} // namespace seasonview
