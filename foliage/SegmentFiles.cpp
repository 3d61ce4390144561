#include "SegmentFiles.h"

#include "AtomicFile.h"
#include "BandReader.h"
#include "CrownCentres.h"
#include "GeoTiffStreamWriter.h"
#include "GridReader.h"
#include "ImageStreamWriter.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <future>
#include <memory>
#include <span>
#include <sstream>
#include <thread>

#include <sys/mman.h>

namespace seasonview {

namespace {

using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Rows of an image in increasing order, any ranges, as 8-bit samples of its first `channels` channels: read a band at
// a time through BandReader; 16-bit samples go through the layer's stretch (tables built once), other non-8-bit
// samples (truth masks) become 255 where non-zero. `rgba`: a pyramid's premultiplied RGBA level 0, read as RGB and
// its alpha (the season's coverage) given separately.
class RowReader {
public:
    static Result<RowReader> open(const std::filesystem::path& path, int channels, const Stretch* stretch,
                                  int preferredRows, bool rgba = false) {
        auto reader = BandReader::open(path, preferredRows);
        if (!reader) return reader.error();
        if (reader->channels() < channels + (rgba ? 1 : 0))
            return fileError(path.string(), "needs " + std::to_string(channels + (rgba ? 1 : 0)) + " channels, has " +
                                                std::to_string(reader->channels()));
        RowReader r(std::move(*reader));
        r.m_channels = channels;
        r.m_rgba = rgba;
        r.m_sixteen = r.m_reader.type() != SampleType::U8;
        if (r.m_sixteen) {
            r.m_lut.resize(size_t(channels) * 65536);
            for (int c = 0; c < channels; ++c)
                for (int v = 0; v < 65536; ++v)
                    r.m_lut[size_t(c) * 65536 + size_t(v)] = stretch ? stretch->apply(c, float(v)) : (v ? 255 : 0);
        } else if (stretch && !stretch->identity && !rgba) {
            // 8-bit samples through a stretch (--stretch percentile): tables of 256.
            r.m_lut8.resize(size_t(channels) * 256);
            for (int c = 0; c < channels; ++c)
                for (int v = 0; v < 256; ++v) r.m_lut8[size_t(c) * 256 + size_t(v)] = stretch->apply(c, float(v));
        }
        return r;
    }

    /// Rows [y0, y1) into `out` (rows × width × channels bytes) and, for an RGBA reader, their alpha into `alpha`
    /// (rows × width bytes). y0 must not lie before the band of the last call.
    Status read(int y0, int y1, std::uint8_t* out, std::uint8_t* alpha = nullptr) {
        assert((alpha != nullptr) == m_rgba && "RowReader::read(): alpha is read from RGBA readers alone");
        const size_t rowBytes = size_t(m_reader.width()) * size_t(m_channels);
        for (int y = y0; y < y1;) {
            const int bandEnd = std::min(m_reader.height(), y + m_reader.bandRows());
            if (!m_sixteen && !m_rgba && m_lut8.empty() && y % m_reader.bandRows() == 0 && bandEnd <= y1 &&
                (y < m_band0 || y >= m_band1)) {
                // A whole band wanted and not loaded: straight into `out`, no copy.
                if (auto st = m_reader.read(y, bandEnd, m_channels, SampleType::U8, out + size_t(y - y0) * rowBytes);
                    !st)
                    return st;
                y = bandEnd;
                continue;
            }
            if (y >= m_band1 || y < m_band0) {
                m_band0 = y - y % m_reader.bandRows();
                m_band1 = std::min(m_reader.height(), m_band0 + m_reader.bandRows());
                if (auto st = load(); !st) return st;
            }
            const int n = std::min(y1, m_band1) - y;
            std::memcpy(out + size_t(y - y0) * rowBytes, m_band.data() + size_t(y - m_band0) * rowBytes,
                        size_t(n) * rowBytes);
            if (alpha)
                std::memcpy(alpha + size_t(y - y0) * size_t(m_reader.width()),
                            m_alpha.data() + size_t(y - m_band0) * size_t(m_reader.width()),
                            size_t(n) * size_t(m_reader.width()));
            y += n;
        }
        return Ok{};
    }

private:
    explicit RowReader(BandReader r) : m_reader(std::move(r)) {}

public:
    int width() const { return m_reader.width(); }

private:

