#include "TiledTiffWriter.h"

#include <libdeflate.h>
#include <tiffio.h>

#include <algorithm>
#include <atomic>
#include <cassert>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <thread>
#include <utility>

namespace seasonview {

namespace {

constexpr int kChannels = 3;

// Per-handle libtiff handlers (libtiff >= 4.5): keep the message for our Error, print nothing, leave the global
// handlers that core/Raster.cpp installs alone.
int rememberTiffError(TIFF*, void* user, const char* module, const char* fmt, va_list ap) {
    char buf[512];
    std::vsnprintf(buf, sizeof buf, fmt, ap);
    *static_cast<std::string*>(user) = (module ? std::string(module) + ": " : std::string()) + buf;
    return 1;
}
int ignoreTiffWarning(TIFF*, void*, const char*, const char*, va_list) { return 1; }

/// Calls fn(index, worker) for every index in [0, count) on up to `threads` threads; worker < threads identifies
/// the calling thread (for per-thread scratch). Returns when all are done.
template <class Fn> void parallelIndices(int count, int threads, const Fn& fn) {
    const int n = std::clamp(threads, 1, std::max(count, 1));
    if (n == 1) {
        for (int i = 0; i < count; ++i) fn(i, 0);
        return;
    }
    std::atomic<int> next{0};
    auto worker = [&](int w) {
        for (int i = next.fetch_add(1); i < count; i = next.fetch_add(1)) fn(i, w);
    };
    std::vector<std::thread> pool;
    pool.reserve(size_t(n - 1));
    for (int w = 1; w < n; ++w) pool.emplace_back(worker, w);
    worker(0);
    for (auto& t : pool) t.join();
}

struct CompressorDeleter {
    void operator()(libdeflate_compressor* c) const { libdeflate_free_compressor(c); }
};

} // namespace

Result<TiledTiffWriter> TiledTiffWriter::create(const std::filesystem::path& path, int width, int height, int tileSize,
                                                int deflateLevel, int threads) {
    assert(width > 0 && height > 0 && tileSize > 0 && tileSize % 16 == 0 &&
           "TiledTiffWriter::create(): sizes must be positive and the tile size a multiple of 16 (TIFF)");
    TiledTiffWriter w;
    w.m_path = path;
    w.m_width = width;
    w.m_height = height;
    w.m_tileSize = tileSize;
    w.m_level = std::clamp(deflateLevel, 1, 12);
    w.m_threads = threads > 0 ? threads : std::max(1, int(std::thread::hardware_concurrency()));
    w.m_error = std::make_unique<std::string>();
    const std::uint64_t rawBytes = std::uint64_t(width) * std::uint64_t(height) * kChannels;
    TIFFOpenOptions* opts = TIFFOpenOptionsAlloc();
    TIFFOpenOptionsSetErrorHandlerExtR(opts, rememberTiffError, w.m_error.get());
    TIFFOpenOptionsSetWarningHandlerExtR(opts, ignoreTiffWarning, nullptr);
    // BigTIFF past 2 GiB of raw pixels: deflate may not bring noisy imagery under the classic 4 GiB offset limit.
    w.m_tif = TIFFOpenExt(path.c_str(), rawBytes > (std::uint64_t(2) << 30) ? "w8" : "w", opts);
    TIFFOpenOptionsFree(opts);
    if (!w.m_tif) return fileError(path.string(), "cannot create file (" + *w.m_error + ")");
    TIFF* t = w.m_tif;
    TIFFSetField(t, TIFFTAG_IMAGEWIDTH, std::uint32_t(width));
    TIFFSetField(t, TIFFTAG_IMAGELENGTH, std::uint32_t(height));
    TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, std::uint16_t(kChannels));
    TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, std::uint16_t(8));
    TIFFSetField(t, TIFFTAG_SAMPLEFORMAT, SAMPLEFORMAT_UINT);
    TIFFSetField(t, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
    TIFFSetField(t, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_RGB);
    TIFFSetField(t, TIFFTAG_COMPRESSION, COMPRESSION_ADOBE_DEFLATE);
    TIFFSetField(t, TIFFTAG_PREDICTOR, PREDICTOR_HORIZONTAL);
    TIFFSetField(t, TIFFTAG_TILEWIDTH, std::uint32_t(tileSize));
    TIFFSetField(t, TIFFTAG_TILELENGTH, std::uint32_t(tileSize));
    return w;
}

TiledTiffWriter::TiledTiffWriter(TiledTiffWriter&& other) noexcept { *this = std::move(other); }

