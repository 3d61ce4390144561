#include "PyramidBuilder.h"

#include "TiledTiffWriter.h"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cassert>
#include <cstdio>
#include <cstring>
#include <future>

namespace seasonview {

namespace {

constexpr size_t kRgb = 3;

std::string firstLine(std::string s) {
    if (const auto nl = s.find('\n'); nl != std::string::npos) s.resize(nl);
    while (!s.empty() && (s.back() == ' ' || s.back() == '.')) s.pop_back();
    return s;
}

/// One level being written: the rows of its current tile row, and the writer they go to when it is full.
struct LevelStream {
    TiledTiffWriter writer;
    std::vector<std::uint8_t> band;   // tileSize rows of width×3 bytes
    std::vector<std::uint8_t> halved; // the next level's row made from this level's last row pair
    int bandRows = 0;                 // rows of the current tile row filled
    int rowsPushed = 0;               // rows of this level received so far
};

/// Appends one row to level k and, every second row (or the last one of an odd height), pushes the box-filtered
/// row on to level k+1; a tile row that is complete is compressed and written. Pairs never straddle tile rows
/// because the tile size is even.
Status pushRow(std::vector<LevelStream>& levels, size_t k, const std::uint8_t* row) {
    for (;; ++k) {
        LevelStream& l = levels[k];
        const int width = l.writer.width();
        const size_t rowBytes = size_t(width) * kRgb;
        std::uint8_t* dst = l.band.data() + size_t(l.bandRows) * rowBytes;
        std::memcpy(dst, row, rowBytes);
        ++l.bandRows;
        ++l.rowsPushed;
        const bool last = l.rowsPushed == l.writer.height();
        const bool emit = k + 1 < levels.size() && (l.bandRows % 2 == 0 || last);
        if (emit) downsampleRow(l.bandRows % 2 == 0 ? dst - rowBytes : dst, l.bandRows % 2 == 0 ? dst : nullptr, width,
                                l.halved.data());
        if (l.bandRows == l.writer.tileSize() || last) {
            if (auto st = l.writer.writeTileRow(l.band.data(), l.bandRows); !st) return st;
            l.bandRows = 0;
        }
        if (!emit) return Ok{};
        row = l.halved.data();
    }
}

/// The source image opened for banded reading of its first three channels (or its first one, for grey).
struct Source {
    std::unique_ptr<OIIO::ImageInput> in;
    int width = 0, height = 0, channels = 0; // channels read: 3 (RGB) or 1 (grey)
    bool sixteenBit = false;
    int tileHeight = 0;                      // 0 for scanline files
    int bandRows = 0;                        // rows per read; a multiple of the tile height for tiled files

