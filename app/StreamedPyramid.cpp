#include "StreamedPyramid.h"

#include "Crs.h"
#include "GridReader.h"
#include "PyramidBuilder.h"
#include "WebSource.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cmath>
#include <cstring>
#include <map>
#include <optional>
#include <memory>
#include <mutex>
#include <set>
#include <thread>
#include <tuple>
#include <utility>

namespace seasonview {

WorkingGrid levelGrid(const WorkingGrid& grid, int level) {
    const auto sizes = pyramidLevelSizes(grid.width, grid.height);
    assert(level >= 0 && level < int(sizes.size()) && "levelGrid(): a level of the grid's pyramid");
    WorkingGrid g = grid;
    g.georef.pixelSize *= std::ldexp(1.0, level);
    g.width = sizes[size_t(level)].first;
    g.height = sizes[size_t(level)].second;
    return g;
}

namespace {

/// streamTileCount()'s state: every loader thread's streamed reads add to it.
struct TileLedger {
    std::mutex mutex;
    std::atomic<bool> counting{false}; // from the first resetStreamTileCount() (a bench): nothing costs before
    std::set<std::tuple<std::string, long long, long long>> needed; // (service description, tile column, tile row)
    long long regions = 0;
};
TileLedger& ledger() {
    static TileLedger l;
    return l;
}

/// One streamed level of one season: the service read at the level's zoom onto the level's grid, in regions of
/// kRegion² texels (a 256-pixel service tile's worth: the tiles a region touches are fetched in parallel, and the
/// clipmap's 64-texel blocks inside it are answered from memory), the last kRegions kept.
/// The open readers of every streamed level (GridReader, each a GDAL dataset of a service description with one
/// connection that curl keeps alive): at most kStreamWorkers, whatever the levels and seasons, so that the service's
/// host never sees more connections than the workers. Idle readers are kept for their level's next region and closed
/// when another level needs a reader. Shared by the streamed levels alive (and gone with the last).
class ReaderPool {
public:
    static std::shared_ptr<ReaderPool> shared() {
        static std::mutex mutex;
        static std::weak_ptr<ReaderPool> current;
        std::lock_guard lock(mutex);
        auto pool = current.lock();
        if (!pool) current = pool = std::make_shared<ReaderPool>();
        return pool;
    }

    /// An idle reader of `level`, or nothing (then the caller opens one): room made for it by closing another
    /// level's idle reader when kStreamWorkers are open. Waits while all are in use.
    std::unique_ptr<GridReader> acquire(const void* level) {
        std::unique_ptr<GridReader> closing; // closed outside the lock
        std::unique_lock lock(m_mutex);
        m_free.wait(lock, [&] { return m_inUse < kStreamWorkers; });
        ++m_inUse;
        for (auto it = m_idle.begin(); it != m_idle.end(); ++it)
            if (it->first == level) {
                auto r = std::move(it->second);
                m_idle.erase(it);
                return r;
            }
        if (m_inUse + int(m_idle.size()) > kStreamWorkers && !m_idle.empty()) {
            closing = std::move(m_idle.front().second);
            m_idle.erase(m_idle.begin());
        }
        return nullptr;
    }
    /// Gives a reader back after a read (`reader` null: it was dropped after a failure).
    void release(const void* level, std::unique_ptr<GridReader> reader) {
        {
            std::lock_guard lock(m_mutex);
            --m_inUse;
            if (reader) m_idle.emplace_back(level, std::move(reader));
        }
        m_free.notify_one();
    }
    /// Closes the idle readers of a level that goes.
    void forget(const void* level) {
        std::vector<std::unique_ptr<GridReader>> closing;
        std::lock_guard lock(m_mutex);
        for (auto it = m_idle.begin(); it != m_idle.end();)
            if (it->first == level) {
                closing.push_back(std::move(it->second));
                it = m_idle.erase(it);
            } else {
                ++it;
            }
    }

private:
    std::mutex m_mutex;
    std::condition_variable m_free;
    int m_inUse = 0;
    std::vector<std::pair<const void*, std::unique_ptr<GridReader>>> m_idle;
};

/// Where GDAL keeps fetched tiles (cacheDir/web/tiles/, WebSource.h): a read error naming a file there is a tile
/// another worker is still writing.
constexpr const char* kTileCacheFolder = "/web/tiles/";

class StreamedLevel {
public:
    static constexpr int kRegion = 256;
    static constexpr size_t kRegions = 16;
    // A region whose read failed (a service's fault) is not asked again for this long: the loader asks for a
    // missing block every frame, and a service that is down must not be asked 60 times a second.
    static constexpr std::chrono::seconds kRetryAfter{5};

