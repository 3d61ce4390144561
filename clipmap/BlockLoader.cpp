#include "BlockLoader.h"

#include "ZstdTileCheck.h"

#include <OpenImageIO/imagecache.h>

#include <algorithm>
#include <cassert>
#include <cstring>

namespace seasonview {

struct PyramidBlockSource::Cache {
    struct Destroy {
        void operator()(OIIO::ImageCache* c) const { OIIO::ImageCache::destroy(c); }
    };
    std::unique_ptr<OIIO::ImageCache, Destroy> cache;
    ZstdTileCheck check; // libtiff, under OpenImageIO, does not verify the tiles' checksums (ZstdTileCheck.h)
};

PyramidBlockSource::PyramidBlockSource(std::vector<std::vector<std::filesystem::path>> levelFiles, int cacheMegabytes,
                                       TexelFormat format)
    : m_files(std::move(levelFiles)), m_format(format), m_cache(std::make_unique<Cache>()) {
    // A private cache (not the process-wide shared one) so its size bound is ours alone.
    m_cache->cache.reset(OIIO::ImageCache::create(false));
    m_cache->cache->attribute("max_memory_MB", float(cacheMegabytes));
    m_cache->cache->attribute("autotile", 0);
    m_cache->cache->attribute("max_open_files", 64);
}

PyramidBlockSource::~PyramidBlockSource() = default;

Status PyramidBlockSource::read(int layer, int level, const TexelRect& t, std::uint8_t* rgba) {
    const std::filesystem::path& file = m_files[size_t(layer)][size_t(level)];
    const OIIO::ustring name(file.string());
    // Imagery pyramid files are premultiplied RGBA, as the texture holds them. Elevation: floats; the canopy: bytes.
    if (auto st = m_cache->check.check(file, t.x0, t.y0, t.x1, t.y1); !st) return st.error();
    if (!m_cache->cache->get_pixels(name, 0, 0, t.x0, t.x1, t.y0, t.y1, 0, 1, 0, texelChannels(m_format),
                                    m_format == TexelFormat::R32F ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8,
                                    rgba, OIIO::AutoStride,
                                    OIIO::AutoStride, OIIO::AutoStride)) {
        std::string e = m_cache->cache->geterror();
        if (auto nl = e.find('\n'); nl != std::string::npos) e.resize(nl);
        return fileError(file.string(), "cannot read texels (" + e + ")");
    }
    return Ok{};
}

std::int64_t PyramidBlockSource::cacheBytes() const {
    long long bytes = 0;
    m_cache->cache->getattribute("stat:cache_memory_used", OIIO::TypeDesc::INT64, &bytes);
    return bytes;
}

std::vector<std::vector<std::filesystem::path>> pyramidLevelFiles(const std::vector<ImagePyramid>& layers) {
    std::vector<std::vector<std::filesystem::path>> files;
    for (const ImagePyramid& p : layers) {
        std::vector<std::filesystem::path> f;
        for (const PyramidLevel& lv : p.levels) f.push_back(lv.file);
        files.push_back(std::move(f));
    }
    return files;
}

MixedBlockSource::MixedBlockSource(const std::vector<ImagePyramid>& layers, int cacheMegabytes, TexelFormat format)
    : m_files(pyramidLevelFiles(layers), cacheMegabytes, format) {
    for (const ImagePyramid& p : layers) {
        assert((p.streamedLevels == 0 || p.openStreamedLevel) && "MixedBlockSource: streamed levels need a reader");
        m_streamed.push_back(p.streamedLevels);
        m_open.push_back(p.openStreamedLevel);
        m_readers.emplace_back(size_t(p.streamedLevels));
    }
}

Status MixedBlockSource::read(int layer, int level, const TexelRect& texels, std::uint8_t* rgba) {
    if (!streamed(layer, level)) return m_files.read(layer, level, texels, rgba);
    LevelTexelReader reader;
    {
        std::lock_guard lock(m_openMutex); // workers open a level once; readers are thread-safe
        LevelTexelReader& kept = m_readers[size_t(layer)][size_t(level)];
        if (!kept) {
            auto opened = m_open[size_t(layer)](level);
            if (!opened) return opened.error(); // asked again with the next block
            kept = std::move(*opened);
        }
        reader = kept;
    }
    return reader(texels, rgba);
}

namespace {
std::int64_t blockBytes(const LoadedBlock& b) {
    std::int64_t n = 0;
    for (const auto& l : b.layers) n += std::int64_t(l.size());
    return n;
}
} // namespace

BlockLoader::BlockLoader(BlockSource& source, const ClipmapSchedule& schedule, std::int64_t maxFinishedBytes,
                         int workers)
    : m_source(source), m_schedule(schedule), m_maxDoneBytes(std::max<std::int64_t>(1, maxFinishedBytes)) {
    for (int i = 0; i < std::max(1, workers); ++i) m_workers.emplace_back([this] { run(); });
}

BlockLoader::~BlockLoader() {
    {
        std::lock_guard lock(m_mutex);
        m_stop = true;
    }
    m_wake.notify_all();
    for (std::thread& w : m_workers) w.join();
}

bool BlockLoader::isPending(const BlockKey& k) const {
    return std::find(m_inFlight.begin(), m_inFlight.end(), k) != m_inFlight.end() ||
           std::any_of(m_queue.begin(), m_queue.end(), [&](const Job& j) { return j.key == k; }) ||
           std::any_of(m_done.begin(), m_done.end(), [&](const LoadedBlock& b) { return b.key == k; });
}

void BlockLoader::want(const std::vector<BlockKey>& blocks) {
    {
        std::lock_guard lock(m_mutex);
        m_queue.clear(); // no longer wanted (or re-added below in the new priority order)
        // Finished blocks the windows have left would only be dropped at upload, after holding memory and the
        // upload budget's place: drop them now (a fast camera otherwise piles up gigabytes of stale blocks).
        std::erase_if(m_done, [&](const LoadedBlock& b) {
            if (intersect(m_schedule.window(b.key.level), b.texels) == b.texels) return false;
            m_doneBytes -= blockBytes(b);
            return true;
        });
        for (const BlockKey& k : blocks)
            if (!isPending(k)) m_queue.push_back({k, m_schedule.blockTexels(k)});
    }
    m_wake.notify_all();
}

std::vector<LoadedBlock> BlockLoader::take(std::int64_t maxTexels) {
    std::vector<LoadedBlock> out;
    std::lock_guard lock(m_mutex);
    std::int64_t texels = 0;
    while (!m_done.empty()) {
        const std::int64_t t = m_done.front().texels.area();
        if (!out.empty() && texels + t > maxTexels) break;
        texels += t;
        m_doneBytes -= blockBytes(m_done.front());
        out.push_back(std::move(m_done.front()));
        m_done.pop_front();
    }
    if (!out.empty()) m_wake.notify_all(); // room again below the cap
    return out;
}

std::int64_t BlockLoader::finishedBytes() const {
    std::lock_guard lock(m_mutex);
    return m_doneBytes;
}

size_t BlockLoader::pending() const {
    std::lock_guard lock(m_mutex);
    return m_queue.size() + m_inFlight.size();
}

void BlockLoader::waitIdle() {
    std::unique_lock lock(m_mutex);
    m_idle.wait(lock, [&] {
        return (m_queue.empty() && m_inFlight.empty()) || (m_inFlight.empty() && m_doneBytes >= m_maxDoneBytes);
    });
}

void BlockLoader::run() {
    std::unique_lock lock(m_mutex);
    while (true) {
        m_wake.wait(lock, [&] { return m_stop || (!m_queue.empty() && m_doneBytes < m_maxDoneBytes); });
        if (m_stop) return;
        const Job job = m_queue.front();
        m_queue.pop_front();
        m_inFlight.push_back(job.key);
        lock.unlock();

        LoadedBlock block;
        block.key = job.key;
        block.texels = job.texels;
        block.layers.resize(size_t(m_source.layers()));
        for (int layer = 0; layer < m_source.layers() && block.error.empty(); ++layer) {
            auto& px = block.layers[size_t(layer)];
            px.resize(size_t(job.texels.area()) * size_t(m_source.bytesPerTexel()));
            if (Status st = m_source.read(layer, job.key.level, job.texels, px.data()); !st) {
                block.error = st.message();
                block.errorLayer = layer;
                block.streamed = m_source.streamed(layer, job.key.level);
            }
        }
        ++m_read;
        if (!block.error.empty()) ++m_errors;

        lock.lock();
        m_inFlight.erase(std::find(m_inFlight.begin(), m_inFlight.end(), job.key));
        m_doneBytes += blockBytes(block);
        m_done.push_back(std::move(block));
        if ((m_queue.empty() && m_inFlight.empty()) || m_doneBytes >= m_maxDoneBytes) m_idle.notify_all();
    }
}

} // namespace seasonview
