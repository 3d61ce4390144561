#include "SegmentFiles.h"

#include "AtomicFile.h"
#include "BandReader.h"
#include "CrownCentres.h"
#include "ImageStreamWriter.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <future>
#include <memory>
#include <sstream>
#include <thread>

#include <sys/mman.h>

namespace seasonview {

namespace {

using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Rows of an image in increasing order, any ranges, as 8-bit samples of its first `channels` channels: read a band at
// a time through BandReader; 16-bit samples go through the layer's stretch (tables built once), other non-8-bit
// samples (truth masks) become 255 where non-zero.
class RowReader {
public:
    static Result<RowReader> open(const std::filesystem::path& path, int channels, const Stretch* stretch,
                                  int preferredRows) {
        auto reader = BandReader::open(path, preferredRows);
        if (!reader) return reader.error();
        if (reader->channels() < channels)
            return fileError(path.string(), "needs " + std::to_string(channels) + " channels, has " +
                                                std::to_string(reader->channels()));
        RowReader r(std::move(*reader));
        r.m_channels = channels;
        r.m_sixteen = r.m_reader.type() != SampleType::U8;
        if (r.m_sixteen) {
            r.m_lut.resize(size_t(channels) * 65536);
            for (int c = 0; c < channels; ++c)
                for (int v = 0; v < 65536; ++v)
                    r.m_lut[size_t(c) * 65536 + size_t(v)] = stretch ? stretch->apply(c, float(v)) : (v ? 255 : 0);
        }
        return r;
    }