    ~StreamedLevel() { m_pool->forget(this); }
    StreamedLevel(const StreamedLevel&) = delete;
    StreamedLevel& operator=(const StreamedLevel&) = delete;
    StreamedLevel(ImageryLayer layer, WorkingGrid grid) : m_layer(std::move(layer)), m_grid(std::move(grid)) {
        m_sixteen = m_layer.source.type == SampleType::U16;
        for (int c = 0; c < 3; ++c) {
            m_lut[c].resize(m_sixteen ? 65536 : 256);
            for (size_t v = 0; v < m_lut[c].size(); ++v) m_lut[c][v] = m_layer.stretch.apply(c, float(v));
        }
    }

    /// Thread-safe: the block loader's workers read regions of one level at once (each region loaded once).
    Status read(const TexelRect& t, std::uint8_t* rgba) {
        noteNeededTiles(t);
        for (int ry = t.y0 / kRegion; ry * kRegion < t.y1; ++ry)
            for (int rx = t.x0 / kRegion; rx * kRegion < t.x1; ++rx) {
                auto region = this->region(rx, ry);
                if (!region) return region.error();
                const Region& r = **region;
                const TexelRect part = intersect(t, r.rect);
                for (int y = part.y0; y < part.y1; ++y)
                    std::memcpy(rgba + (size_t(y - t.y0) * size_t(t.width()) + size_t(part.x0 - t.x0)) * 4,
                                r.rgba.data() + (size_t(y - r.rect.y0) * size_t(r.rect.width()) +
                                                 size_t(part.x0 - r.rect.x0)) * 4,
                                size_t(part.width()) * 4);
            }
        return Ok{};
    }

private:
    /// Adds the service tiles under `t` to the ledger: its outline (16 points) mapped to the service's pixels, whose
    /// 256-pixel tiles are the service's (an XYZ/TMS description's window starts at a tile; a WMTS one's nearly).
    void noteNeededTiles(const TexelRect& t) {
        if (!ledger().counting.load()) return; // a PROJ transform per block, kept only for a bench's figures
        const auto px = sourcePixels(t);
        if (!px) return;
        constexpr double kTile = 256.0;
        const long long x0 = (long long)std::floor(double(px->x0) / kTile);
        const long long x1 = (long long)std::floor((double(px->x1) - 1e-9) / kTile);
        const long long y0 = (long long)std::floor(double(px->y0) / kTile);
        const long long y1 = (long long)std::floor((double(px->y1) - 1e-9) / kTile);
        const RasterInfo& src = m_layer.source.tiles.front();
        TileLedger& l = ledger();
        std::lock_guard lock(l.mutex);
        for (long long y = y0; y <= y1; ++y)
            for (long long x = x0; x <= x1; ++x) l.needed.emplace(src.path.string(), x, y);
    }