    Status load() {
        const size_t samples = size_t(m_band1 - m_band0) * size_t(m_reader.width()) * size_t(m_channels);
        m_band.resize(samples);
        if (m_rgba) {
            const size_t pixels = samples / size_t(m_channels);
            m_raw8.resize(pixels * size_t(m_channels + 1));
            m_alpha.resize(pixels);
            if (auto st = m_reader.read(m_band0, m_band1, m_channels + 1, SampleType::U8, m_raw8.data()); !st) return st;
            const size_t in = size_t(m_channels) + 1, outc = size_t(m_channels);
            for (size_t i = 0; i < pixels; ++i) {
                for (size_t c = 0; c < outc; ++c) m_band[i * outc + c] = m_raw8[i * in + c];
                m_alpha[i] = m_raw8[i * in + outc];
            }
            return Ok{};
        }
        if (!m_sixteen) {
            if (auto st = m_reader.read(m_band0, m_band1, m_channels, SampleType::U8, m_band.data()); !st) return st;
            if (!m_lut8.empty()) {
                const size_t ch = size_t(m_channels);
                for (size_t i = 0; i < samples; ++i) m_band[i] = m_lut8[(i % ch) * 256 + m_band[i]];
            }
            return Ok{};
        }
        m_raw.resize(samples);
        if (auto st = m_reader.read(m_band0, m_band1, m_channels, SampleType::U16, m_raw.data()); !st) return st;
        const size_t ch = size_t(m_channels);
        for (size_t i = 0; i < samples; ++i) m_band[i] = m_lut[(i % ch) * 65536 + m_raw[i]];
        return Ok{};
    }

    BandReader m_reader;
    int m_channels = 3;
    bool m_sixteen = false;
    bool m_rgba = false;
    std::vector<std::uint8_t> m_raw8, m_alpha; // RGBA: the band as read, its alpha
    std::vector<std::uint8_t> m_lut;  // per channel, 65536 entries
    std::vector<std::uint8_t> m_lut8; // 8-bit samples through a stretch: per channel, 256 entries
    std::vector<std::uint16_t> m_raw;
    std::vector<std::uint8_t> m_band;
    int m_band0 = 0, m_band1 = 0;
};

// Reads the same rows of both seasons, the leaf-off one on a second thread. With `valid` (RGBA readers: the pair's
// pyramid level 0), 255 where both seasons have data, else 0.
Status readPair(RowReader& on, RowReader& off, int y0, int y1, std::uint8_t* onOut, std::uint8_t* offOut,
                std::uint8_t* valid = nullptr) {
    const size_t n = size_t(y1 - y0) * size_t(on.width());
    std::vector<std::uint8_t> alphaOff(valid ? n : 0);
    Status offStatus = Ok{};
    std::thread t([&] { offStatus = off.read(y0, y1, offOut, valid ? alphaOff.data() : nullptr); });
    Status onStatus = on.read(y0, y1, onOut, valid);
    t.join();
    if (!onStatus) return onStatus;
    if (!offStatus) return offStatus;
    if (valid)
        for (size_t i = 0; i < n; ++i) valid[i] = valid[i] && alphaOff[i] ? 255 : 0;
    return Ok{};
}

// Bytes that are not zeroed when they grow: every byte of the window is read into before it is used, and zeroing
// the whole held pair (hundreds of MB) would cost as much as a tenth of decoding it. Large buffers ask for
// transparent huge pages: first touching the held pair's 400 MB in 4 KiB pages cost more than decoding it from
// Zstandard on this (virtualised) machine, 100,000 page faults against 200.
class ByteBuffer {
public:
    std::uint8_t* data() { return m_data.get(); }
    size_t size() const { return m_size; }
    void reserve(size_t n) {
        if (n <= m_capacity) return;
        constexpr size_t kHuge = size_t(2) << 20;
        const size_t bytes = n >= 4 * kHuge ? (n + kHuge - 1) / kHuge * kHuge : n;
        Memory grown(static_cast<std::uint8_t*>(n >= 4 * kHuge ? std::aligned_alloc(kHuge, bytes) : std::malloc(n)));
        if (!grown) throw std::bad_alloc();
#ifdef MADV_HUGEPAGE
        if (n >= 4 * kHuge) ::madvise(grown.get(), bytes, MADV_HUGEPAGE); // advice only: failure is harmless
#endif
        if (m_size) std::memcpy(grown.get(), m_data.get(), m_size);
        m_data = std::move(grown);
        m_capacity = n;
    }
    void resize(size_t n) {
        if (n > m_capacity) reserve(std::max(n, 2 * m_capacity));
        m_size = n;
    }

private:
    struct Free {
        void operator()(std::uint8_t* p) const { std::free(p); }
    };
    using Memory = std::unique_ptr<std::uint8_t, Free>;
    Memory m_data;
    size_t m_size = 0, m_capacity = 0;
};

// Rows [first, last) of both seasons held in memory; the window slides down the image.
// Rows [first, last) of both seasons held in memory, and (withValid) where both have data; the window slides down
// the image.
struct PairWindow {
    ByteBuffer on, off, valid;
    int first = 0, last = 0, width = 0;
    bool withValid = false;

    const std::uint8_t* validRows(int row) { return withValid ? valid.data() + size_t(row - first) * size_t(width) : nullptr; }

