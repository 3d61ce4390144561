// A pyramid level file in the cache (tiled, Zstandard-compressed RGBA8 TIFF with content checksums) as a command
// reads it: its header checked against the index (RGBA8 in 256² tiles of the size the file says, up to 2048², as
// opening a pyramid checks every level), then every tile read through the clipmaps' block loader.
#include "FuzzSupport.h"

#include "BlockLoader.h"
#include "ImagePyramid.h"
#include "Raster.h"

#include <vector>

using namespace seasonview;

SEASONVIEW_FUZZ_TARGET(pyramid_tile) {
    const auto level = fuzz::writeInput(data, size, "level_00.tif");
    const auto info = readRasterInfo(level);
    if (!info || info->width > 2048 || info->height > 2048) return 0;
    const int w = info->width, h = info->height;
    if (!checkLevelFile(level, size, w, h, 256, TexelFormat::Rgba8).empty()) return 0;
    PyramidBlockSource source({{level}}, 256, TexelFormat::Rgba8);
    std::vector<std::uint8_t> rgba(256 * 256 * 4);
    for (int y = 0; y < h; y += 256)
        for (int x = 0; x < w; x += 256)
            (void)source.read(0, 0, TexelRect{x, y, std::min(w, x + 256), std::min(h, y + 256)}, rgba.data());
    return 0;
}
