#pragma once
// Background loading of clipmap blocks (no GL): a worker thread reads the blocks the schedule asks for, for every
// layer (leaf-on, leaf-off, ...) at once, from a BlockSource; the render thread takes finished blocks within its
// per-frame budget and uploads them. Nothing on the render thread ever waits for disk.
#include "ClipmapSchedule.h"
#include "ImagePyramid.h"
#include "Result.h"

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace seasonview {

/// Where block texels come from. Implementations must be safe to call from the loader thread.
class BlockSource {
public:
    virtual ~BlockSource() = default;
    virtual int layers() const = 0;
    /// Reads `texels` (level texel coordinates, inside the level's image) of `layer` at `level` as rows of
    /// `texels.width()` texels of bytesPerTexel() bytes (RGBA8, or one float for elevation) into `rgba`. Errors name
    /// the file.
    virtual Status read(int layer, int level, const TexelRect& texels, std::uint8_t* rgba) = 0;
    /// Bytes per texel of what read() writes (4: RGBA8 or a float; a derived layer may write fewer).
    virtual int bytesPerTexel() const { return 4; }
    /// Bytes the source holds in its own cache (0 when it has none).
    virtual std::int64_t cacheBytes() const { return 0; }
    /// Whether `level` of `layer` is streamed from the network: its read errors are a service's faults (counted and
    /// shown, asked again later), not a damaged cache.
    virtual bool streamed(int layer, int level) const {
        (void)layer, (void)level;
        return false;
    }
};

/// Each layer's level files, level by level (a streamed level's path is empty): PyramidBlockSource's levelFiles.
std::vector<std::vector<std::filesystem::path>> pyramidLevelFiles(const std::vector<ImagePyramid>& layers);

/// Pyramid level files (one per level, per layer) read through one OpenImageIO ImageCache of bounded size.
class PyramidBlockSource final : public BlockSource {
public:
    /// levelFiles[layer][level]: the tiled TIFF of that pyramid level. `cacheMegabytes` bounds the tile cache.
    /// `format`: Rgba8 files are read as they are (premultiplied RGBA8), R32F files as floats, R8 as bytes.
    PyramidBlockSource(std::vector<std::vector<std::filesystem::path>> levelFiles, int cacheMegabytes = 256,
                       TexelFormat format = TexelFormat::Rgba8);
    ~PyramidBlockSource() override;
    int layers() const override { return int(m_files.size()); }
    Status read(int layer, int level, const TexelRect& texels, std::uint8_t* rgba) override;
    int bytesPerTexel() const override { return texelBytes(m_format); }
    std::int64_t cacheBytes() const override;

private:
    std::vector<std::vector<std::filesystem::path>> m_files;
    TexelFormat m_format;
    struct Cache;
    std::unique_ptr<Cache> m_cache;
};

/// Pyramids whose finest levels may be streamed (ImagePyramid::streamedLevels): those levels through the layer's
/// LevelTexelReader (made at the level's first read), the others from their files (PyramidBlockSource). Thread-safe.
class MixedBlockSource final : public BlockSource {
public:
    MixedBlockSource(const std::vector<ImagePyramid>& layers, int cacheMegabytes, TexelFormat format);
    int layers() const override { return m_files.layers(); }
    Status read(int layer, int level, const TexelRect& texels, std::uint8_t* rgba) override;
    std::int64_t cacheBytes() const override { return m_files.cacheBytes(); }
    bool streamed(int layer, int level) const override { return level < m_streamed[size_t(layer)]; }

private:
    PyramidBlockSource m_files;
    std::vector<int> m_streamed;
    std::vector<std::function<Result<LevelTexelReader>(int level)>> m_open;
    std::mutex m_openMutex;
    std::vector<std::vector<LevelTexelReader>> m_readers; // [layer][level], empty until first read (m_openMutex)
};

/// A loaded block: texels of every layer (BlockSource::bytesPerTexel() each), rows of `texels.width()`.
struct LoadedBlock {
    BlockKey key;
    TexelRect texels;
    std::vector<std::vector<std::uint8_t>> layers;
    std::string error; // non-empty: the read failed (the block stays missing; the shader keeps falling back)
    int errorLayer = -1; // the layer whose read failed
    bool streamed = false; // the failed read was of a streamed level (BlockSource::streamed)
};

class BlockLoader {
public:
    /// `maxFinishedBytes`: back-pressure. The worker stops reading while the finished blocks not yet taken hold
    /// this many bytes, so a loader faster than the render thread's upload budget cannot pile up memory.
    /// `workers`: threads reading at once (the source must then be thread-safe): more than one for a source whose
    /// reads wait on a network rather than on a disk or a core.
    BlockLoader(BlockSource& source, const ClipmapSchedule& schedule, std::int64_t maxFinishedBytes = 64 << 20,
                int workers = 1);
    ~BlockLoader(); // stops and joins the workers
    BlockLoader(const BlockLoader&) = delete;
    BlockLoader& operator=(const BlockLoader&) = delete;

    /// Replaces the wanted list (render thread, once a frame): blocks already queued or in flight are not asked
    /// twice; queued blocks no longer wanted are dropped, and so are finished ones the schedule's windows have
    /// left (the view moved on while they waited for upload). Order = priority.
    void want(const std::vector<BlockKey>& blocks);
    /// Finished blocks, oldest first, at most `maxTexels` texels in all (at least one block when any is ready).
    std::vector<LoadedBlock> take(std::int64_t maxTexels);
    /// Blocks queued or being read.
    size_t pending() const;
    /// Blocks read so far, and read errors so far.
    std::int64_t blocksRead() const { return m_read.load(); }
    std::int64_t readErrors() const { return m_errors.load(); }
    /// Bytes of finished blocks waiting to be taken (never much above maxFinishedBytes).
    std::int64_t finishedBytes() const;
    /// Waits until nothing is queued or in flight, or until the worker waits for blocks to be taken (finished
    /// blocks at the cap) (tests and one-shot stills only; never in a frame loop).
    void waitIdle();

private:
    void run();
    bool isPending(const BlockKey& k) const; // m_mutex held

    struct Job {
        BlockKey key;
        TexelRect texels;
    };
    BlockSource& m_source;
    const ClipmapSchedule& m_schedule;
    mutable std::mutex m_mutex;
    std::condition_variable m_wake, m_idle;
    std::deque<Job> m_queue;
    std::vector<BlockKey> m_inFlight;
    std::deque<LoadedBlock> m_done;
    std::int64_t m_doneBytes = 0, m_maxDoneBytes;
    bool m_stop = false;
    std::atomic<std::int64_t> m_read{0}, m_errors{0};
    std::vector<std::thread> m_workers;
};

} // namespace seasonview