    /// The service description's pixels under level texels `t` (its outline, 16 points, mapped there), clipped to
    /// the description; nothing when they miss it.
    std::optional<TexelRect> sourcePixels(const TexelRect& t) const {
        const RasterInfo& src = m_layer.source.tiles.front();
        std::vector<glm::dvec2> pts;
        for (int i = 0; i <= 4; ++i)
            for (const glm::dvec2 f : {glm::dvec2(i / 4.0, 0.0), glm::dvec2(i / 4.0, 1.0), glm::dvec2(0.0, i / 4.0),
                                       glm::dvec2(1.0, i / 4.0)})
                pts.push_back(m_grid.georef.pixelToCrs(glm::dvec2(t.x0, t.y0) + f * glm::dvec2(t.width(), t.height())));
        convert(m_grid.georef.crs, src.georef->crs, pts);
        glm::dvec2 lo(1e300), hi(-1e300);
        for (const glm::dvec2& p : pts) {
            const glm::dvec2 px = src.georef->crsToPixel(p);
            lo = glm::min(lo, px), hi = glm::max(hi, px);
        }
        if (!(lo.x <= hi.x && lo.y <= hi.y)) return std::nullopt;
        const TexelRect r{int(std::max(0.0, std::floor(lo.x))), int(std::max(0.0, std::floor(lo.y))),
                          int(std::min(double(src.width), std::ceil(hi.x))),
                          int(std::min(double(src.height), std::ceil(hi.y)))};
        if (r.empty()) return std::nullopt;
        return r;
    }

    struct Region {
        TexelRect rect;
        std::vector<std::uint8_t> rgba;
        std::uint64_t used = 0;
    };
    using Key = std::pair<int, int>;

    /// The region (rx, ry): kept, else loaded (outside the lock: other workers read other regions meanwhile; one
    /// asking for a region being loaded waits for it), else the error of a recent failure.
    Result<std::shared_ptr<const Region>> region(int rx, int ry) {
        const Key key{rx, ry};
        std::unique_lock lock(m_mutex);
        while (true) {
            if (auto it = m_regions.find(key); it != m_regions.end()) {
                it->second->used = ++m_clock;
                return std::shared_ptr<const Region>(it->second);
            }
            if (auto f = m_failed.find(key); f != m_failed.end()) {
                if (std::chrono::steady_clock::now() - f->second.first < kRetryAfter) return Error{f->second.second};
                m_failed.erase(f);
            }
            if (!m_loading.count(key)) break;
            m_loaded.wait(lock);
        }
        m_loading.insert(key);
        lock.unlock();
        {
            TileLedger& l = ledger();
            std::lock_guard ledgerLock(l.mutex);
            ++l.regions;
        }
        auto r = std::make_shared<Region>();
        r->rect = {rx * kRegion, ry * kRegion, std::min(m_grid.width, (rx + 1) * kRegion),
                   std::min(m_grid.height, (ry + 1) * kRegion)};
        const Status st = load(*r);
        lock.lock();
        m_loading.erase(key);
        m_loaded.notify_all();
        if (!st) {
            m_failed[key] = {std::chrono::steady_clock::now(), st.message()};
            return st.error();
        }
        if (m_regions.size() >= kRegions) {
            auto oldest = std::min_element(m_regions.begin(), m_regions.end(),
                                           [](const auto& a, const auto& b) { return a.second->used < b.second->used; });
            m_regions.erase(oldest); // a reader copying from it keeps it alive (shared_ptr)
        }
        r->used = ++m_clock;
        m_regions[key] = r;
        return std::shared_ptr<const Region>(r);
    }