    Status slide(RowReader& onReader, RowReader& offReader, int newFirst, int newLast) {
        const size_t rowBytes = size_t(width) * 3;
        if (newFirst > first) {
            const size_t keep = size_t(std::max(0, last - newFirst)) * rowBytes;
            std::memmove(on.data(), on.data() + size_t(newFirst - first) * rowBytes, keep);
            std::memmove(off.data(), off.data() + size_t(newFirst - first) * rowBytes, keep);
            if (withValid)
                std::memmove(valid.data(), valid.data() + size_t(newFirst - first) * size_t(width), keep / 3);
            first = newFirst;
            last = std::max(last, first);
        }
        if (newLast <= last) return Ok{};
        on.resize(size_t(newLast - first) * rowBytes);
        off.resize(size_t(newLast - first) * rowBytes);
        if (withValid) valid.resize(size_t(newLast - first) * size_t(width));
        const size_t at = size_t(last - first) * rowBytes;
        if (auto st = readPair(onReader, offReader, last, newLast, on.data() + at, off.data() + at,
                               withValid ? valid.data() + at / 3 : nullptr);
            !st)
            return st;
        last = newLast;
        return Ok{};
    }
};

// The truth mask's rows on the working grid, as 0/255, and where it has data: a raster without georeferencing must
// have the grid's size (its pixels are the grid's); a georeferenced one is read on the grid (nearest neighbour, as
// it is when it is the grid), 0 where it does not reach.
class TruthRows {
public:
    static Result<TruthRows> open(const std::filesystem::path& path, const WorkingGrid& grid, int preferredRows) {
        auto info = readRasterInfo(path);
        if (!info) return info.error();
        TruthRows t;
        t.m_width = grid.width;
        if (!info->georef) {
            if (info->width != grid.width || info->height != grid.height)
                return fileError(path.string(), "truth mask is " + std::to_string(info->width) + "x" +
                                                    std::to_string(info->height) + " pixels but the imagery is " +
                                                    std::to_string(grid.width) + "x" + std::to_string(grid.height) +
                                                    " (a truth mask on another grid needs georeferencing)");
            auto r = RowReader::open(path, 1, nullptr, preferredRows);
            if (!r) return r.error();
            t.m_plain.emplace(std::move(*r));
            return t;
        }
        auto mosaic = openMosaic(SourceList(path), "truth");
        if (!mosaic) return mosaic.error();
        auto r = GridReader::open(*mosaic, grid, Resampling::Nearest, preferredRows);
        if (!r) return r.error();
        t.m_complete = r->direct();
        t.m_grid.emplace(std::move(*r));
        return t;
    }
    /// Whether the truth covers every pixel (then the coverage read is all 255).
    bool complete() const { return m_complete; }

    /// Rows [y0, y1) (increasing from call to call): `truth` 255 where the truth is non-zero, `covered` 255 where it
    /// has data.
    Status read(int y0, int y1, std::uint8_t* truth, std::uint8_t* covered) {
        const size_t n = size_t(y1 - y0) * size_t(m_width);
        if (m_plain) {
            std::memset(covered, 255, n);
            return m_plain->read(y0, y1, truth);
        }
        const int band = m_grid->bandRows();
        for (int y = y0; y < y1;) {
            if (y < m_band0 || y >= m_band1) {
                m_band0 = y - y % band;
                m_band1 = std::min(m_grid->height(), m_band0 + band);
                const size_t pixels = size_t(m_band1 - m_band0) * size_t(m_width);
                m_values.resize(pixels);
                m_covered.resize(pixels);
                if (auto st = m_grid->read(m_band0, m_band1, 1, SampleType::U8, m_values.data(), m_covered.data()); !st)
                    return st;
                for (std::uint8_t& v : m_values) v = v ? 255 : 0;
            }
            const int rows = std::min(y1, m_band1) - y;
            const size_t at = size_t(y - m_band0) * size_t(m_width), to = size_t(y - y0) * size_t(m_width);
            std::memcpy(truth + to, m_values.data() + at, size_t(rows) * size_t(m_width));
            std::memcpy(covered + to, m_covered.data() + at, size_t(rows) * size_t(m_width));
            y += rows;
        }
        return Ok{};
    }

private:
    std::optional<RowReader> m_plain;
    std::optional<GridReader> m_grid;
    std::vector<std::uint8_t> m_values, m_covered;
    int m_width = 0, m_band0 = 0, m_band1 = 0;
    bool m_complete = true;
};

// One output image: a PNG (or other plain image) through ImageStreamWriter, or a GeoTIFF on the scene's working grid
// through GeoTiffStreamWriter (tiled, deflate, with the grid's georeferencing and, for masks, nodata 255).
class OutputImage {
public:
    static Result<OutputImage> open(const std::filesystem::path& path, int w, int h, int channels, bool mask,
                                    const Georef& grid) {
        OutputImage o;
        if (isTiff(path)) {
            GeoTiffWriteOptions options;
            options.compression = TiffCompression::Deflate;
            if (mask) options.nodata = double(kMaskNodata);
            auto writer = GeoTiffStreamWriter::open(path, w, h, channels, SampleType::U8, grid, options);
            if (!writer) return writer.error();
            o.m_tiff.emplace(std::move(*writer));
        } else {
            auto writer = ImageStreamWriter::open(path, w, h, channels, mask ? ImageEncoding::FastMask
                                                                             : ImageEncoding::Default);
            if (!writer) return writer.error();
            o.m_plain.emplace(std::move(*writer));
        }
        return o;
    }
    bool geotiff() const { return m_tiff.has_value(); }
    Status writeRows(int y0, int rows, const std::uint8_t* data) {
        return m_tiff ? m_tiff->writeRows(y0, rows, data) : m_plain->writeRows(y0, rows, data);
    }
    Status finish() { return m_tiff ? m_tiff->finish() : m_plain->finish(); }