    /// Rows [y0, y1) into `out` (rows × width × channels bytes). y0 must not lie before the band of the last call.
    Status read(int y0, int y1, std::uint8_t* out) {
        const size_t rowBytes = size_t(m_reader.width()) * size_t(m_channels);
        for (int y = y0; y < y1;) {
            const int bandEnd = std::min(m_reader.height(), y + m_reader.bandRows());
            if (!m_sixteen && y % m_reader.bandRows() == 0 && bandEnd <= y1 && (y < m_band0 || y >= m_band1)) {
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
            y += n;
        }
        return Ok{};
    }

private:
    explicit RowReader(BandReader r) : m_reader(std::move(r)) {}

    Status load() {
        const size_t samples = size_t(m_band1 - m_band0) * size_t(m_reader.width()) * size_t(m_channels);
        m_band.resize(samples);
        if (!m_sixteen) return m_reader.read(m_band0, m_band1, m_channels, SampleType::U8, m_band.data());
        m_raw.resize(samples);
        if (auto st = m_reader.read(m_band0, m_band1, m_channels, SampleType::U16, m_raw.data()); !st) return st;
        const size_t ch = size_t(m_channels);
        for (size_t i = 0; i < samples; ++i) m_band[i] = m_lut[(i % ch) * 65536 + m_raw[i]];
        return Ok{};
    }

    BandReader m_reader;
    int m_channels = 3;
    bool m_sixteen = false;
    std::vector<std::uint8_t> m_lut; // per channel, 65536 entries
    std::vector<std::uint16_t> m_raw;
    std::vector<std::uint8_t> m_band;
    int m_band0 = 0, m_band1 = 0;
};

// Reads the same rows of both seasons, the leaf-off one on a second thread.
Status readPair(RowReader& on, RowReader& off, int y0, int y1, std::uint8_t* onOut, std::uint8_t* offOut) {
    Status offStatus = Ok{};
    std::thread t([&] { offStatus = off.read(y0, y1, offOut); });
    Status onStatus = on.read(y0, y1, onOut);
    t.join();
    return onStatus ? offStatus : onStatus;
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
struct PairWindow {
    ByteBuffer on, off;
    int first = 0, last = 0, width = 0;

    Status slide(RowReader& onReader, RowReader& offReader, int newFirst, int newLast) {
        const size_t rowBytes = size_t(width) * 3;
        if (newFirst > first) {
            const size_t keep = size_t(std::max(0, last - newFirst)) * rowBytes;
            std::memmove(on.data(), on.data() + size_t(newFirst - first) * rowBytes, keep);
            std::memmove(off.data(), off.data() + size_t(newFirst - first) * rowBytes, keep);
            first = newFirst;
            last = std::max(last, first);
        }
        if (newLast <= last) return Ok{};
        on.resize(size_t(newLast - first) * rowBytes);
        off.resize(size_t(newLast - first) * rowBytes);
        const size_t at = size_t(last - first) * rowBytes;
        if (auto st = readPair(onReader, offReader, last, newLast, on.data() + at, off.data() + at); !st) return st;
        last = newLast;
        return Ok{};
    }
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
    const Georef& g = *scene.leafon.info.georef;
    const glm::dvec2 c(scene.leafon.info.width * 0.5, scene.leafon.info.height * 0.5);
    const glm::dvec3 p0 = scene.frame.toLocal(g.crs, g.pixelToCrs(c));
    const glm::dvec3 px = scene.frame.toLocal(g.crs, g.pixelToCrs(c + glm::dvec2(1.0, 0.0)));
    const glm::dvec3 py = scene.frame.toLocal(g.crs, g.pixelToCrs(c + glm::dvec2(0.0, 1.0)));
    return std::sqrt(glm::length(glm::dvec2(px - p0)) * glm::length(glm::dvec2(py - p0)));
}

// The crown list as CSV rows: the pixel centre in the scene's local frame and in the imagery's CRS.
std::string crownCsv(const Scene& scene, const std::vector<CrownDetection>& crowns, std::vector<CrownPoint>& local) {
    const Georef& g = *scene.leafon.info.georef;
    const bool geographic = g.crs.isGeographic();
    const double metres = pixelMetres(scene);
    std::string text = "id,x,y,easting,northing,radius_m\n";
    char line[160];
    local.clear();
    local.reserve(crowns.size());
    for (size_t i = 0; i < crowns.size(); ++i) {
        const glm::dvec2 crs = g.pixelToCrs({crowns[i].px, crowns[i].py});
        const glm::dvec3 p = scene.frame.toLocal(g.crs, crs);
        const double r = crowns[i].radiusPx * metres;
        local.push_back({p.x, p.y, r});
        const char* format = geographic ? "%zu,%.3f,%.3f,%.8f,%.8f,%.3f\n" : "%zu,%.3f,%.3f,%.3f,%.3f,%.3f\n";
        std::snprintf(line, sizeof line, format, i + 1, p.x, p.y, crs.x, crs.y, r);
        text += line;
    }
    return text;
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

Result<SegmentReport> segmentScene(const Scene& scene, const SegmentJob& job) {
    const auto start = Clock::now();
    const SegmentationParams& params = job.params;
    [[maybe_unused]] const int k = effectiveK(params);
    assert(k >= 1 && k <= kSegMaxK && k % 2 == 1 && "segmentScene(): k must be odd, 1..kSegMaxK");
    assert(!job.mask.empty() && job.bandRows > 0 && "segmentScene(): a mask path and a positive band height");
    const int w = scene.leafon.info.width, h = scene.leafon.info.height;
    const int halo = segmentationHalo(params);
    const int bandRows = job.bandRows;
    SegmentReport report;
    report.width = w;
    report.height = h;
    auto progress = [&](double f, const char* stage) {
        if (job.progress) job.progress(f, stage);
    };

    // Inputs first (cheap checks), then the outputs, before any pixel work.
    const bool withTruth = !job.truth.empty();
    if (withTruth) {
        auto info = readRasterInfo(job.truth);
        if (!info) return info.error();
        if (info->width != w || info->height != h)
            return fileError(job.truth.string(), "truth mask is " + std::to_string(info->width) + "x" +
                                                     std::to_string(info->height) + " pixels but the imagery is " +
                                                     std::to_string(w) + "x" + std::to_string(h));
    }
    std::optional<std::vector<CrownPoint>> trueTrees;
    if (!job.truthTrees.empty()) {
        auto t = readTrueTrees(job.truthTrees);
        if (!t) return t.error();
        trueTrees = std::move(*t);
    }
    const bool withCrowns = !job.trees.empty() || trueTrees.has_value();
    auto maskOut = ImageStreamWriter::open(job.mask, w, h, 1, ImageEncoding::FastMask);
    if (!maskOut) return maskOut.error();
    std::optional<ImageStreamWriter> overlayOut;
    if (!job.overlay.empty()) {
        auto o = ImageStreamWriter::open(job.overlay, w, h, 3);
        if (!o) return o.error();
        overlayOut = std::move(*o);
    }

    // The readers' bands: at least the halo, so that a window never needs more than the bands around it.
    const CrownParams crownParams = crownParamsForGsd(pixelMetres(scene));
    const int crownHaloRows = withCrowns ? crownHalo(crownParams) : 0;
    const int preferredRows = std::max({256, bandRows, 2 * halo});
    auto openPair = [&]() -> Result<std::pair<RowReader, RowReader>> {
        auto a = RowReader::open(scene.leafon.info.path, 3, &scene.leafon.stretch, preferredRows);
        if (!a) return a.error();
        auto b = RowReader::open(scene.leafoff.info.path, 3, &scene.leafoff.stretch, preferredRows);
        if (!b) return b.error();
        return std::make_pair(std::move(*a), std::move(*b));
    };
    auto pair = openPair();
    if (!pair) return pair.error();

    // The pair's statistics (equalized, default): given, from the pair held whole, or from a first streamed pass.
    const bool colour = params.method == SegmentationMethod::Equalized;
    const bool drop = params.method == SegmentationMethod::Default;
    const std::uint64_t pairBytes = 2 * std::uint64_t(w) * std::uint64_t(h) * 3;
    PairWindow window;
    window.width = w;
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
        SegmentationHistograms hist;
        const size_t rowBytes = size_t(w) * 3;
        for (int y0 = 0; y0 < h; y0 += preferredRows) {
            const int y1 = std::min(h, y0 + preferredRows);
            auto t = Clock::now();
            if (auto st = window.slide(pair->first, pair->second, 0, y1); !st) return st.error();
            report.readSeconds += secondsSince(t);
            t = Clock::now(); // each band's histograms while its rows are still in cache
            hist.merge(rowHistograms(RgbRows{window.on.data() + size_t(y0) * rowBytes,
                                             window.off.data() + size_t(y0) * rowBytes, w, h, y0, y1 - y0},
                                     colour, drop));
            report.segmentSeconds += secondsSince(t);
            progress(0.5 * y1 / h, "reading");
        }
        report.stats = statsFromHistograms(hist, params.method);
    } else {
        // Too large to hold: a first pass over both files for the histograms, band by band.
        report.statsSource = StatsSource::HistogramPass;
        report.inputPasses = 2;
        SegmentationHistograms hist;
        std::vector<std::uint8_t> on, off;
        for (int y0 = 0; y0 < h; y0 += bandRows) {
            const int y1 = std::min(h, y0 + bandRows);
            on.resize(size_t(y1 - y0) * size_t(w) * 3);
            off.resize(on.size());
            auto t = Clock::now();
            if (auto st = readPair(pair->first, pair->second, y0, y1, on.data(), off.data()); !st) return st.error();
            report.readSeconds += secondsSince(t);
            t = Clock::now();
            hist.merge(rowHistograms(RgbRows{on.data(), off.data(), w, h, y0, y1 - y0}, colour, drop));
            report.segmentSeconds += secondsSince(t);
            progress(0.3 * y1 / h, "histograms");
        }
        report.stats = statsFromHistograms(hist, params.method);
        auto again = openPair(); // the readers only go forward
        if (!again) return again.error();
        pair = std::move(again);
    }
    const double done0 = report.heldInMemory ? 0.5 : report.inputPasses == 2 ? 0.3 : 0.0;

    // Bands of output rows with their halo. The mask and overlay of a band are encoded on a writer thread while the
    // next band is segmented (two buffers of each, taking turns).
    std::optional<RowReader> truthReader;
    if (withTruth) {
        auto t = RowReader::open(job.truth, 1, nullptr, preferredRows);
        if (!t) return t.error();
        truthReader = std::move(*t);
    }
    std::vector<std::uint8_t> mask[2], overlay[2], truth;
    std::vector<std::uint8_t> crownMask; // mask rows [crownFirst, crownLast) for the crown search
    int crownFirst = 0, crownLast = 0, crownDone = 0;
    std::vector<CrownDetection> crowns;
    Confusion confusion;
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
        if (withTruth)
            if (auto st = truthReader->read(y0, y1, truth.data()); !st) return st.error();
        report.readSeconds += secondsSince(t);

        t = Clock::now();
        std::vector<std::uint8_t>& m = mask[band % 2];
        m.resize(n);
        const RgbRows in{window.on.data(), window.off.data(), w, h, window.first, window.last - window.first};
        segmentRows(in, y0, rows, params, report.stats, m.data());
        report.segmentSeconds += secondsSince(t);

        if (withTruth) confusion.add(m.data(), truth.data(), n);
        std::vector<std::uint8_t>& o = overlay[band % 2];
        if (overlayOut) {
            t = Clock::now();
            o.resize(n * 3);
            drawOverlay(window.on.data() + size_t(y0 - window.first) * size_t(w) * 3, m.data(),
                        withTruth ? truth.data() : nullptr, n, o.data());
            report.writeSeconds += secondsSince(t);
        }
        // The writer of the previous band must be done before this band's turn (and its buffers are free again).
        if (auto st = waitForWriter(); !st) return st.error();
        pendingWrite = std::async(std::launch::async, [&, y0, rows, band]() -> Status {
            const auto t0 = Clock::now();
            if (auto st = maskOut->writeRows(y0, rows, mask[band % 2].data()); !st) return st;
            if (overlayOut)
                if (auto st = overlayOut->writeRows(y0, rows, overlay[band % 2].data()); !st) return st;
            writerSeconds += secondsSince(t0);
            return Ok{};
        });

        if (withCrowns) {
            // Crowns lag the mask by their halo, and wait for at least four halos of rows (each call transforms its
            // rows plus a halo on both sides); the last band flushes them all.
            t = Clock::now();
            crownMask.insert(crownMask.end(), m.begin(), m.end());
            crownLast = y1;
            const int done = y1 == h ? h : std::max(crownDone, y1 - crownHaloRows);
            if (done == h || done - crownDone >= 4 * crownHaloRows) {
                detectCrownRows(crownMask.data(), w, h, crownFirst, crownLast - crownFirst, crownDone,
                                done - crownDone, crownParams, crowns);
                crownDone = done;
                const int keepFrom = std::max(crownFirst, crownDone - crownHaloRows);
                crownMask.erase(crownMask.begin(), crownMask.begin() + std::ptrdiff_t(keepFrom - crownFirst) * w);
                crownFirst = keepFrom;
            }
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
    if (!job.trees.empty()) {
        std::string err;
        if (!writeTextAtomic(job.trees, csv, err)) return fileError(job.trees.string(), err);
    }
    report.writeSeconds += writerSeconds + secondsSince(t);
    if (withTruth) report.confusion = confusion;
    report.crowns = int(crowns.size());
    if (trueTrees) report.centres = matchCentres(local, *trueTrees);
    report.totalSeconds = secondsSince(start);
    return report;
}

} // namespace seasonview