    /// The region's texels: the service's tiles at the level's zoom warped onto the region of the level's grid
    /// (GridReader::readWindow, through a reader kept open between regions: its service description opened and its
    /// transformation made once), stretched, premultiplied by coverage (0, 0, 0, 0 where the service has no data),
    /// as buildPyramidLevels makes a prepared level 0.
    Status load(Region& r) {
        const TexelRect& R = r.rect;
        const std::filesystem::path description = m_layer.source.tiles.front().path;
        std::unique_ptr<GridReader> reader = m_pool->acquire(this);
        struct Release { // the reader back to the pool however this returns (dropped after a failed read)
            ReaderPool& pool;
            const void* level;
            std::unique_ptr<GridReader>& reader;
            bool keep = false;
            ~Release() { pool.release(level, keep ? std::move(reader) : nullptr); }
        } release{*m_pool, this, reader};
        if (!reader) {
            auto opened = GridReader::open(m_layer.source, m_grid, m_layer.resampling, kRegion);
            if (!opened) return opened.error();
            reader = std::make_unique<GridReader>(std::move(*opened));
        }
        const size_t n = size_t(R.area());
        std::vector<std::uint16_t> samples(n * 3);
        std::vector<std::uint8_t> coverage(n);
        const SampleType type = m_sixteen ? SampleType::U16 : SampleType::U8;
        Status st = reader->readWindow(R.x0, R.y0, R.x1, R.y1, 3, type, samples.data(), coverage.data());
        // GDAL 3.6 writes a fetched tile into its disk cache in place: another worker reading the same tile (a
        // neighbouring region, or a level at the same zoom) may find it half written. Read again, a few times.
        for (int again = 0; !st && again < 5 && st.message().find(kTileCacheFolder) != std::string::npos; ++again) {
            std::this_thread::sleep_for(std::chrono::milliseconds(20 << again));
            st = reader->readWindow(R.x0, R.y0, R.x1, R.y1, 3, type, samples.data(), coverage.data());
        }
        if (!st) {
            // The failing tile's URL and status: from GDAL's block number when it gives one, else by asking the
            // server again for the tiles under the region (a tile that did not decode). The reader is dropped.
            if (auto tile = web::tileFailure(description, st.message())) return *tile;
            if (const auto px = sourcePixels(R))
                if (auto tile = web::tileFailureIn(description, px->x0, px->y0, px->x1, px->y1)) return *tile;
            return st;
        }
        release.keep = true;
        r.rgba.resize(n * 4);
        const auto* bytes = reinterpret_cast<const std::uint8_t*>(samples.data());
        for (size_t i = 0; i < n; ++i) {
            std::uint8_t* out = &r.rgba[i * 4];
            if (!coverage[i]) {
                out[0] = out[1] = out[2] = out[3] = 0;
                continue;
            }
            for (size_t c = 0; c < 3; ++c) out[c] = m_lut[c][m_sixteen ? samples[i * 3 + c] : bytes[i * 3 + c]];
            out[3] = 255;
        }
        return Ok{};
    }

