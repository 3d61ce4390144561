#pragma once
// GDAL plumbing shared by core's readers and writers: one-time driver registration and settings, datasets as
// move-only handles, and GDAL's error messages caught per call so that each failure becomes one line naming the
// file. Internal to core: other modules go through Raster.h, RasterSource.h and GridReader.h.
#include "Raster.h"
#include "Result.h"

#include <gdal_priv.h>

#include <filesystem>
#include <memory>
#include <string>

namespace seasonview::gdal {

/// Registers GDAL's drivers and sets what seasonview relies on: no .aux.xml side files (reading never writes next
/// to the user's data), a bounded block cache (256 MB), JPEG-in-TIFF decoded to RGB. Idempotent and thread-safe;
/// every entry point of core that touches GDAL calls it first.
void init();

struct DatasetCloser {
    void operator()(GDALDataset* d) const { GDALClose(GDALDataset::ToHandle(d)); }
};
using Dataset = std::unique_ptr<GDALDataset, DatasetCloser>;

/// Collects the GDAL errors raised on this thread while it lives (GDAL's handlers are per thread), without
/// printing them. `message()` is the first failure (else the first warning), as one line.
class ErrorCapture {
public:
    ErrorCapture();
    ~ErrorCapture();
    ErrorCapture(const ErrorCapture&) = delete;
    ErrorCapture& operator=(const ErrorCapture&) = delete;

    bool failed() const { return !m_failure.empty(); }
    /// A failure, or a warning that means pixels were not read as stored (a short read, a JPEG stream cut short or
    /// corrupt: GDAL and libtiff report some of those as warnings and fill the pixels in). Warnings known to be
    /// harmless (extraneous bytes before a JPEG marker, unknown TIFF tags) do not count. For reads of pixels.
    bool lostData() const { return failed() || m_dataWarning; }
    /// The first failure's text, or else the first data-losing warning's, or else the first warning's; "" when GDAL
    /// said nothing.
    std::string message() const {
        return !m_failure.empty() ? m_failure : !m_dataWarningText.empty() ? m_dataWarningText : m_warning;
    }

private:
    std::string m_failure, m_warning, m_dataWarningText;
    bool m_dataWarning = false;
};

/// The error of a pixel read that lost data: "FILE: truncated or corrupt image data in rows Y0-Y1 (what the decoder
/// said)"; no rows when y0 < 0 (GDAL's warper does not say which it read). `why` overrides GDAL's words (the own tile decoder's, which name the tile).
Error readFailure(const std::string& file, const ErrorCapture& errors, int y0, int y1, const std::string& why = {});

/// Limits on what a raster may declare, checked when it is opened, before anything is allocated for it: a side of
/// 2^20 pixels (100 km at 10 cm), 256 bands, 2^24 tiles or strips (a 2^20-pixel square in 256² tiles), and one tile
/// or strip of 1 GiB decoded. A header past them is damaged or not meant for seasonview; the error names the limit.
inline constexpr std::int64_t kMaxRasterSide = std::int64_t(1) << 20;
inline constexpr std::int64_t kMaxRasterBands = 256;
inline constexpr std::int64_t kMaxRasterBlocks = std::int64_t(1) << 24;
inline constexpr std::int64_t kMaxRasterBlockBytes = std::int64_t(1) << 30;
/// Checks an open dataset against those limits; errors name `file`.
Status checkRasterLimits(GDALDataset& ds, const std::string& file);

/// Opens a raster read-only (any driver GDAL has). Errors name the file: not found, a folder, empty, or not a
/// raster GDAL can read (with GDAL's words).
Result<Dataset> openRaster(const std::filesystem::path& path);

/// Our sample type for a GDAL data type: Byte → U8, UInt16 → U16, Int16 → I16, everything else numeric → F32 (read
/// as float). Nothing for complex types.
std::optional<SampleType> sampleTypeOf(GDALDataType t);
/// The GDAL data type of our sample type.
GDALDataType gdalTypeOf(SampleType t);

/// Writes the georeferencing (geotransform, CRS) and, when given, the nodata value of every band into an existing,
/// closed GeoTIFF, which GDAL rewrites in place (the pixels are untouched). Errors name the file.
Status stampGeoreference(const std::filesystem::path& tiff, const Georef& georef, const std::optional<double>& nodata);

} // namespace seasonview::gdal
