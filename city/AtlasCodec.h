#pragma once
// Atlas images in the tree file: the mip chain (2×2 box filter down to 4×4) and its compression (BC1/BC3 through
// stb_dxt, or lossless deflate), plus decoding for the CPU (tests, quality measurement, the deflate path's upload).
// Images are RGBA8, rows bottom-up (OpenGL's order), square, a power of two of at least 4.
#include "AtlasTree.h"

#include <cstdint>
#include <vector>

namespace seasonview::city {

/// Halves an RGBA8 image (size² texels) with a 2×2 box filter.
std::vector<std::uint8_t> halveRgba(const std::vector<std::uint8_t>& rgba, int size);

/// Fills every texel not `covered` (one byte per texel, non-zero = covered) with its nearest covered texel (4-
/// neighbour distance, breadth first): empty atlas space then continues the areas' edges, so the filter footprints
/// of coarse mips and anisotropic probes that reach past an area's border see its own colours, not black.
/// Nothing happens when no texel is covered.
void dilateRgba(std::vector<std::uint8_t>& rgba, int size, const std::vector<std::uint8_t>& covered);

/// Compresses an atlas (level 0 given, RGBA8) with its whole mip chain into one blob; BC blocks on up to `threads`
/// threads (the result does not depend on it).
std::vector<std::uint8_t> encodeAtlas(AtlasFormat format, bool alpha, const std::vector<std::uint8_t>& rgba, int size,
                                      int threads = 1);

/// One mip level of a blob as it is uploaded: BC blocks for Bc, RGB(A)8 rows for Deflate. Empty on a corrupt blob.
std::vector<std::uint8_t> atlasLevelData(AtlasFormat format, bool alpha, const std::vector<std::uint8_t>& blob,
                                         int size, int level);

/// Level 0 of a blob decoded to RGBA8. Empty on a corrupt blob.
std::vector<std::uint8_t> decodeAtlasRgba(AtlasFormat format, bool alpha, const std::vector<std::uint8_t>& blob, int size);

/// BC1 (8-byte blocks) or BC3 (16-byte) data of a size² image decoded to RGBA8.
std::vector<std::uint8_t> decodeBc(const std::uint8_t* blocks, int size, bool alpha);

} // namespace seasonview::city
