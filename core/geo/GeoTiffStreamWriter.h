#pragma once
// Streams a raster into a deflate-, Zstandard- or JPEG-compressed TIFF (tiled, or in strips of 16 rows), optionally
// georeferenced, in bounded memory: the caller hands over rows top to bottom in any amounts, the writer compresses
// each complete row of tiles on several threads (libdeflate or libzstd with the TIFF predictor; libjpeg, YCbCr 4:2:0,
// each tile a complete JPEG stream) and libtiff writes the tiles in order as raw tiles.
// Written to a temporary name next to the target and renamed by finish(), so a failed or abandoned file never
// appears under its final name. The bytes depend only on the pixels and the options, not on how rows are split
// between writeRows() calls or on the thread count. Used by writeGeoTiff, the synthetic scene generator and the
// pyramid builder.
#include "Raster.h"
#include "Result.h"

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

struct tiff;

namespace seasonview {

class GeoTiffStreamWriter {
public:
    /// Creates the temporary file for a width×height raster of `channels` interleaved samples of `type`
    /// (PHOTOMETRIC_RGB from 3 channels, a 4th or 2nd channel is unassociated alpha; JPEG: 8-bit RGB only, stored as
    /// PHOTOMETRIC_YCBCR), with GeoTIFF tags when `georef` is given. BigTIFF when width×height×channels×sample bytes
    /// exceeds options.bigTiffAbove. options.tileSize must be 0 (strips) or a positive multiple of 16. Errors name the
    /// file (also JPEG of anything but 8-bit RGB).
    static Result<GeoTiffStreamWriter> open(const std::filesystem::path& path, int width, int height, int channels,
                                            SampleType type, const std::optional<Georef>& georef,
                                            const GeoTiffWriteOptions& options = {});

    GeoTiffStreamWriter(GeoTiffStreamWriter&& other) noexcept;
    GeoTiffStreamWriter& operator=(GeoTiffStreamWriter&& other) noexcept;
    GeoTiffStreamWriter(const GeoTiffStreamWriter&) = delete;
    GeoTiffStreamWriter& operator=(const GeoTiffStreamWriter&) = delete;
    /// Without finish(), closes and deletes the temporary file: nothing appears under the final name.
    ~GeoTiffStreamWriter();

    /// Appends image rows [y0, y0 + rows): y0 must be rowsWritten() (rows come top to bottom) and y0 + rows at most
    /// height(). `data` holds rows × width × channels samples of the writer's type, tightly packed; it is only
    /// read. Rows that complete a row of tiles are compressed and written at once (directly from `data` when a
    /// call starts on a tile-row boundary); the rest wait in an internal buffer of one tile row.
    Status writeRows(int y0, int rows, const void* data);

    /// Writes the TIFF directory, closes the file and renames it to its final name. Call once, after all rows.
    Status finish();

    int width() const { return m_width; }
    int height() const { return m_height; }
    int rowsWritten() const { return m_rowsWritten; }
    bool bigTiff() const { return m_bigTiff; }

private:
    struct Encoder; // per-thread compressors and scratch, libdeflate types kept out of this header

    GeoTiffStreamWriter();
    Status encodeBlockRow(const std::uint8_t* rows, int y0, int rowCount);
    Status fail(const std::string& what);
    void abandon();

    std::filesystem::path m_path, m_tmp;
    ::tiff* m_tif = nullptr;
    int m_width = 0, m_height = 0, m_channels = 0, m_sampleBytes = 1, m_threads = 1;
    SampleType m_type = SampleType::U8;
    int m_blockWidth = 0, m_blockHeight = 0; // a tile, or a strip (full width, 16 rows)
    bool m_tiled = true, m_bigTiff = false;
    int m_rowsWritten = 0;
    std::unique_ptr<std::string> m_error;     // libtiff's last message about this file (stable address)
    std::unique_ptr<Encoder> m_encoder;
    std::vector<std::uint8_t> m_pending;      // rows of an incomplete block row
    std::optional<Georef> m_georef;           // stamped by GDAL in finish()
    std::optional<double> m_nodata;
    int m_pendingRows = 0;
};

} // namespace seasonview