TiledTiffWriter& TiledTiffWriter::operator=(TiledTiffWriter&& other) noexcept {
    if (this != &other) {
        if (m_tif) TIFFClose(m_tif);
        m_path = std::move(other.m_path);
        m_tif = std::exchange(other.m_tif, nullptr);
        m_width = other.m_width;
        m_height = other.m_height;
        m_tileSize = other.m_tileSize;
        m_level = other.m_level;
        m_threads = other.m_threads;
        m_nextTileRow = other.m_nextTileRow;
        m_error = std::move(other.m_error);
        m_compressed = std::move(other.m_compressed);
    }
    return *this;
}

TiledTiffWriter::~TiledTiffWriter() {
    if (m_tif) TIFFClose(m_tif);
}

Status TiledTiffWriter::fail(const std::string& what) {
    if (m_tif) TIFFClose(m_tif);
    m_tif = nullptr;
    return fileError(m_path.string(), what + (m_error->empty() ? std::string() : " (" + *m_error + ")"));
}

Status TiledTiffWriter::writeTileRow(const std::uint8_t* rows, int rowCount) {
    assert(m_tif && "TiledTiffWriter::writeTileRow(): file is closed");
    const int y0 = m_nextTileRow * m_tileSize;
    assert(y0 < m_height && rowCount == std::min(m_tileSize, m_height - y0) &&
           "TiledTiffWriter::writeTileRow(): wrong row count");
    const int ts = m_tileSize;
    const size_t tileRowBytes = size_t(ts) * kChannels;
    const size_t tileBytes = tileRowBytes * size_t(ts);
    const size_t srcRowBytes = size_t(m_width) * kChannels;
    const int tilesAcross = (m_width + ts - 1) / ts;
    // Compress a bounded chunk of tiles at a time so a 65536-wide row never holds all its compressed tiles at once.
    const int chunk = std::max(16, m_threads * 8);
    m_compressed.resize(size_t(chunk));
    const size_t threads = static_cast<size_t>(m_threads);
    std::vector<std::vector<std::uint8_t>> scratch(threads, std::vector<std::uint8_t>(tileBytes));
    std::vector<std::unique_ptr<libdeflate_compressor, CompressorDeleter>> compressors(threads);
    for (auto& c : compressors) {
        c.reset(libdeflate_alloc_compressor(m_level));
        if (!c) return fail("out of memory for the compressor");
    }
    for (int first = 0; first < tilesAcross; first += chunk) {
        const int count = std::min(chunk, tilesAcross - first);
        parallelIndices(count, m_threads, [&](int i, int worker) {
            const int x0 = (first + i) * ts;
            const int w = std::min(ts, m_width - x0);
            std::uint8_t* tile = scratch[size_t(worker)].data();
            for (int y = 0; y < ts; ++y) {
                std::uint8_t* dst = tile + size_t(y) * tileRowBytes;
                size_t copied = 0;
                if (y < rowCount) {
                    copied = size_t(w) * kChannels;
                    std::memcpy(dst, rows + size_t(y) * srcRowBytes + size_t(x0) * kChannels, copied);
                }
                std::memset(dst + copied, 0, tileRowBytes - copied); // edge tiles: zero padding
                // TIFF predictor 2 (horizontal differencing), per channel, right to left, modulo 256.
                for (size_t k = tileRowBytes - 1; k >= kChannels; --k) dst[k] = std::uint8_t(dst[k] - dst[k - kChannels]);
            }
            libdeflate_compressor* c = compressors[size_t(worker)].get();
            std::vector<std::uint8_t>& out = m_compressed[size_t(i)];
            out.resize(libdeflate_zlib_compress_bound(c, tileBytes));
            out.resize(libdeflate_zlib_compress(c, tile, tileBytes, out.data(), out.size()));
        });
        for (int i = 0; i < count; ++i) {
            std::vector<std::uint8_t>& out = m_compressed[size_t(i)];
            const std::uint32_t index = TIFFComputeTile(m_tif, std::uint32_t((first + i) * ts), std::uint32_t(y0), 0, 0);
            if (out.empty() || TIFFWriteRawTile(m_tif, index, out.data(), tmsize_t(out.size())) < 0)
                return fail("cannot write tile (disk full?)");
        }
    }
    ++m_nextTileRow;
    return Ok{};
}

Status TiledTiffWriter::close() {
    assert(m_tif && "TiledTiffWriter::close(): already closed");
    assert(m_nextTileRow * m_tileSize >= m_height && "TiledTiffWriter::close(): tile rows missing");
    if (!TIFFFlush(m_tif)) return fail("cannot write the TIFF directory (disk full?)");
    TIFFClose(m_tif);
    m_tif = nullptr;
    m_compressed.clear();
    return Ok{};
}

} // namespace seasonview
