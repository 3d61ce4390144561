#pragma once
// Reads an image in bands of whole rows, tiled or scanline files alike, so memory stays bounded (a band) whatever
// the image size. Deflate, Zstandard and JPEG TIFFs (what GeoTiffStreamWriter and most GeoTIFF tools write: unsigned
// 8/16-bit, RGB or grey, tiled or in strips; JPEG 8-bit YCbCr as orthophotos come) are decoded here, the compressed
// tiles of a band read raw through libtiff and decoded on all cores (libdeflate, libzstd, libjpeg as libtiff's codec
// decodes with JPEGCOLORMODE_RGB), which is faster than GDAL's own multi-threaded reads on these files (README);
// every other file and format, and any tile that does not decode, goes through GDAL. Both give the same samples.
#include "Raster.h"
#include "Result.h"

#include <filesystem>
#include <memory>

namespace seasonview {

class BandReader {
public:
    /// Opens `path`; bands are `preferredRows` rows, rounded down to whole tiles (or whole strips of a deflate TIFF),
    /// at least one.
    static Result<BandReader> open(const std::filesystem::path& path, int preferredRows = 256);
    BandReader(BandReader&&) noexcept;
    BandReader& operator=(BandReader&&) noexcept;
    ~BandReader();

    int width() const { return m_width; }
    int height() const { return m_height; }
    int channels() const { return m_channels; }    // in the file
    int bandRows() const { return m_bandRows; }    // rows per read (the last band may be shorter)
    SampleType type() const { return m_type; }     // as stored (U8, U16, I16, F32)
    /// Whether reads of the stored sample type are decoded here by libdeflate, libzstd or libjpeg (else by GDAL).
    bool decodesTilesItself() const;
    /// Reads that the own decoder started and handed to GDAL (a block it could not read or decode): 0 for intact
    /// files, which is what the tests check, since GDAL would otherwise hide a broken decoder.
    int readsHandedOver() const { return m_handedOver; }

    /// Reads rows [y0, y1) (y0 a multiple of bandRows(), y1 - y0 <= bandRows()) of channels [0, channels) as
    /// 8-bit (`type` U8) or 16-bit (U16) interleaved samples into `out` (other stored types converted numerically,
    /// clamped). Errors name the file. Not thread-safe: one reader per thread (a read itself runs on all cores).
    Status read(int y0, int y1, int channels, SampleType type, void* out) const;

private:
    BandReader() = default;
    std::filesystem::path m_path;
    struct Input;
    std::unique_ptr<Input> m_in;
    int m_width = 0, m_height = 0, m_channels = 0, m_bandRows = 0, m_tileHeight = 0;
    SampleType m_type = SampleType::U8;
    mutable int m_handedOver = 0;
};

} // namespace seasonview