    static bool isTiff(const std::filesystem::path& p) {
        std::string e = p.extension().string();
        for (char& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
        return e == ".tif" || e == ".tiff";
    }

private:
    std::optional<GeoTiffStreamWriter> m_tiff;
    std::optional<ImageStreamWriter> m_plain;
};

std::vector<std::string> splitCsv(const std::string& line) {
    std::vector<std::string> out;
    std::string cell;
    std::istringstream s(line);
    while (std::getline(s, cell, ',')) {
        while (!cell.empty() && (cell.back() == '\r' || cell.back() == ' ')) cell.pop_back();
        out.push_back(cell);
    }
    return out;
}

// Metres per pixel for crown sizes: the geometric mean of the pixel's width and height in the local frame at the
// image centre (they differ for geographic imagery, whose pixels are square in degrees; the distance transform
// treats pixels as square).
double pixelMetres(const Scene& scene) {
    const Georef& g = scene.grid.georef;
    const glm::dvec2 c(scene.grid.width * 0.5, scene.grid.height * 0.5);
    const glm::dvec3 p0 = scene.frame.toLocal(g.crs, g.pixelToCrs(c));
    const glm::dvec3 px = scene.frame.toLocal(g.crs, g.pixelToCrs(c + glm::dvec2(1.0, 0.0)));
    const glm::dvec3 py = scene.frame.toLocal(g.crs, g.pixelToCrs(c + glm::dvec2(0.0, 1.0)));
    return std::sqrt(glm::length(glm::dvec2(px - p0)) * glm::length(glm::dvec2(py - p0)));
}

// The crown list as CSV rows: the pixel centre in the scene's local frame, in the working grid's CRS (easting,
// northing; the .prj written next to the file names it) and in WGS 84 (lon, lat).
std::string crownCsv(const Scene& scene, const std::vector<CrownDetection>& crowns, std::vector<CrownPoint>& local) {
    const Georef& g = scene.grid.georef;
    const bool geographic = g.crs.isGeographic();
    const double metres = pixelMetres(scene);
    std::string text = "id,x,y,easting,northing,radius_m,lon,lat\n";
    char line[200];
    local.clear();
    local.reserve(crowns.size());
    std::vector<glm::dvec2> lonLat(crowns.size());
    for (size_t i = 0; i < crowns.size(); ++i) lonLat[i] = g.pixelToCrs({crowns[i].px, crowns[i].py});
    convert(g.crs, Crs::geographic(), std::span<glm::dvec2>(lonLat));
    for (size_t i = 0; i < crowns.size(); ++i) {
        const glm::dvec2 crs = g.pixelToCrs({crowns[i].px, crowns[i].py});
        const glm::dvec3 p = scene.frame.toLocal(g.crs, crs);
        const double r = crowns[i].radiusPx * metres;
        local.push_back({p.x, p.y, r});
        const char* format = geographic ? "%zu,%.3f,%.3f,%.8f,%.8f,%.3f,%.8f,%.8f\n"
                                        : "%zu,%.3f,%.3f,%.3f,%.3f,%.3f,%.8f,%.8f\n";
        std::snprintf(line, sizeof line, format, i + 1, p.x, p.y, crs.x, crs.y, r, lonLat[i].x, lonLat[i].y);
        text += line;
    }
    return text;
}

bool isGeoJson(const std::filesystem::path& p) {
    std::string e = p.extension().string();
    for (char& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
    return e == ".geojson" || e == ".json";
}

// The crowns as a GeoJSON FeatureCollection of points in WGS 84 (RFC 7946), each with its id, local x/y, the
// working grid's easting/northing and radius.
std::string crownGeoJson(const Scene& scene, const std::vector<CrownDetection>& crowns,
                         const std::vector<CrownPoint>& local) {
    const Georef& g = scene.grid.georef;
    std::vector<glm::dvec2> grid(crowns.size()), lonLat(crowns.size());
    for (size_t i = 0; i < crowns.size(); ++i) grid[i] = lonLat[i] = g.pixelToCrs({crowns[i].px, crowns[i].py});
    convert(g.crs, Crs::geographic(), std::span<glm::dvec2>(lonLat));
    std::string text = "{\"type\": \"FeatureCollection\", \"features\": [\n";
    char line[400];
    for (size_t i = 0; i < crowns.size(); ++i) {
        std::snprintf(line, sizeof line,
                      "%s{\"type\": \"Feature\", \"geometry\": {\"type\": \"Point\", \"coordinates\": [%.8f, %.8f]}, "
                      "\"properties\": {\"id\": %zu, \"x\": %.3f, \"y\": %.3f, \"easting\": %.3f, \"northing\": %.3f, "
                      "\"radius_m\": %.3f}}",
                      i ? ",\n" : "", lonLat[i].x, lonLat[i].y, i + 1, local[i].x, local[i].y, grid[i].x, grid[i].y,
                      local[i].radiusM);
        text += line;
    }
    return text + "\n]}\n";
}

void drawOverlay(const std::uint8_t* onRgb, const std::uint8_t* mask, const std::uint8_t* truth, size_t n,
                 std::uint8_t* out) {
    for (size_t i = 0; i < n; ++i) {
        const bool m = mask[i] != 0, t = truth && truth[i] != 0;
        const std::uint8_t* colour = m && (t || !truth) ? kOverlayTruePositive
                                     : m                ? kOverlayFalsePositive
                                     : t                ? kOverlayFalseNegative
                                                        : nullptr;
        for (size_t c = 0; c < 3; ++c)
            out[i * 3 + c] = colour ? std::uint8_t((onRgb[i * 3 + c] + colour[c] + 1) / 2) : onRgb[i * 3 + c];
    }
}

} // namespace

Result<std::vector<CrownPoint>> readTrueTrees(const std::filesystem::path& csv) {
    std::ifstream f(csv);
    if (!f) return fileError(csv.string(), std::filesystem::exists(csv) ? "cannot read file" : "file not found");
    std::string line;
    if (!std::getline(f, line)) return fileError(csv.string(), "empty file (expected a header with x, y, radius_m)");
    const std::vector<std::string> header = splitCsv(line);
    auto column = [&](const char* name) {
        auto it = std::find(header.begin(), header.end(), name);
        return it == header.end() ? -1 : int(it - header.begin());
    };
    const int cx = column("x"), cy = column("y"), cr = column("radius_m"), ct = column("type");
    if (cx < 0 || cy < 0 || cr < 0) return fileError(csv.string(), "header needs columns x, y and radius_m");
    std::vector<CrownPoint> trees;
    for (int n = 2; std::getline(f, line); ++n) {
        if (line.empty() || line == "\r") continue;
        const std::vector<std::string> cells = splitCsv(line);
        if (int(cells.size()) < int(header.size()))
            return fileError(csv.string(), "line " + std::to_string(n) + ": " + std::to_string(cells.size()) +
                                               " columns, header has " + std::to_string(header.size()));
        if (ct >= 0 && cells[size_t(ct)] != "deciduous") continue;
        CrownPoint p;
        auto number = [&](int index, double& out) {
            const std::string& cell = cells[size_t(index)];
            try {
                size_t used = 0;
                out = std::stod(cell, &used);
                return used == cell.size() && std::isfinite(out);
            } catch (const std::exception&) {
                return false;
            }
        };
        if (!number(cx, p.x) || !number(cy, p.y) || !number(cr, p.radiusM))
            return fileError(csv.string(), "line " + std::to_string(n) + ": x, y and radius_m must be numbers");
        if (!(p.radiusM >= 0.0)) return fileError(csv.string(), "line " + std::to_string(n) + ": negative radius_m");
        trees.push_back(p);
    }
    return trees;
}

const char* statsSourceName(StatsSource source) {
    switch (source) {
    case StatsSource::None: return "none";
    case StatsSource::Given: return "given";
    case StatsSource::HeldPair: return "held pair";
    case StatsSource::HistogramPass: return "histogram pass";
    }
    return "?";
}

namespace {

using ReaderPair = std::pair<RowReader, RowReader>;

// The pair's statistics (equalized, default): given, from the pair held whole in `window` (which then never slides),
// or from a first streamed pass, after which `pair` is opened again (the readers only go forward). Sets the report's
// stats, statsSource, heldInMemory, inputPasses and the seconds spent.
Status pairStatistics(const SegmentJob& job, int w, int h, int preferredRows, bool fromLevelZero,
                      const std::function<Result<ReaderPair>()>& openPair, ReaderPair& pair, PairWindow& window,
                      SegmentReport& report) {
    const SegmentationParams& params = job.params;
    const bool colour = params.method == SegmentationMethod::Equalized;
    const bool drop = params.method == SegmentationMethod::Default;
    const std::uint64_t pairBytes = 2 * std::uint64_t(w) * std::uint64_t(h) * 3;
    if (!needsHistograms(params.method)) {
        report.statsSource = StatsSource::None;
    } else if (job.histograms) {
        report.statsSource = StatsSource::Given;
        report.stats = statsFromHistograms(*job.histograms, params.method);
    } else if (pairBytes <= job.memoryBudget) {
        // Decoded once and held: the window grows to the whole image and never slides.
        report.statsSource = StatsSource::HeldPair;
        report.heldInMemory = true;
        window.on.reserve(pairBytes / 2);
        window.off.reserve(pairBytes / 2);
        if (fromLevelZero) window.valid.reserve(pairBytes / 6);
        SegmentationHistograms hist;
        const size_t rowBytes = size_t(w) * 3;
        for (int y0 = 0; y0 < h; y0 += preferredRows) {
            const int y1 = std::min(h, y0 + preferredRows);
            auto t = Clock::now();
            if (auto st = window.slide(pair.first, pair.second, 0, y1); !st) return st;
            report.readSeconds += secondsSince(t);
            t = Clock::now(); // each band's histograms while its rows are still in cache
            RgbRows rows{window.on.data() + size_t(y0) * rowBytes, window.off.data() + size_t(y0) * rowBytes, w, h, y0,
                         y1 - y0};
            rows.valid = window.validRows(y0);
            hist.merge(rowHistograms(rows, colour, drop));
            report.segmentSeconds += secondsSince(t);
            if (job.progress) job.progress(0.5 * y1 / h, "reading");
        }
        report.stats = statsFromHistograms(hist, params.method);
    } else {
        // Too large to hold: a first pass over both files for the histograms, band by band.
        report.statsSource = StatsSource::HistogramPass;
        report.inputPasses = 2;
        SegmentationHistograms hist;
        std::vector<std::uint8_t> on, off, valid;
        for (int y0 = 0; y0 < h; y0 += job.bandRows) {
            const int y1 = std::min(h, y0 + job.bandRows);
            on.resize(size_t(y1 - y0) * size_t(w) * 3);
            off.resize(on.size());
            valid.resize(fromLevelZero ? size_t(y1 - y0) * size_t(w) : 0);
            auto t = Clock::now();
            if (auto st = readPair(pair.first, pair.second, y0, y1, on.data(), off.data(),
                                   fromLevelZero ? valid.data() : nullptr);
                !st)
                return st;
            report.readSeconds += secondsSince(t);
            t = Clock::now();
            RgbRows rows{on.data(), off.data(), w, h, y0, y1 - y0};
            rows.valid = fromLevelZero ? valid.data() : nullptr;
            hist.merge(rowHistograms(rows, colour, drop));
            report.segmentSeconds += secondsSince(t);
            if (job.progress) job.progress(0.3 * y1 / h, "histograms");
        }
        report.stats = statsFromHistograms(hist, params.method);
        auto again = openPair(); // the readers only go forward
        if (!again) return again.error();
        pair = std::move(*again);
    }
    return Ok{};
}

// The crowns found, as `path` asks (GeoJSON, or CSV with the CRS of its easting/northing columns in a .prj beside it,
// as GIS tools read it); nothing when `path` is empty.
Status writeCrownTable(const Scene& scene, const std::filesystem::path& path, const std::vector<CrownDetection>& crowns,
                       const std::vector<CrownPoint>& local, const std::string& csv) {
    if (path.empty()) return Ok{};
    std::string err;
    if (isGeoJson(path)) {
        if (!writeTextAtomic(path, crownGeoJson(scene, crowns, local), err)) return fileError(path.string(), err);
        return Ok{};
    }
    if (!writeTextAtomic(path, csv, err)) return fileError(path.string(), err);
    const std::filesystem::path prj = std::filesystem::path(path).replace_extension(".prj");
    if (!writeTextAtomic(prj, scene.grid.georef.crs.esriWkt() + "\n", err)) return fileError(prj.string(), err);
    return Ok{};
}

// A band's overlay (drawOverlay) with the pixels where a season has no data (`valid` 0) as a grey checkerboard, as
// image editors show transparency. `n` pixels of rows from y0, `w` wide.
void drawOverlayBand(const std::uint8_t* onRgb, const std::uint8_t* mask, const std::uint8_t* truth,
                     const std::uint8_t* valid, int w, int y0, size_t n, std::uint8_t* out) {
    drawOverlay(onRgb, mask, truth, n, out);
    if (!valid) return;
    for (size_t i = 0; i < n; ++i)
        if (!valid[i]) {
            const size_t x = i % size_t(w), y = size_t(y0) + i / size_t(w);
            const std::uint8_t v = ((x / 8 + y / 8) % 2) ? 96 : 160;
            out[3 * i] = out[3 * i + 1] = out[3 * i + 2] = v;
        }
}

// Crown detection over the mask as its bands arrive (CrownCentres.h): the crowns lag the mask by their halo and wait
// for at least four halos of rows (each call transforms its rows plus a halo on both sides); the last band flushes
// them all.
class CrownStream {
public:
    CrownStream(int width, int height, const CrownParams& params, int haloRows)
        : m_width(width), m_height(height), m_params(params), m_halo(haloRows) {}
    /// The mask rows of the next band, ending at row y1.
    void add(const std::vector<std::uint8_t>& rows, int y1) {
        m_mask.insert(m_mask.end(), rows.begin(), rows.end());
        m_last = y1;
        const int done = y1 == m_height ? m_height : std::max(m_done, y1 - m_halo);
        if (done != m_height && done - m_done < 4 * m_halo) return;
        detectCrownRows(m_mask.data(), m_width, m_height, m_first, m_last - m_first, m_done, done - m_done, m_params,
                        crowns);
        m_done = done;
        const int keepFrom = std::max(m_first, m_done - m_halo);
        m_mask.erase(m_mask.begin(), m_mask.begin() + std::ptrdiff_t(keepFrom - m_first) * m_width);
        m_first = keepFrom;
    }
    std::vector<CrownDetection> crowns;

private:
    int m_width, m_height;
    CrownParams m_params;
    int m_halo;
    std::vector<std::uint8_t> m_mask; // mask rows [m_first, m_last) for the search
    int m_first = 0, m_last = 0, m_done = 0;
};

// What a segmentation reads and writes besides the pair, opened before any pixel work, inputs (the cheap checks)
// first: the truth mask and the true trees when given, the mask file and the overlay when asked for.
struct SegmentFilesOpen {
    std::optional<TruthRows> truth;
    std::optional<std::vector<CrownPoint>> trueTrees;
    std::optional<OutputImage> mask; // always there once open
    std::optional<OutputImage> overlay;
};

Result<SegmentFilesOpen> openSegmentFiles(const Scene& scene, const SegmentJob& job, int preferredRows) {
    const int w = scene.grid.width, h = scene.grid.height;
    SegmentFilesOpen f;
    if (!job.truth.empty()) {
        auto t = TruthRows::open(job.truth, scene.grid, preferredRows);
        if (!t) return t.error();
        f.truth = std::move(*t);
    }
    if (!job.truthTrees.empty()) {
        auto t = readTrueTrees(job.truthTrees);
        if (!t) return t.error();
        f.trueTrees = std::move(*t);
    }
    auto mask = OutputImage::open(job.mask, w, h, 1, true, scene.grid.georef);
    if (!mask) return mask.error();
    f.mask = std::move(*mask);
    if (!job.overlay.empty()) {
        auto o = OutputImage::open(job.overlay, w, h, 3, false, scene.grid.georef);
        if (!o) return o.error();
        f.overlay = std::move(*o);
    }
    return f;
}

// The two seasons' row readers: the scene's files through their stretch, or, for a warped pair, its prepared level 0
// (premultiplied RGBA: alpha is each season's coverage).
Result<std::pair<RowReader, RowReader>> openSeasonRows(const Scene& scene, const SegmentJob& job, int rows) {
    const bool fromLevelZero = job.levelZero.has_value();
    auto a = fromLevelZero ? RowReader::open((*job.levelZero)[0], 3, nullptr, rows, true)
                           : RowReader::open(scene.leafon.info.path, 3, &scene.leafon.stretch, rows);
    if (!a) return a.error();
    auto b = fromLevelZero ? RowReader::open((*job.levelZero)[1], 3, nullptr, rows, true)
                           : RowReader::open(scene.leafoff.info.path, 3, &scene.leafoff.stretch, rows);
    if (!b) return b.error();
    return std::make_pair(std::move(*a), std::move(*b));
}

// Pixels where a season has no data (`valid` 0; null: every pixel has both) are not canopy: cleared in `mask`.
// Returns how many there are.
std::uint64_t clearNoData(std::uint8_t* mask, const std::uint8_t* valid, size_t n) {
    if (!valid) return 0;
    std::uint64_t cleared = 0;
    for (size_t i = 0; i < n; ++i)
        if (!valid[i]) {
            mask[i] = 0;
            ++cleared;
        }
    return cleared;
}

} // namespace

Result<SegmentReport> segmentScene(const Scene& scene, const SegmentJob& job) {
    const auto start = Clock::now();
    const SegmentationParams& params = job.params;
    [[maybe_unused]] const int k = effectiveK(params);
    assert(k >= 1 && k <= kSegMaxK && k % 2 == 1 && "segmentScene(): k must be odd, 1..kSegMaxK");
    assert(!job.mask.empty() && job.bandRows > 0 && "segmentScene(): a mask path and a positive band height");
    assert((job.levelZero || !scene.warped()) && "segmentScene(): a warped scene is read from its prepared level 0");
    const int w = scene.grid.width, h = scene.grid.height;
    const int halo = segmentationHalo(params);
    const int bandRows = job.bandRows;
    SegmentReport report;
    report.width = w;
    report.height = h;
    auto progress = [&](double f, const char* stage) {
        if (job.progress) job.progress(f, stage);
    };

    // Inputs first (cheap checks), then the outputs, before any pixel work.
    // The readers' bands: at least the halo, so that a window never needs more than the bands around it.
    const int preferredRows = std::max({256, bandRows, 2 * halo});
    auto files = openSegmentFiles(scene, job, preferredRows);
    if (!files) return files.error();
    const bool withTruth = files->truth.has_value();
    std::optional<TruthRows>& truthReader = files->truth;
    const std::optional<std::vector<CrownPoint>>& trueTrees = files->trueTrees;
    const bool withCrowns = !job.trees.empty() || trueTrees.has_value();
    std::optional<OutputImage>& maskOut = files->mask;
    std::optional<OutputImage>& overlayOut = files->overlay;

    const CrownParams crownParams = crownParamsForGsd(pixelMetres(scene));
    const int crownHaloRows = withCrowns ? crownHalo(crownParams) : 0;
    const bool fromLevelZero = job.levelZero.has_value();
    auto openPair = [&] { return openSeasonRows(scene, job, preferredRows); };
    auto pair = openPair();
    if (!pair) return pair.error();

    PairWindow window;
    window.width = w;
    window.withValid = fromLevelZero;
    if (auto st = pairStatistics(job, w, h, preferredRows, fromLevelZero, openPair, *pair, window, report); !st)
        return st.error();
    const double done0 = report.heldInMemory ? 0.5 : report.inputPasses == 2 ? 0.3 : 0.0;

    // Bands of output rows with their halo. The mask and overlay of a band are encoded on a writer thread while the
    // next band is segmented (two buffers of each, taking turns).
    std::vector<std::uint8_t> mask[2], encoded[2], overlay[2], truth, truthCovered, scored;
    CrownStream crownStream(w, h, crownParams, crownHaloRows);
    const std::vector<CrownDetection>& crowns = crownStream.crowns;
    Confusion confusion;
    std::uint64_t nodataPixels = 0;
    double writerSeconds = 0.0; // the writer thread's own time
    // Declared after everything the writer thread touches: destroyed (joined) before them on an early return.
    std::future<Status> pendingWrite;
    auto waitForWriter = [&]() -> Status {
        if (!pendingWrite.valid()) return Ok{};
        return pendingWrite.get();
    };
    for (int y0 = 0, band = 0; y0 < h; y0 += bandRows, ++band) {
        const int y1 = std::min(h, y0 + bandRows), rows = y1 - y0;
        const size_t n = size_t(rows) * size_t(w);
        auto t = Clock::now();
        if (!report.heldInMemory)
            if (auto st = window.slide(pair->first, pair->second, std::max(0, y0 - halo), std::min(h, y1 + halo)); !st)
                return st.error();
        truth.resize(withTruth ? n : 0);
        truthCovered.resize(withTruth ? n : 0);
        if (withTruth)
            if (auto st = truthReader->read(y0, y1, truth.data(), truthCovered.data()); !st) return st.error();
        report.readSeconds += secondsSince(t);

        t = Clock::now();
        std::vector<std::uint8_t>& m = mask[band % 2];
        m.resize(n);
        RgbRows in{window.on.data(), window.off.data(), w, h, window.first, window.last - window.first};
        in.valid = window.validRows(window.first);
        segmentRows(in, y0, rows, params, report.stats, m.data());
        // Pixels where a season has no data are neither canopy nor background: not canopy for the crowns, left
        // out of the scores, their own value in the written mask.
        const std::uint8_t* valid = window.validRows(y0);
        nodataPixels += clearNoData(m.data(), valid, n);
        report.segmentSeconds += secondsSince(t);

        if (withTruth) {
            const std::uint8_t* score = valid;
            if (!truthReader->complete()) {
                scored.resize(n);
                for (size_t i = 0; i < n; ++i) scored[i] = truthCovered[i] && (!valid || valid[i]) ? 255 : 0;
                score = scored.data();
            }
            confusion.add(m.data(), truth.data(), n, score);
        }
        // The mask as written: GeoTIFF 1 canopy, 0 background, kMaskNodata without data; PNG 255 / 0.
        std::vector<std::uint8_t>& e = encoded[band % 2];
        const std::uint8_t* written = m.data();
        if (maskOut->geotiff()) {
            e.resize(n);
            for (size_t i = 0; i < n; ++i) e[i] = valid && !valid[i] ? kMaskNodata : m[i] ? 1 : 0;
            written = e.data();
        }
        std::vector<std::uint8_t>& o = overlay[band % 2];
        if (overlayOut) {
            t = Clock::now();
            o.resize(n * 3);
            drawOverlayBand(window.on.data() + size_t(y0 - window.first) * size_t(w) * 3, m.data(),
                            withTruth ? truth.data() : nullptr, valid, w, y0, n, o.data());
            report.writeSeconds += secondsSince(t);
        }
        // The writer of the previous band must be done before this band's turn (and its buffers are free again).
        if (auto st = waitForWriter(); !st) return st.error();
        pendingWrite = std::async(std::launch::async, [&, y0, rows, band, written]() -> Status {
            const auto t0 = Clock::now();
            if (auto st = maskOut->writeRows(y0, rows, written); !st) return st;
            if (overlayOut)
                if (auto st = overlayOut->writeRows(y0, rows, overlay[band % 2].data()); !st) return st;
            writerSeconds += secondsSince(t0);
            return Ok{};
        });

        if (withCrowns) {
            t = Clock::now();
            crownStream.add(m, y1);
            report.crownSeconds += secondsSince(t);
        }
        progress(done0 + (1.0 - done0) * y1 / h, "segmenting");
    }

    auto t = Clock::now();
    if (auto st = waitForWriter(); !st) return st.error();
    if (auto st = maskOut->finish(); !st) return st.error();
    if (overlayOut)
        if (auto st = overlayOut->finish(); !st) return st.error();
    std::vector<CrownPoint> local;
    const std::string csv = crownCsv(scene, crowns, local);
    if (auto st = writeCrownTable(scene, job.trees, crowns, local, csv); !st) return st.error();
    report.writeSeconds += writerSeconds + secondsSince(t);
    if (withTruth) report.confusion = confusion;
    report.nodataPixels = nodataPixels;
    report.crowns = int(crowns.size());
    if (trueTrees) report.centres = matchCentres(local, *trueTrees);
    report.totalSeconds = secondsSince(start);
    return report;
}

} // namespace seasonview