    ImageryLayer m_layer;
    WorkingGrid m_grid;
    bool m_sixteen = false;
    std::vector<std::uint8_t> m_lut[3];
    std::mutex m_mutex; // the maps and the clock
    std::condition_variable m_loaded;
    std::map<Key, std::shared_ptr<Region>> m_regions;
    std::set<Key> m_loading;
    std::shared_ptr<ReaderPool> m_pool = ReaderPool::shared();
    std::map<Key, std::pair<std::chrono::steady_clock::time_point, std::string>> m_failed;
    std::uint64_t m_clock = 0;
};

} // namespace

Result<PrepareReport> prepareStreamedPyramid(const Scene& scene, const std::string& role,
                                             const PrepareOptions& options) {
    const bool on = role == "leafon";
    assert((on || role == "leafoff") && "prepareStreamedPyramid(): leafon or leafoff");
    const ImageryLayer& full = on ? scene.leafon : scene.leafoff;
    const auto sizes = pyramidLevelSizes(scene.grid.width, scene.grid.height);
    int prepared = 0;
    while (prepared + 1 < int(sizes.size()) &&
           std::max(sizes[size_t(prepared)].first, sizes[size_t(prepared)].second) > kStreamPreparedSide)
        ++prepared;
    if (prepared == 0) return preparePyramid(full, options); // small enough to prepare whole

    // The coarse levels: the season read at their first level's zoom, on that level's grid.
    auto coarse = serviceLayerOnGrid(scene, role, levelGrid(scene.grid, prepared), options.cacheDir);
    if (!coarse) return coarse.error();
    auto report = preparePyramid(*coarse, options);
    if (!report) return report;

    // What the loader's thread needs to open a finer level: the scene's sources and the season's colours.
    auto light = std::make_shared<Scene>();
    light->sources = scene.sources;
    light->grid = scene.grid;
    for (ImageryLayer* l : {&light->leafon, &light->leafoff}) {
        const ImageryLayer& from = l == &light->leafon ? scene.leafon : scene.leafoff;
        l->stretch = from.stretch;
        l->resampling = from.resampling;
    }
    ImagePyramid& p = report->pyramid;
    std::vector<PyramidLevel> levels;
    for (int l = 0; l < prepared; ++l) levels.push_back(PyramidLevel{{}, sizes[size_t(l)].first, sizes[size_t(l)].second});
    levels.insert(levels.end(), p.levels.begin(), p.levels.end());
    p.levels = std::move(levels);
    p.streamedLevels = prepared;
    p.openStreamedLevel = [light, role, cacheDir = options.cacheDir](int level) -> Result<LevelTexelReader> {
        const WorkingGrid grid = levelGrid(light->grid, level);
        // Each of the loader's workers reads with its share of the connections to the service.
        auto layer = serviceLayerOnGrid(*light, role, grid, cacheDir,
                                        std::max(1, web::kDefaultConnections / kStreamWorkers));
        if (!layer) return layer.error();
        auto reader = std::make_shared<StreamedLevel>(std::move(*layer), grid);
        return LevelTexelReader([reader](const TexelRect& t, std::uint8_t* rgba) { return reader->read(t, rgba); });
    };
    return report;
}

Result<PrepareReport> prepareSeasonPyramid(const Scene& scene, const std::string& role, const PrepareOptions& options) {
    const bool on = role == "leafon";
    if (scene.sources.stream && isTileService(on ? scene.sources.leafon : scene.sources.leafoff))
        return prepareStreamedPyramid(scene, role, options);
    return preparePyramid(on ? scene.leafon : scene.leafoff, options);
}

std::vector<ImagePyramid> preparedPart(const std::vector<ImagePyramid>& pyramids, int* level) {
    int first = 0;
    for (const ImagePyramid& p : pyramids) first = std::max(first, p.streamedLevels);
    if (level) *level = first;
    if (first == 0) return pyramids;
    std::vector<ImagePyramid> out;
    for (const ImagePyramid& p : pyramids) {
        ImagePyramid q = p;
        q.levels.erase(q.levels.begin(), q.levels.begin() + first);
        q.sourceKey += "|from level " + std::to_string(first); // what is cached from it is not the full pyramid's
        q.streamedLevels = 0;
        q.openStreamedLevel = nullptr;
        out.push_back(std::move(q));
    }
    return out;
}

StreamTileCount streamTileCount() {
    TileLedger& l = ledger();
    std::lock_guard lock(l.mutex);
    StreamTileCount c{(long long)l.needed.size(), l.regions};
    for (const auto& [description, col, row] : l.needed) {
        if (const auto bytes = web::cachedTileBytes(description, col, row)) c.bytesNeeded += *bytes;
        else ++c.tilesNotCached;
    }
    return c;
}

void resetStreamTileCount() {
    TileLedger& l = ledger();
    std::lock_guard lock(l.mutex);
    l.needed.clear();
    l.regions = 0;
    l.counting = true;
}

Status refuseStreamed(const std::vector<ImagePyramid>& pyramids, const std::string& what) {
    for (const ImagePyramid& p : pyramids)
        if (p.streamedLevels > 0)
            return Error{"--stream: " + what + " reads every full-resolution texel, which a streamed season does not "
                         "have; run it without --stream (the season is then prepared whole)"};
    return Ok{};
}

} // namespace seasonview
