#pragma once
// Content checksums of Zstandard TIFF tiles, verified. GeoTiffStreamWriter writes every Zstandard tile as a frame
// with a checksum of its decoded bytes, but libtiff's codec (tif_zstd.c) stops once its output buffer is full and
// never reaches the checksum at the frame's end: a flipped bit in a tile's literals decodes into wrong samples
// without an error, through libtiff, GDAL and OpenImageIO alike. The pyramid cache's reader checks each tile here
// once, the first time a read touches it.
//
// Checking a tile by decoding it costs a second decode (OpenImageIO decodes it again to read it), so
// GeoTiffStreamWriter also appends to each Zstandard tile a CRC-32 of the tile's compressed bytes, in a skippable
// frame (RFC 8878 §3.1.2: every Zstandard decoder passes over it; libtiff's codec stops before it), and a tile that
// carries one is checked by that CRC alone, without decoding. Tiles without it (files other writers made) are
// decoded.
#include "Result.h"

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace seasonview {

/// The trailer GeoTiffStreamWriter appends to a Zstandard tile: a skippable frame whose 8 bytes of content are the
/// tag "SVC1" and the CRC-32 (zlib's) of every byte of the tile before the trailer, little-endian.
inline constexpr std::size_t kTileChecksumBytes = 16;
/// Appends the trailer to `tile` (one or more Zstandard frames).
void appendTileChecksum(std::vector<std::uint8_t>& tile);
enum class TileChecksum { Absent, Matches, Differs };
/// What the trailer at the end of `tile` (`bytes` bytes, trailer included) says of the bytes before it.
TileChecksum verifyTileChecksum(const std::uint8_t* tile, std::size_t bytes);

class ZstdTileCheck {
public:
    ZstdTileCheck();
    ~ZstdTileCheck();
    ZstdTileCheck(const ZstdTileCheck&) = delete;
    ZstdTileCheck& operator=(const ZstdTileCheck&) = delete;

    /// Checks the tiles of `file` (a tiled TIFF) that texels [x0, x1) × [y0, y1) lie in, each once per file for
    /// this object's life (again once the file's size or time changes): every Zstandard tile must match the CRC-32
    /// of its trailer, or without one, decode to its full size with its content checksum right. Files
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