    /// Reads rows [y0, y1) into `buf` (interleaved, native 8/16-bit). Returns "" or the reader's error.
    std::string read(int y0, int y1, void* buf) const {
        const OIIO::TypeDesc t = sixteenBit ? OIIO::TypeDesc::UINT16 : OIIO::TypeDesc::UINT8;
        const bool ok = tileHeight > 0 ? in->read_tiles(0, 0, 0, width, y0, y1, 0, 1, 0, channels, t, buf)
                                       : in->read_scanlines(0, 0, y0, y1, 0, 0, channels, t, buf);
        if (ok) return {};
        const std::string e = firstLine(in->geterror());
        return e.empty() ? "read failed" : e;
    }
};

Result<Source> openSource(const ImageryLayer& layer, int tileSize) {
    const std::string path = layer.info.path.string();
    Source s;
    s.in = OIIO::ImageInput::open(path);
    if (!s.in) {
        std::error_code ec;
        if (!std::filesystem::exists(layer.info.path, ec)) return fileError(path, "file not found");
        const std::string e = firstLine(OIIO::geterror());
        return fileError(path, "not a readable image" + (e.empty() ? std::string() : " (" + e + ")"));
    }
    const OIIO::ImageSpec& spec = s.in->spec();
    s.width = spec.width;
    s.height = spec.height;
    if (s.width != layer.info.width || s.height != layer.info.height)
        return fileError(path, "changed while preparing (now " + std::to_string(s.width) + "x" +
                                   std::to_string(s.height) + ", was " + std::to_string(layer.info.width) + "x" +
                                   std::to_string(layer.info.height) + ")");
    if (spec.format != OIIO::TypeDesc::UINT8 && spec.format != OIIO::TypeDesc::UINT16)
        return fileError(path, std::string("unsupported sample type ") + spec.format.c_str() +
                                   " (imagery must be 8- or 16-bit)");
    s.sixteenBit = spec.format == OIIO::TypeDesc::UINT16;
    s.channels = spec.nchannels >= 3 ? 3 : 1;
    if (spec.tile_width > 0 && spec.tile_height > 0 && spec.tile_depth <= 1) {
        s.tileHeight = spec.tile_height;
        s.bandRows = s.tileHeight * std::max(1, tileSize / s.tileHeight);
    } else {
        s.bandRows = tileSize;
    }
    return s;
}

/// Per-channel lookup table source sample -> stretched 8-bit value (256 or 65536 entries per channel).
std::vector<std::uint8_t> stretchTable(const Stretch& stretch, int channel, bool sixteenBit) {
    std::vector<std::uint8_t> lut(sixteenBit ? 65536 : 256);
    for (size_t v = 0; v < lut.size(); ++v) lut[v] = stretch.apply(channel, float(v));
    return lut;
}

} // namespace

std::vector<std::pair<int, int>> pyramidLevelSizes(int width, int height) {
    assert(width > 0 && height > 0 && "pyramidLevelSizes(): empty image");
    std::vector<std::pair<int, int>> sizes{{width, height}};
    while (width > 1 || height > 1) {
        width = (width + 1) / 2;
        height = (height + 1) / 2;
        sizes.emplace_back(width, height);
    }
    return sizes;
}

std::string pyramidLevelFileName(int level) {
    char name[32];
    std::snprintf(name, sizeof name, "level_%02d.tif", level);
    return name;
}

void downsampleRow(const std::uint8_t* a, const std::uint8_t* b, int width, std::uint8_t* out) {
    const int pairs = width / 2;
    if (b) {
        for (int x = 0; x < pairs; ++x)
            for (size_t c = 0; c < kRgb; ++c) {
                const size_t i = size_t(2 * x) * kRgb + c;
                out[size_t(x) * kRgb + c] = std::uint8_t((a[i] + a[i + kRgb] + b[i] + b[i + kRgb] + 2) / 4);
            }
    } else {
        for (int x = 0; x < pairs; ++x)
            for (size_t c = 0; c < kRgb; ++c) {
                const size_t i = size_t(2 * x) * kRgb + c;
                out[size_t(x) * kRgb + c] = std::uint8_t((a[i] + a[i + kRgb] + 1) / 2);
            }
    }
    if (width % 2 == 1) { // the last column has no right neighbour: average what exists
        const size_t i = size_t(width - 1) * kRgb;
        for (size_t c = 0; c < kRgb; ++c)
            out[size_t(pairs) * kRgb + c] = b ? std::uint8_t((a[i + c] + b[i + c] + 1) / 2) : a[i + c];
    }
}

Result<std::vector<PyramidLevel>> buildPyramidLevels(const ImageryLayer& layer, const std::filesystem::path& folder,
                                                     int tileSize, const ProgressFn& progress) {
    assert(tileSize > 0 && tileSize % 16 == 0 && "buildPyramidLevels(): tile size must be a positive multiple of 16");
    auto opened = openSource(layer, tileSize);
    if (!opened) return opened.error();
    const Source& src = *opened;

    std::vector<PyramidLevel> levels;
    std::vector<LevelStream> streams;
    const auto sizes = pyramidLevelSizes(src.width, src.height);
    for (size_t k = 0; k < sizes.size(); ++k) {
        const auto [w, h] = sizes[k];
        PyramidLevel level{folder / pyramidLevelFileName(int(k)), w, h};
        auto writer = TiledTiffWriter::create(level.file, w, h, tileSize);
        if (!writer) return writer.error();
        LevelStream s{std::move(*writer), {}, {}, 0, 0};
        s.band.resize(size_t(w) * kRgb * size_t(std::min(tileSize, h)));
        if (k + 1 < sizes.size()) s.halved.resize(size_t(sizes[k + 1].first) * kRgb);
        streams.push_back(std::move(s));
        levels.push_back(std::move(level));
    }

    std::vector<std::uint8_t> lut[3];
    for (int c = 0; c < 3; ++c) lut[c] = stretchTable(layer.stretch, src.channels == 3 ? c : 0, src.sixteenBit);
    const size_t sampleBytes = src.sixteenBit ? 2 : 1;
    const size_t srcRowBytes = size_t(src.width) * size_t(src.channels) * sampleBytes;
    // uint16 storage serves both sample types: 8-bit rows are read through unsigned char pointers.
    std::vector<std::uint16_t> buffers[2];
    for (auto& b : buffers) b.resize((srcRowBytes * size_t(std::min(src.bandRows, src.height)) + 1) / 2);
    std::vector<std::uint8_t> rgb(size_t(src.width) * kRgb);
    auto toRgb = [&](const auto* samples) { // one source row (8- or 16-bit) -> stretched RGB8 in `rgb`
        const size_t n = size_t(src.channels);
        for (size_t x = 0, w = size_t(src.width); x < w; ++x)
            for (size_t c = 0; c < kRgb; ++c) rgb[x * kRgb + c] = lut[c][samples[x * n + (n == 3 ? c : 0)]];
    };

    // Band b+1 is read on another thread while band b is converted, filtered and compressed. Declared after the
    // buffers: a future from std::async waits in its destructor, so an early return never leaves a read running.
    const int bands = (src.height + src.bandRows - 1) / src.bandRows;
    auto readBand = [&](int b) {
        const int y0 = b * src.bandRows;
        return std::async(std::launch::async, [&src, &buffers, y0, b] {
            return src.read(y0, std::min(src.height, y0 + src.bandRows), buffers[b % 2].data());
        });
    };
    std::future<std::string> pending = readBand(0);
    for (int b = 0; b < bands; ++b) {
        if (const std::string e = pending.get(); !e.empty())
            return fileError(layer.info.path.string(), "truncated or corrupt image data (" + e + ")");
        if (b + 1 < bands) pending = readBand(b + 1);
        const int y0 = b * src.bandRows, y1 = std::min(src.height, y0 + src.bandRows);
        for (int y = y0; y < y1; ++y) {
            const size_t offset = size_t(y - y0) * srcRowBytes; // bytes into the band
            if (src.sixteenBit) toRgb(buffers[b % 2].data() + offset / 2);
            else toRgb(reinterpret_cast<const std::uint8_t*>(buffers[b % 2].data()) + offset);
            if (auto st = pushRow(streams, 0, rgb.data()); !st) return st.error();
        }
        if (progress) progress(0.99 * double(y1) / double(src.height), "building pyramid");
    }
    for (auto& s : streams)
        if (auto st = s.writer.close(); !st) return st.error();
    if (progress) progress(1.0, "done");
    return levels;
}

} // namespace seasonview
