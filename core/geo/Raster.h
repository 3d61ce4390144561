#pragma once
// Raster IO: every input raster is opened through GDAL (any format it reads: GeoTIFF with any compression, COG,
// JPEG 2000, PNG/JPEG with world files, VRT, ...; any CRS PROJ knows). Writing tiled GeoTIFFs goes through libtiff
// with our own parallel codecs (GeoTiffStreamWriter.h, which also streams rasters too large to hold); GDAL stamps
// their georeferencing.
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

/// How a raster marks pixels without data (GDAL's mask flags, simplified).
enum class NodataKind {
    None,       // every pixel is data
    Value,      // bands' nodata value (a pixel is nodata where every band has it)
    Alpha,      // an alpha band (0 = no data)
    Mask        // a per-dataset mask (an internal TIFF mask, a .msk file, a VRT's mask band)
};

/// What a raster file holds, read from its header only.
struct RasterInfo {
    std::filesystem::path path;
    int width = 0, height = 0, channels = 0; // channels: all bands, an alpha band (alphaBand) included
    SampleType type = SampleType::U8;
    std::optional<Georef> georef;     // absent for plain images (PNG masks) and for rasters without a CRS
    bool geotransformWithoutCrs = false; // georeferenced pixels, but no CRS (give one: --crs)
    std::optional<double> nodata;     // the first band's nodata value when it has one
    NodataKind nodataKind = NodataKind::None;
    int alphaBand = 0;                // 1-based GDAL band of the alpha channel, 0 = none
    bool tiled = false;
    std::string driver;               // GDAL's short name: GTiff, PNG, JP2OpenJPEG, VRT, ...
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

/// Reads the header (size, type, georeferencing, nodata) through GDAL. Errors: missing file, not an image,
/// unsupported sample type, rotated or sheared grids. A file without georeferencing has no georef; one with a
/// geotransform but no CRS gets `assumedCrs` when given, else no georef and geotransformWithoutCrs (the caller
/// decides whether either is an error).
Result<RasterInfo> readRasterInfo(const std::filesystem::path& path, const std::optional<Crs>& assumedCrs = {});

/// Whole-image reads (truth masks, textures, small DEMs) hold at most this much; larger images are refused before
/// allocation with the limit named (imagery and DEMs of any size stream through BandReader and GridReader instead).
inline constexpr std::uint64_t kMaxWholeImageBytes = std::uint64_t(4) << 30;
/// Reads all pixels converted to T (u8, u16 or float: values converted numerically, clamped to T's range, never
/// rescaled), first `maxChannels` bands. Errors name the file (truncated, corrupt: any GDAL read error).
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
    bool associatedAlpha = false; // a 4th (or 2nd) channel is associated alpha: the colour is premultiplied by it
    int threads = 0;           // compression threads (0 = hardware concurrency); the bytes do not depend on it
    std::uint64_t bigTiffAbove = std::uint64_t(2) << 30; // BigTIFF when the raw samples exceed this many bytes
};

/// Writes an interleaved raster as a tiled, compressed (options.compression) GeoTIFF (any CRS, PixelIsArea) through
/// GeoTiffStreamWriter. Atomic: written to a temporary name in the same folder, renamed on success. `data` holds
/// width*height*channels samples of the given type.
Status writeGeoTiff(const std::filesystem::path& path, const void* data, SampleType type, int width, int height,
                    int channels, const Georef& georef, const GeoTiffWriteOptions& options = {});

/// Writes an 8-bit image (PNG, TIFF, ... by extension), atomically. Row 0 is the top row.
Status writeImageAtomic(const std::filesystem::path& path, const std::uint8_t* data, int width, int height, int channels);

} // namespace seasonview
