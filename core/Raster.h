#pragma once
// Raster IO: GeoTIFF georeferencing through libgeotiff (Debian's OpenImageIO 2.4 does not expose the GeoTIFF tags),
// pixels through OpenImageIO. Writing georeferenced tiled GeoTIFFs goes through libtiff + libgeotiff
// (GeoTiffStreamWriter.h, which also streams rasters too large to hold).
#include "Crs.h"
#include "Result.h"

#include <glm/vec2.hpp>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <vector>

namespace seasonview {

enum class SampleType { U8, U16, I16, F32 };
const char* sampleTypeName(SampleType t);

/// Affine pixel -> CRS mapping of a north-up raster. Pixel (col,row) has its top-left corner at
/// origin + (col*pixelSize.x, -row*pixelSize.y): pixel centres are at (col+0.5, row+0.5).
struct Georef {
    Crs crs;
    glm::dvec2 origin{0.0};      // CRS coordinates of the top-left corner of pixel (0,0)
    glm::dvec2 pixelSize{1.0};   // CRS units per pixel, both positive (rows go south)

    glm::dvec2 pixelToCrs(glm::dvec2 px) const { return {origin.x + px.x * pixelSize.x, origin.y - px.y * pixelSize.y}; }
    glm::dvec2 crsToPixel(glm::dvec2 p) const { return {(p.x - origin.x) / pixelSize.x, (origin.y - p.y) / pixelSize.y}; }
};

/// What a raster file holds, read from its header only.
struct RasterInfo {
    std::filesystem::path path;
    int width = 0, height = 0, channels = 0;
    SampleType type = SampleType::U8;
    std::optional<Georef> georef;     // absent for plain images (PNG masks)
    std::optional<double> nodata;     // GDAL_NODATA tag when present
    bool tiled = false;
};

/// Pixels of a raster, interleaved, row 0 = north (top).
template <typename T> struct Image {
    int width = 0, height = 0, channels = 0;
    std::vector<T> pixels;
    T& at(int x, int y, int c = 0) { return pixels[(size_t(y) * size_t(width) + size_t(x)) * size_t(channels) + size_t(c)]; }
    const T& at(int x, int y, int c = 0) const {
        return pixels[(size_t(y) * size_t(width) + size_t(x)) * size_t(channels) + size_t(c)];
    }
};

/// Reads the header (size, type, georeferencing). Errors: missing file, not an image, unsupported sample type,
/// unsupported CRS. A file without GeoTIFF tags has no georef (the caller decides whether that is an error).
Result<RasterInfo> readRasterInfo(const std::filesystem::path& path);

/// Reads all pixels converted to T (u8, u16 or float), first `maxChannels` channels. Errors name the file
/// (truncated, corrupt).
Result<Image<std::uint8_t>> readImageU8(const std::filesystem::path& path, int maxChannels = 4);
Result<Image<std::uint16_t>> readImageU16(const std::filesystem::path& path, int maxChannels = 4);
Result<Image<float>> readImageF32(const std::filesystem::path& path, int maxChannels = 1);

/// Options for writing a GeoTIFF (writeGeoTiff, GeoTiffStreamWriter).
/// How GeoTiffStreamWriter compresses tiles. Deflate is what every TIFF reader knows; Zstandard (libtiff ≥ 4.0.10,
/// GDAL ≥ 2.3, QGIS) is as small on imagery and decodes about five times faster (0.12 vs 0.63 s for an 8192² RGB
/// season on one core of this machine), so it is what the synthetic scenes and the pyramid cache use. Jpeg is what
/// orthophotos usually come as (lossy; 8-bit RGB only, stored YCbCr 4:2:0 as GDAL's COMPRESS=JPEG PHOTOMETRIC=YCBCR
/// does, but each tile with its own tables rather than a shared JPEGTables tag).
enum class TiffCompression { Deflate, Zstd, Jpeg };

/// "deflate" / "zstd" / "jpeg" (the synth flag's values).
const char* tiffCompressionName(TiffCompression c);

struct GeoTiffWriteOptions {
    int tileSize = 256;        // tiled TIFF, tileSize² tiles, a multiple of 16 (0 = strips of 16 rows)
    TiffCompression compression = TiffCompression::Deflate;
    int deflateLevel = 1;      // libdeflate level 1..12; 1 is ~3x faster than 6 for ~10% larger files
    int zstdLevel = 1;         // Zstandard level 1..22; 1 is smaller than deflate level 1 on imagery
    int jpegQuality = 90;      // JPEG quality 1..100 (libjpeg's scale)
    std::optional<double> nodata;
    int threads = 0;           // compression threads (0 = hardware concurrency); the bytes do not depend on it
    std::uint64_t bigTiffAbove = std::uint64_t(2) << 30; // BigTIFF when the raw samples exceed this many bytes
};

/// Writes an interleaved raster as a tiled, compressed (options.compression) GeoTIFF (UTM or geographic, PixelIsArea) through
/// GeoTiffStreamWriter. Atomic: written to a temporary name in the same folder, renamed on success. `data` holds
/// width*height*channels samples of the given type.
Status writeGeoTiff(const std::filesystem::path& path, const void* data, SampleType type, int width, int height,
                    int channels, const Georef& georef, const GeoTiffWriteOptions& options = {});

/// Writes an 8-bit image (PNG, TIFF, ... by extension) through OpenImageIO, atomically. Row 0 is the top row.
Status writeImageAtomic(const std::filesystem::path& path, const std::uint8_t* data, int width, int height, int channels);

} // namespace seasonview
