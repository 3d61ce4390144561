#pragma once
// The streaming part of `seasonview prepare`: source imagery in, one tiled 8-bit RGB TIFF per mip level out, in a
// single pass over the source with memory bounded by a few tile rows per level. The cache logic around it
// (keys, manifest, validation, atomic rename) is in ImagePyramid.cpp.
#include "ImagePyramid.h"

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace seasonview {

/// Level sizes in pixels: level 0 = width×height, level k+1 = ceil(level k / 2) per axis, down to 1×1 (included).
std::vector<std::pair<int, int>> pyramidLevelSizes(int width, int height);

/// "level_LL.tif".
std::string pyramidLevelFileName(int level);

/// 2×2 box filter of one output row of level k+1 (ceil(width/2) pixels of `channels` bytes) from rows `a` and `b` of
/// level k (width pixels each; `b` null when `a` is the last row of an odd height). An odd width's last output pixel
/// averages the samples that exist. Rounds to nearest. On premultiplied RGBA this is the correct filter: alpha
/// becomes coverage and colour the covered texels' mean times it.
void downsampleRow(const std::uint8_t* a, const std::uint8_t* b, int width, std::uint8_t* out, int channels = 4);

/// Writes every level of `layer`'s pyramid as `folder`/level_LL.tif (folder exists; files are overwritten).
/// Level 0 is the season on its working grid (GridReader: read as it is when direct, else warped) with
/// `layer.stretch` applied, RGBA with alpha 255 where it has data and (0, 0, 0, 0) where it has none; each next level
/// is the 2×2 box filter of the previous one. The source is read in bands of rows on a prefetch thread while tiles
/// are compressed on all cores. Errors name the source (unreadable, truncated) or the level file (cannot write).
/// `progress` gets the fraction of grid rows done.
Result<std::vector<PyramidLevel>> buildPyramidLevels(const ImageryLayer& layer, const std::filesystem::path& folder,
                                                     int tileSize, const ProgressFn& progress);

} // namespace seasonview
