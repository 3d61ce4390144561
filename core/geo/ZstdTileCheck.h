#pragma once
// Content checksums of Zstandard TIFF tiles, verified. GeoTiffStreamWriter writes every Zstandard tile as a frame
// with a checksum of its decoded bytes, but libtiff's codec (tif_zstd.c) stops once its output buffer is full and
// never reaches the checksum at the frame's end: a flipped bit in a tile's literals decodes into wrong samples
// without an error, through libtiff, GDAL and OpenImageIO alike. The pyramid cache's reader checks each tile here
// once, the first time a read touches it.
#include "Result.h"

#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace seasonview {

class ZstdTileCheck {
public:
    ZstdTileCheck();
    ~ZstdTileCheck();
    ZstdTileCheck(const ZstdTileCheck&) = delete;
    ZstdTileCheck& operator=(const ZstdTileCheck&) = delete;

    /// Checks the tiles of `file` (a tiled TIFF) that texels [x0, x1) × [y0, y1) lie in, each once per file for
    /// this object's life (again once the file's size or time changes): every Zstandard tile must decode to its full size with its content checksum right. Files
    /// that are not Zstandard-compressed, and tiles without a checksum, pass (there is nothing to check). The error
    /// names the file and the tile. Thread-safe.
    Status check(const std::filesystem::path& file, int x0, int y0, int x1, int y1);

private:
    struct File {
        std::uintmax_t bytes = 0;                       // the file as checked: rewritten, it is checked again
        std::filesystem::file_time_type modified{};
        bool zstd = false;
        int width = 0, height = 0, tileWidth = 0, tileHeight = 0, tilesAcross = 0;
        std::vector<char> checked; // per tile
    };
    std::mutex m_mutex;
    std::map<std::string, File> m_files;
    struct Decoder;
    std::unique_ptr<Decoder> m_decoder;
};

} // namespace seasonview
