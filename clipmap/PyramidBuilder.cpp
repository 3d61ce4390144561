#include "PyramidBuilder.h"

#include "GeoTiffStreamWriter.h"
#include "GridReader.h"

#include <algorithm>
#include <cassert>
#include <cstdio>
#include <cstring>
#include <future>

namespace seasonview {

namespace {

constexpr size_t kRgba = 4;


/// One level being written: the rows of its current tile row, and the writer they go to when it is full.
struct LevelStream {
    GeoTiffStreamWriter writer;
    int tileSize = 0;
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
        const size_t rowBytes = size_t(width) * kRgba;
        std::uint8_t* dst = l.band.data() + size_t(l.bandRows) * rowBytes;
        std::memcpy(dst, row, rowBytes);
        ++l.bandRows;
        ++l.rowsPushed;
        const bool last = l.rowsPushed == l.writer.height();
        const bool emit = k + 1 < levels.size() && (l.bandRows % 2 == 0 || last);
        if (emit) downsampleRow(l.bandRows % 2 == 0 ? dst - rowBytes : dst, l.bandRows % 2 == 0 ? dst : nullptr, width,
                                l.halved.data(), int(kRgba));
        if (l.bandRows == l.tileSize || last) {
            if (auto st = l.writer.writeRows(l.rowsPushed - l.bandRows, l.bandRows, l.band.data()); !st) return st;
            l.bandRows = 0;
        }
        if (!emit) return Ok{};
        row = l.halved.data();
    }
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

void downsampleRow(const std::uint8_t* a, const std::uint8_t* b, int width, std::uint8_t* out, int channels) {
    const size_t n = size_t(channels);
    const int pairs = width / 2;
    if (b) {
        for (int x = 0; x < pairs; ++x)
            for (size_t c = 0; c < n; ++c) {
                const size_t i = size_t(2 * x) * n + c;
                out[size_t(x) * n + c] = std::uint8_t((a[i] + a[i + n] + b[i] + b[i + n] + 2) / 4);
            }
    } else {
        for (int x = 0; x < pairs; ++x)
            for (size_t c = 0; c < n; ++c) {
                const size_t i = size_t(2 * x) * n + c;
                out[size_t(x) * n + c] = std::uint8_t((a[i] + a[i + n] + 1) / 2);
            }
    }
    if (width % 2 == 1) { // the last column has no right neighbour: average what exists
        const size_t i = size_t(width - 1) * n;
        for (size_t c = 0; c < n; ++c)
            out[size_t(pairs) * n + c] = b ? std::uint8_t((a[i + c] + b[i + c] + 1) / 2) : a[i + c];
    }
}

Result<std::vector<PyramidLevel>> buildPyramidLevels(const ImageryLayer& layer, const std::filesystem::path& folder,
                                                     int tileSize, const ProgressFn& progress) {
    assert(tileSize > 0 && tileSize % 16 == 0 && "buildPyramidLevels(): tile size must be a positive multiple of 16");
    const WorkingGrid grid = layer.grid();
    auto opened = GridReader::open(layer.source, grid, layer.resampling, tileSize);
    if (!opened) return opened.error();
    GridReader& src = *opened;
    const int width = grid.width, height = grid.height, bandRows = src.bandRows();
    const bool sixteenBit = layer.source.type == SampleType::U16;
    assert(layer.source.bands >= 3 && "buildPyramidLevels(): an RGB season (loadScene checks)");
    const int channels = 3;

    std::vector<PyramidLevel> levels;
    std::vector<LevelStream> streams;
    const auto sizes = pyramidLevelSizes(width, height);
    for (size_t k = 0; k < sizes.size(); ++k) {
        const auto [w, h] = sizes[k];
        PyramidLevel level{folder / pyramidLevelFileName(int(k)), w, h};
        GeoTiffWriteOptions options;
        options.tileSize = tileSize;
        // Zstandard: the clipmap loader decodes these tiles (libtiff's codec) five times faster than deflate ones,
        // at the same size. Alpha is associated (the colour is premultiplied by it).
        options.compression = TiffCompression::Zstd;
        options.associatedAlpha = true;
        auto writer = GeoTiffStreamWriter::open(level.file, w, h, int(kRgba), SampleType::U8, std::nullopt, options);
        if (!writer) return writer.error();
        LevelStream s{std::move(*writer), tileSize, {}, {}, 0, 0};
        s.band.resize(size_t(w) * kRgba * size_t(std::min(tileSize, h)));
        if (k + 1 < sizes.size()) s.halved.resize(size_t(sizes[k + 1].first) * kRgba);
        streams.push_back(std::move(s));
        levels.push_back(std::move(level));
    }

    std::vector<std::uint8_t> lut[3];
    for (int c = 0; c < 3; ++c) lut[c] = stretchTable(layer.stretch, c, sixteenBit);
    const size_t sampleBytes = sixteenBit ? 2 : 1;
    const size_t srcRowBytes = size_t(width) * size_t(channels) * sampleBytes;
    // uint16 storage serves both sample types: 8-bit rows are read through unsigned char pointers.
    std::vector<std::uint16_t> buffers[2];
    std::vector<std::uint8_t> coverage[2];
    for (int i = 0; i < 2; ++i) {
        buffers[i].resize((srcRowBytes * size_t(std::min(bandRows, height)) + 1) / 2);
        coverage[i].resize(size_t(width) * size_t(std::min(bandRows, height)));
    }
    std::vector<std::uint8_t> rgba(size_t(width) * kRgba);
    // One row (8- or 16-bit) -> stretched, premultiplied RGBA8 in `rgba`: alpha 255 where the season has data, and
    // (0, 0, 0, 0) where it has none.
    auto toRgba = [&](const auto* samples, const std::uint8_t* covered) {
        const size_t n = size_t(channels);
        for (size_t x = 0, w = size_t(width); x < w; ++x) {
            std::uint8_t* out = &rgba[x * kRgba];
            if (!covered[x]) {
                out[0] = out[1] = out[2] = out[3] = 0;
                continue;
            }
            for (size_t c = 0; c < 3; ++c) out[c] = lut[c][samples[x * n + c]];
            out[3] = 255;
        }
    };

    // Band b+1 is read (and warped) on another thread while band b is converted, filtered and compressed. Declared
    // after the buffers: a future from std::async waits in its destructor, so an early return never leaves a read
    // running.
    const int bands = (height + bandRows - 1) / bandRows;
    const SampleType type = sixteenBit ? SampleType::U16 : SampleType::U8;
    auto readBand = [&](int b) {
        const int y0 = b * bandRows;
        return std::async(std::launch::async, [&src, &buffers, &coverage, y0, b, height, bandRows, channels, type] {
            const Status st = src.read(y0, std::min(height, y0 + bandRows), channels, type, buffers[b % 2].data(),
                                       coverage[b % 2].data());
            return st ? std::string() : st.message();
        });
    };
    std::future<std::string> pending = readBand(0);
    for (int b = 0; b < bands; ++b) {
        if (const std::string e = pending.get(); !e.empty()) return Error{e};
        if (b + 1 < bands) pending = readBand(b + 1);
        const int y0 = b * bandRows, y1 = std::min(height, y0 + bandRows);
        for (int y = y0; y < y1; ++y) {
            const size_t offset = size_t(y - y0) * srcRowBytes; // bytes into the band
            const std::uint8_t* covered = coverage[b % 2].data() + size_t(y - y0) * size_t(width);
            if (sixteenBit) toRgba(buffers[b % 2].data() + offset / 2, covered);
            else toRgba(reinterpret_cast<const std::uint8_t*>(buffers[b % 2].data()) + offset, covered);
            if (auto st = pushRow(streams, 0, rgba.data()); !st) return st.error();
        }
        if (progress) progress(0.99 * double(y1) / double(height), src.direct() ? "building pyramid" : "warping");
    }
    for (auto& s : streams)
        if (auto st = s.writer.finish(); !st) return st.error();
    if (progress) progress(1.0, "done");
    return levels;
}

} // namespace seasonview
