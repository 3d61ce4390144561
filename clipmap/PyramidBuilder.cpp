#include "PyramidBuilder.h"

#include "BandReader.h"
#include "GeoTiffStreamWriter.h"

#include <algorithm>
#include <cassert>
#include <cstdio>
#include <cstring>
#include <future>

namespace seasonview {

namespace {

constexpr size_t kRgb = 3;


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
        const size_t rowBytes = size_t(width) * kRgb;
        std::uint8_t* dst = l.band.data() + size_t(l.bandRows) * rowBytes;
        std::memcpy(dst, row, rowBytes);
        ++l.bandRows;
        ++l.rowsPushed;
        const bool last = l.rowsPushed == l.writer.height();
        const bool emit = k + 1 < levels.size() && (l.bandRows % 2 == 0 || last);
        if (emit) downsampleRow(l.bandRows % 2 == 0 ? dst - rowBytes : dst, l.bandRows % 2 == 0 ? dst : nullptr, width,
                                l.halved.data());
        if (l.bandRows == l.tileSize || last) {
            if (auto st = l.writer.writeRows(l.rowsPushed - l.bandRows, l.bandRows, l.band.data()); !st) return st;
            l.bandRows = 0;
        }
        if (!emit) return Ok{};
        row = l.halved.data();
    }
}

/// The source image opened for banded reading of its first three channels (or its first one, for grey).
struct Source {
    BandReader reader;
    int width = 0, height = 0, channels = 0; // channels read: 3 (RGB) or 1 (grey)
    bool sixteenBit = false;
    int bandRows = 0;                        // rows per read; whole tiles for tiled files

    /// Reads rows [y0, y1) into `buf` (interleaved, native 8/16-bit). Returns "" or the error line (names the file).
    std::string read(int y0, int y1, void* buf) const {
        Status st = reader.read(y0, y1, channels, sixteenBit ? SampleType::U16 : SampleType::U8, buf);
        return st ? std::string() : st.message();
    }
};

Result<Source> openSource(const ImageryLayer& layer, int tileSize) {
    const std::string path = layer.info.path.string();
    auto reader = BandReader::open(layer.info.path, tileSize);
    if (!reader) return reader.error();
    Source s{std::move(*reader)};
    s.width = s.reader.width();
    s.height = s.reader.height();
    if (s.width != layer.info.width || s.height != layer.info.height)
        return fileError(path, "changed while preparing (now " + std::to_string(s.width) + "x" +
                                   std::to_string(s.height) + ", was " + std::to_string(layer.info.width) + "x" +
                                   std::to_string(layer.info.height) + ")");
    if (s.reader.type() != SampleType::U8 && s.reader.type() != SampleType::U16)
        return fileError(path, std::string("unsupported sample type ") + sampleTypeName(s.reader.type()) +
                                   " (imagery must be 8- or 16-bit)");
    s.sixteenBit = s.reader.type() == SampleType::U16;
    s.channels = s.reader.channels() >= 3 ? 3 : 1;
    s.bandRows = s.reader.bandRows();
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
        GeoTiffWriteOptions options;
        options.tileSize = tileSize;
        // Zstandard: the clipmap loader decodes these tiles (libtiff's codec) five times faster than deflate ones,
        // at the same size; caches of deflate tiles from earlier versions still read.
        options.compression = TiffCompression::Zstd;
        auto writer = GeoTiffStreamWriter::open(level.file, w, h, int(kRgb), SampleType::U8, std::nullopt, options);
        if (!writer) return writer.error();
        LevelStream s{std::move(*writer), tileSize, {}, {}, 0, 0};
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
        if (const std::string e = pending.get(); !e.empty()) return Error{e};
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
        if (auto st = s.writer.finish(); !st) return st.error();
    if (progress) progress(1.0, "done");
    return levels;
}

} // namespace seasonview
