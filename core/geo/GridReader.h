#pragma once
// Rows of a raster mosaic on a working grid, in bounded memory: what `prepare` builds pyramids from, and what
// DEMs and truth masks are read through. Two ways, chosen per mosaic:
//  - direct: one file that is the grid (same CRS, lattice and size) and marks no pixel as nodata: its rows as they
//    are, through BandReader's parallel tile decoders;
//  - warped: every tile that reaches the band of rows warped onto it by GDAL's warper (multi-threaded kernel,
//    PROJ transformation approximated to 1/8 pixel), later tiles over earlier ones where they have data, each tile's
//    nodata value, alpha band or mask honoured; coverage says where any tile had data.
#include "RasterMosaic.h"
#include "Result.h"
#include "WorkingGrid.h"

#include <cstdint>
#include <memory>
#include <string>

namespace seasonview {

enum class Resampling { Auto, Nearest, Bilinear, Cubic, Average, Lanczos };

/// "auto", "near", "bilinear", "cubic", "average", "lanczos".
const char* resamplingName(Resampling r);
/// The resampling called `name`; an error lists the names.
Result<Resampling> parseResampling(const std::string& name);

class GridReader {
public:
    /// Opens `mosaic` for reading on `grid`. Auto resampling: nearest for a tile on the grid's lattice (its pixels
    /// are copied), average where a tile is more than 1.5 times finer than the grid, bilinear otherwise. Bands are
    /// `preferredRows` rows (the direct path rounds to whole tiles). Errors name the file.
    static Result<GridReader> open(const RasterMosaic& mosaic, const WorkingGrid& grid, Resampling resampling,
                                   int preferredRows);
    GridReader(GridReader&&) noexcept;
    GridReader& operator=(GridReader&&) noexcept;
    ~GridReader();

    int width() const { return m_width; }
    int height() const { return m_height; }
    int bandRows() const { return m_bandRows; }
    /// True when rows are read as they are from a single file (no warp).
    bool direct() const;

    /// Reads rows [y0, y1) (y0 a multiple of bandRows(), y1 - y0 <= bandRows()) of bands [0, channels) as
    /// interleaved samples of `type` (U8, U16 or F32; converted numerically from the stored type) into `samples`,
    /// and, when `coverage` is not null, one byte per pixel into it: 255 where the mosaic has data, 0 where it has
    /// none (outside every tile, or nodata there); samples are 0 where coverage is 0. Errors name the tile and what
    /// GDAL said. Not thread-safe: one reader per thread.
    Status read(int y0, int y1, int channels, SampleType type, void* samples, std::uint8_t* coverage);
    /// Reads the window [x0, x1) × [y0, y1) of the grid as read() reads rows (rows of x1 - x0 pixels), in any order:
    /// the tiles it reaches stay open for the next window (a streamed clip level's regions). Not thread-safe.
    Status readWindow(int x0, int y0, int x1, int y1, int channels, SampleType type, void* samples,
                      std::uint8_t* coverage);

private:
    Status readWarped(int x0, int y0, int x1, int y1, int channels, SampleType type, void* samples,
                      std::uint8_t* coverage);
    Status readWarpedOnce(int x0, int y0, int x1, int y1, int channels, SampleType type, void* samples,
                          std::uint8_t* coverage);
    GridReader();
    struct Impl;
    std::unique_ptr<Impl> m_impl;
    int m_width = 0, m_height = 0, m_bandRows = 0;
};

} // namespace seasonview
