#include "GridReader.h"

#include "BandReader.h"
#include "GdalSupport.h"
#include "WarpKernel.h"
#include "WebSource.h"

#include <gdal_alg.h>
#include <gdalwarper.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <span>
#include <thread>
#include <vector>

namespace seasonview {

namespace {

/// One tile of a warped mosaic: opened while bands of rows reach it.
struct WarpTile {
    RasterInfo info;
    int row0 = 0, row1 = 0, col0 = 0, col1 = 0; // the grid window it can touch (a margin for the kernel included)
    GDALResampleAlg alg = GRA_Bilinear;
    bool ownKernel = false; // nearest and bilinear: WarpKernel.h; the other kernels: GDAL's warper
    gdal::Dataset ds;
    void* transform = nullptr; // GDALGenImgProjTransform: tile pixels <-> grid pixels (of the band's dataset)
    void* approx = nullptr;    // the same, approximated to 1/8 pixel
    void close() {
        if (approx) GDALDestroyApproxTransformer(approx);
        if (transform) GDALDestroyGenImgProjTransformer(transform);
        approx = transform = nullptr;
        ds.reset();
    }
    ~WarpTile() { close(); }
    WarpTile() = default;
    WarpTile(WarpTile&& o) noexcept { *this = std::move(o); }
    WarpTile& operator=(WarpTile&& o) noexcept {
        if (this != &o) {
            close();
            info = o.info;
            row0 = o.row0;
            row1 = o.row1;
            col0 = o.col0;
            col1 = o.col1;
            alg = o.alg;
            ownKernel = o.ownKernel;
            ds = std::move(o.ds);
            transform = std::exchange(o.transform, nullptr);
            approx = std::exchange(o.approx, nullptr);
        }
        return *this;
    }
};

GDALResampleAlg gdalAlg(Resampling r) {
    switch (r) {
    case Resampling::Nearest: return GRA_NearestNeighbour;
    case Resampling::Cubic: return GRA_Cubic;
    case Resampling::Average: return GRA_Average;
    case Resampling::Lanczos: return GRA_Lanczos;
    default: return GRA_Bilinear;
    }
}

int bytesOf(SampleType t) { return t == SampleType::U8 ? 1 : t == SampleType::F32 ? 4 : 2; }

/// Grid pixels [x0, x1) × [y0, y1): what one read fills.
struct TexelWindow {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

/// A tile's part of a window of the grid through WarpKernel: the lattice of where grid pixels sample the tile (PROJ), the
/// window of the tile it reaches with its validity (alpha, mask or nodata value), then nearest or bilinear.
template <typename T>
Status ownWarpTyped(const WarpTile& t, const WorkingGrid& grid, const TexelWindow& w, int channels, T* out,
                    std::uint8_t* coverage) {
    const RasterInfo& info = t.info;
    const std::string name = info.path.string();
    const int y0 = w.y0;
    const int r0 = std::max(t.row0, w.y0), r1 = std::min(t.row1, w.y1);
    const int col0 = std::max(t.col0, w.x0), col1 = std::min(t.col1, w.x1);
    if (r0 >= r1 || col0 >= col1) return Ok{};
    const Georef& gg = grid.georef;
    const Georef& tg = *info.georef;
    const Crs gridCrs = gg.crs, tileCrs = tg.crs;
    const SourceLattice lattice = SourceLattice::build(col0, r0, col1, r1, [&](std::span<glm::dvec2> pts) {
        for (glm::dvec2& p : pts) p = gg.pixelToCrs(p);
        convert(gridCrs, tileCrs, pts);
        for (glm::dvec2& p : pts) p = tg.crsToPixel(p);
    });
    if (lattice.min().x > lattice.max().x) return Ok{}; // nothing of the band maps into the tile's CRS
    const int sx0 = std::max(0, int(std::floor(lattice.min().x)) - 2);
    const int sy0 = std::max(0, int(std::floor(lattice.min().y)) - 2);
    const int sx1 = std::min(info.width, int(std::ceil(lattice.max().x)) + 2);
    const int sy1 = std::min(info.height, int(std::ceil(lattice.max().y)) + 2);
    if (sx0 >= sx1 || sy0 >= sy1) return Ok{};
    SourceWindow<T> src;
    src.x0 = sx0;
    src.y0 = sy0;
    src.width = sx1 - sx0;
    src.height = sy1 - sy0;
    src.channels = channels;
    const size_t n = size_t(src.width) * size_t(src.height);
    src.samples.resize(n * size_t(channels));
    src.valid.assign(n, 1);
    std::vector<int> bands;
    for (int b = 1; b <= info.channels && int(bands.size()) < channels; ++b)
        if (b != info.alphaBand) bands.push_back(b);
    gdal::ErrorCapture errors;
    GDALDataset& ds = *t.ds;
    const GSpacing bytes = GSpacing(sizeof(T));
    const GDALDataType type =
        gdal::gdalTypeOf(sizeof(T) == 1 ? SampleType::U8 : sizeof(T) == 2 ? SampleType::U16 : SampleType::F32);
    CPLErr err = CE_None;
    // An 8-bit alpha band that is GDAL's mask (no nodata value or internal mask before it) is read with the colour.
    const bool alphaRead = info.nodataKind == NodataKind::Alpha && info.alphaBand > 0 && sizeof(T) == 1 &&
                           ds.GetRasterBand(info.alphaBand)->GetRasterDataType() == GDT_Byte &&
                           ds.GetRasterBand(bands.front())->GetMaskFlags() == (GMF_ALPHA | GMF_PER_DATASET);
    if (alphaRead) {
        // The alpha band in the same read as the colour: each tile decoded (and, for a URL, fetched) once, not again
        // through the mask band. Data where alpha is 128 or more, as from the mask band below.
        std::vector<int> withAlpha = bands;
        withAlpha.push_back(info.alphaBand);
        const int c1 = channels + 1;
        std::vector<T> all(n * size_t(c1));
        err = ds.RasterIO(GF_Read, sx0, sy0, src.width, src.height, all.data(), src.width, src.height, type, c1,
                          withAlpha.data(), bytes * c1, bytes * c1 * src.width, bytes, nullptr);
        for (size_t i = 0; i < n; ++i) {
            for (int c = 0; c < channels; ++c) src.samples[i * size_t(channels) + size_t(c)] = all[i * size_t(c1) + size_t(c)];
            src.valid[i] = all[i * size_t(c1) + size_t(channels)] >= 128 ? 1 : 0;
        }
    } else {
        err = ds.RasterIO(GF_Read, sx0, sy0, src.width, src.height, src.samples.data(), src.width, src.height, type,
                          channels, bands.data(), bytes * channels, bytes * channels * src.width, bytes, nullptr);
    }
    if (err == CE_None && !alphaRead && (info.nodataKind == NodataKind::Alpha || info.nodataKind == NodataKind::Mask)) {
        // Alpha and masks through GDAL's mask band: 0 no data, 255 data (alpha scaled to a byte).
        err = ds.GetRasterBand(bands.front())
                  ->GetMaskBand()
                  ->RasterIO(GF_Read, sx0, sy0, src.width, src.height, src.valid.data(), src.width, src.height,
                             GDT_Byte, 0, 0, nullptr);
        for (std::uint8_t& v : src.valid) v = v >= 128 ? 1 : 0;
    } else if (err == CE_None && info.nodataKind == NodataKind::Value && info.nodata) {
        // A pixel is no data where every band has the nodata value (GDAL's UNIFIED_SRC_NODATA).
        const T nd = T(*info.nodata);
        for (size_t i = 0; i < n; ++i) {
            bool all = true;
            for (int c = 0; c < channels && all; ++c) all = src.samples[i * size_t(channels) + size_t(c)] == nd;
            src.valid[i] = all ? 0 : 1;
        }
    }
    if (err != CE_None || errors.lostData()) return gdal::readFailure(name, errors, sy0, sy0 + src.height);
    const int threads = std::max(1, int(std::thread::hardware_concurrency()));
    resampleWindow(lattice, src, t.alg == GRA_Bilinear, col0, r0, col1, r1, out, coverage, w.x1 - w.x0, y0, w.x0,
                   threads);
    return Ok{};
}

Status ownWarp(const WarpTile& t, const WorkingGrid& grid, const TexelWindow& w, int channels, SampleType type,
               void* out, std::uint8_t* coverage) {
    switch (type) {
    case SampleType::U8: return ownWarpTyped(t, grid, w, channels, static_cast<std::uint8_t*>(out), coverage);
    case SampleType::U16: return ownWarpTyped(t, grid, w, channels, static_cast<std::uint16_t*>(out), coverage);
    default: return ownWarpTyped(t, grid, w, channels, static_cast<float*>(out), coverage);
    }
}

} // namespace

const char* resamplingName(Resampling r) {
    switch (r) {
    case Resampling::Auto: return "auto";
    case Resampling::Nearest: return "near";
    case Resampling::Bilinear: return "bilinear";
    case Resampling::Cubic: return "cubic";
    case Resampling::Average: return "average";
    case Resampling::Lanczos: return "lanczos";
    }
    return "?";
}

Result<Resampling> parseResampling(const std::string& name) {
    for (Resampling r : {Resampling::Auto, Resampling::Nearest, Resampling::Bilinear, Resampling::Cubic,
                         Resampling::Average, Resampling::Lanczos})
        if (name == resamplingName(r)) return r;
    return Error{"--resampling '" + name + "': expected auto|near|bilinear|cubic|average|lanczos"};
}

struct GridReader::Impl {
    WorkingGrid grid;
    int bands = 0;
    std::optional<BandReader> direct;
    std::vector<WarpTile> tiles;
    std::string gridWkt;
};

GridReader::GridReader() = default;
GridReader::GridReader(GridReader&&) noexcept = default;
GridReader& GridReader::operator=(GridReader&&) noexcept = default;
GridReader::~GridReader() = default;

bool GridReader::direct() const { return m_impl->direct.has_value(); }

Result<GridReader> GridReader::open(const RasterMosaic& mosaic, const WorkingGrid& grid, Resampling resampling,
                                    int preferredRows) {
    assert(!mosaic.tiles.empty() && grid.width > 0 && grid.height > 0 && preferredRows > 0 &&
           "GridReader::open(): a mosaic, a grid, positive rows");
    GridReader r;
    r.m_impl = std::make_unique<Impl>();
    Impl& impl = *r.m_impl;
    impl.grid = grid;
    impl.bands = mosaic.bands;
    r.m_width = grid.width;
    r.m_height = grid.height;
    const RasterInfo& first = mosaic.tiles.front();
    const bool isGrid = mosaic.tiles.size() == 1 && onGridLattice(first, grid) && first.width == grid.width &&
                        first.height == grid.height && grid.georef.crsToPixel(first.georef->origin) == glm::dvec2(0.0);
    if (isGrid && first.nodataKind == NodataKind::None && (first.type == SampleType::U8 || first.type == SampleType::U16)) {
        auto reader = BandReader::open(first.path, preferredRows);
        if (!reader) return reader.error();
        r.m_bandRows = reader->bandRows();
        impl.direct = std::move(*reader);
        return r;
    }
    r.m_bandRows = preferredRows;
    impl.gridWkt = grid.georef.crs.wkt();
    for (const RasterInfo& t : mosaic.tiles) {
        WarpTile w;
        w.info = t;
        // The grid pixels the tile's outline covers, with a margin for the resampling kernel (lanczos: 3 pixels).
        RasterMosaic one;
        one.tiles = {t};
        auto [lo, hi] = extentIn(one, grid.georef.crs);
        const glm::dvec2 a = grid.georef.crsToPixel({lo.x, hi.y}), b = grid.georef.crsToPixel({hi.x, lo.y});
        constexpr int kMargin = 4;
        w.col0 = std::max(0, int(std::floor(a.x)) - kMargin);
        w.row0 = std::max(0, int(std::floor(a.y)) - kMargin);
        w.col1 = std::min(grid.width, int(std::ceil(b.x)) + kMargin);
        w.row1 = std::min(grid.height, int(std::ceil(b.y)) + kMargin);
        if (w.col0 >= w.col1 || w.row0 >= w.row1) continue; // outside the grid (an --extent cut it away)
        Resampling alg = resampling;
        if (alg == Resampling::Auto) {
            if (onGridLattice(t, grid)) {
                alg = Resampling::Nearest;
            } else {
                // The tile's pixel in grid pixels: finer than 1/1.5 of a grid pixel is averaged.
                const double tileArea = double(t.width) * double(t.height);
                const double gridArea = (b.x - a.x) * (b.y - a.y);
                alg = tileArea > 2.25 * gridArea ? Resampling::Average : Resampling::Bilinear;
            }
        }
        w.alg = gdalAlg(alg);
        w.ownKernel = alg == Resampling::Nearest || alg == Resampling::Bilinear;
        impl.tiles.push_back(std::move(w));
    }
    return r;
}

Status GridReader::read(int y0, int y1, int channels, SampleType type, void* samples, std::uint8_t* coverage) {
    assert(y0 % m_bandRows == 0 && y0 < y1 && y1 - y0 <= m_bandRows && y1 <= m_height && channels >= 1 &&
           channels <= m_impl->bands && "GridReader::read(): whole bands of existing rows and bands");
    Impl& impl = *m_impl;
    if (impl.direct) {
        assert(type != SampleType::F32 && "GridReader::read(): the direct path reads 8- or 16-bit");
        if (coverage) std::memset(coverage, 255, size_t(y1 - y0) * size_t(m_width));
        return impl.direct->read(y0, y1, channels, type, samples);
    }
    // Bands come top-down: tiles the bands have passed are closed.
    for (WarpTile& t : impl.tiles)
        if (t.row1 <= y0) t.close();
    return readWarped(0, y0, m_width, y1, channels, type, samples, coverage);
}

Status GridReader::readWindow(int x0, int y0, int x1, int y1, int channels, SampleType type, void* samples,
                              std::uint8_t* coverage) {
    assert(x0 >= 0 && y0 >= 0 && x0 < x1 && y0 < y1 && x1 <= m_width && y1 <= m_height && channels >= 1 &&
           channels <= m_impl->bands && "GridReader::readWindow(): a window of the grid, existing bands");
    Impl& impl = *m_impl;
    if (impl.direct) {
        // The file's rows, whole bands of them, cut to the window.
        const int sample = bytesOf(type), rows = m_bandRows;
        const size_t pixel = size_t(channels) * size_t(sample);
        std::vector<std::uint8_t> band(size_t(m_width) * size_t(rows) * pixel);
        for (int b0 = y0 / rows * rows; b0 < y1; b0 += rows) {
            const int b1 = std::min(m_height, b0 + rows);
            if (auto st = impl.direct->read(b0, b1, channels, type, band.data()); !st) return st;
            for (int y = std::max(y0, b0); y < std::min(y1, b1); ++y)
                std::memcpy(static_cast<std::uint8_t*>(samples) + size_t(y - y0) * size_t(x1 - x0) * pixel,
                            band.data() + (size_t(y - b0) * size_t(m_width) + size_t(x0)) * pixel,
                            size_t(x1 - x0) * pixel);
        }
        if (coverage) std::memset(coverage, 255, size_t(x1 - x0) * size_t(y1 - y0));
        return Ok{};
    }
    return readWarped(x0, y0, x1, y1, channels, type, samples, coverage);
}

Status GridReader::readWarped(int x0, int y0, int x1, int y1, int channels, SampleType type, void* samples,
                              std::uint8_t* coverage) {
    // A tile service answering 429 or 5xx: GDAL 3.6's tile drivers fail the block at once and never read Retry-After.
    // The window is read again (it starts from nothing) after what web::busyWait learns from the server: its
    // Retry-After, else 1, 2 and 4 s; at most 3 times.
    for (int attempt = 0;; ++attempt) {
        Status st = readWarpedOnce(x0, y0, x1, y1, channels, type, samples, coverage);
        if (st || attempt == 3) return st;
        std::optional<double> wait;
        for (const WarpTile& t : m_impl->tiles)
            if (st.message().rfind(t.info.path.string() + ":", 0) == 0) {
                wait = web::busyWait(t.info.path, st.message(), double(1 << attempt));
                break;
            }
        if (!wait) return st;
        std::this_thread::sleep_for(std::chrono::duration<double>(*wait));
    }
}

Status GridReader::readWarpedOnce(int x0, int y0, int x1, int y1, int channels, SampleType type, void* samples,
                                  std::uint8_t* coverage) {
    Impl& impl = *m_impl;
    const int rows = y1 - y0, cols = x1 - x0;
    const TexelWindow window{x0, y0, x1, y1};
    const size_t pixels = size_t(rows) * size_t(cols);
    const int sample = bytesOf(type);
    std::memset(samples, 0, pixels * size_t(channels) * size_t(sample));
    std::vector<std::uint8_t> ownCoverage;
    if (!coverage) {
        ownCoverage.resize(pixels);
        coverage = ownCoverage.data();
    }
    std::memset(coverage, 0, pixels);

    const Georef& g = impl.grid.georef;
    double geo[6] = {g.origin.x + g.pixelSize.x * x0, g.pixelSize.x, 0.0, g.origin.y - g.pixelSize.y * y0, 0.0,
                     -g.pixelSize.y};
    // For GDAL's warper (average, cubic, lanczos): the window as a GDAL dataset over our buffers, bands 1..channels
    // the samples, band channels+1 the coverage; made when a tile needs it.
    gdal::Dataset band;
    auto memBand = [&]() -> Status {
        if (band) return Ok{};
        GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
        band.reset(mem->Create("", cols, rows, 0, GDT_Byte, nullptr));
        if (!band) return Error{"cannot create the warp's band of rows (out of memory?)"};
        auto addBand = [&](void* data, GDALDataType t, int pixelBytes, int lineBytes) {
            char ptr[64], pix[32], line[32];
            std::snprintf(ptr, sizeof ptr, "DATAPOINTER=%p", data);
            std::snprintf(pix, sizeof pix, "PIXELOFFSET=%d", pixelBytes);
            std::snprintf(line, sizeof line, "LINEOFFSET=%d", lineBytes);
            const char* options[] = {ptr, pix, line, nullptr};
            return band->AddBand(t, const_cast<char**>(options)) == CE_None;
        };
        const GDALDataType gt = gdal::gdalTypeOf(type);
        for (int c = 0; c < channels; ++c)
            if (!addBand(static_cast<std::uint8_t*>(samples) + size_t(c) * size_t(sample), gt, sample * channels,
                         sample * channels * cols))
                return Error{"cannot create the warp's band of rows"};
        if (!addBand(coverage, GDT_Byte, 1, cols)) return Error{"cannot create the warp's band of rows"};
        band->SetGeoTransform(geo);
        return Ok{};
    };

    for (WarpTile& t : impl.tiles) {
        if (t.row1 <= y0 || t.row0 >= y1 || t.col1 <= x0 || t.col0 >= x1) continue;
        const std::string name = t.info.path.string();
        gdal::ErrorCapture errors;
        if (!t.ds) {
            const char* open[] = {"NUM_THREADS=ALL_CPUS", nullptr};
            const web::RemoteOpen quiet(t.info.path);
            t.ds.reset(GDALDataset::FromHandle(GDALOpenEx(t.info.path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY,
                                                          nullptr, open, nullptr)));
            if (!t.ds) return fileError(name, "cannot be opened again (" + errors.message() + ")");
            const std::string srcSrs = "SRC_SRS=" + t.info.georef->crs.wkt();
            const std::string dstSrs = "DST_SRS=" + impl.gridWkt;
            const char* options[] = {srcSrs.c_str(), dstSrs.c_str(), nullptr};
            t.transform = GDALCreateGenImgProjTransformer2(GDALDataset::ToHandle(t.ds.get()), nullptr,
                                                           const_cast<char**>(options));
            if (!t.transform) return fileError(name, "no transformation into the grid's CRS (" + errors.message() + ")");
            t.approx = GDALCreateApproxTransformer(GDALGenImgProjTransform, t.transform, 0.125);
        }
        if (t.ownKernel) {
            if (auto st = ownWarp(t, impl.grid, window, channels, type, samples, coverage); !st) return st;
            continue;
        }
        if (auto st = memBand(); !st) return st;
        GDALSetGenImgProjTransformerDstGeoTransform(t.transform, geo);
        GDALWarpOptions* o = GDALCreateWarpOptions();
        o->hSrcDS = GDALDataset::ToHandle(t.ds.get());
        o->hDstDS = GDALDataset::ToHandle(band.get());
        o->nBandCount = channels;
        o->panSrcBands = static_cast<int*>(CPLMalloc(sizeof(int) * size_t(channels)));
        o->panDstBands = static_cast<int*>(CPLMalloc(sizeof(int) * size_t(channels)));
        for (int c = 0, src = 1; c < channels; ++c, ++src) {
            if (src == t.info.alphaBand) ++src;
            o->panSrcBands[c] = src;
            o->panDstBands[c] = c + 1;
        }
        o->nSrcAlphaBand = t.info.alphaBand;
        o->nDstAlphaBand = channels + 1;
        o->eResampleAlg = t.alg;
        o->dfWarpMemoryLimit = 256.0 * 1024 * 1024;
        o->pfnTransformer = GDALApproxTransform;
        o->pTransformerArg = t.approx;
        if (t.info.nodataKind == NodataKind::Value && t.info.nodata) {
            o->padfSrcNoDataReal = static_cast<double*>(CPLMalloc(sizeof(double) * size_t(channels)));
            for (int c = 0; c < channels; ++c) o->padfSrcNoDataReal[c] = *t.info.nodata;
        }
        o->papszWarpOptions = CSLSetNameValue(o->papszWarpOptions, "NUM_THREADS", "ALL_CPUS");
        o->papszWarpOptions = CSLSetNameValue(o->papszWarpOptions, "UNIFIED_SRC_NODATA", "YES");
        o->papszWarpOptions = CSLSetNameValue(o->papszWarpOptions, "SKIP_NOSOURCE", "YES");
        GDALWarpOperation op;
        CPLErr err = op.Initialize(o);
        const int r0 = std::max(t.row0, y0) - y0, r1 = std::min(t.row1, y1) - y0;
        const int c0 = std::max(t.col0, x0) - x0, c1 = std::min(t.col1, x1) - x0;
        if (err == CE_None) err = op.ChunkAndWarpImage(c0, r0, c1 - c0, r1 - r0);
        GDALDestroyWarpOptions(o);
        if (err != CE_None || errors.lostData()) return gdal::readFailure(name, errors, -1, -1);
    }
    // Coverage is binary: a pixel more than half covered by data is data.
    auto* bytes = static_cast<std::uint8_t*>(samples);
    const size_t pixelBytes = size_t(channels) * size_t(sample);
    for (size_t i = 0; i < pixels; ++i) {
        if (coverage[i] >= 128) {
            coverage[i] = 255;
        } else {
            coverage[i] = 0;
            std::memset(bytes + i * pixelBytes, 0, pixelBytes);
        }
    }
    return Ok{};
}

} // namespace seasonview
