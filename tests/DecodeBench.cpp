// Side by side: BandReader's own parallel tile decoders against GDAL's multi-threaded reads (the GTiff driver with
// NUM_THREADS=ALL_CPUS, the same bands of 1024 rows), on a synthetic 4096² season written three ways (Zstandard,
// deflate, JPEG-in-TIFF YCbCr), as `seasonview synth --compression` writes them. Not a test: run by hand,
//   build/tests/seasonview_decode_bench [--benchmark_repetitions=3]
// docs/benchmarks.md quotes its MP/s. Fixtures go to $TMPDIR/seasonview-decode-bench (made once).
// Also the first-touch tile check (ZstdTileCheck) of the Zstandard season: by the CRC-32 each tile carries, and by
// decoding the tiles (the same file with the CRC trailers taken off, as another writer's file), next to libtiff
// decoding the tiles once (what OpenImageIO does for the block loader in any case); docs/performance.md quotes it.
#include "BandReader.h"
#include "SyntheticScene.h"
#include "ZstdTileCheck.h"

#include <benchmark/benchmark.h>
#include <gdal_priv.h>
#include <tiffio.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <vector>

using namespace seasonview;

namespace {

namespace fs = std::filesystem;

const fs::path& fixture(TiffCompression c) {
    static std::map<TiffCompression, fs::path> made;
    auto it = made.find(c);
    if (it != made.end()) return it->second;
    const fs::path dir = fs::temp_directory_path() / "seasonview-decode-bench" / tiffCompressionName(c);
    if (!fs::exists(dir / "leafon.tif")) {
        SynthOptions o;
        o.sizeM = 1024;
        o.gsd = 0.25;
        o.city = false;
        o.compression = c;
        auto r = generateSyntheticScene(o, dir);
        if (!r) std::fprintf(stderr, "%s\n", r.message().c_str());
    }
    return made.emplace(c, dir / "leafon.tif").first->second;
}

void ownDecoder(benchmark::State& state, TiffCompression c) {
    const fs::path& file = fixture(c);
    std::int64_t pixels = 0;
    for (auto _ : state) {
        auto r = BandReader::open(file, 1024);
        if (!r || !r->decodesTilesItself()) {
            state.SkipWithError("not decoded by the own decoder");
            return;
        }
        std::vector<std::uint8_t> buf(size_t(r->width()) * size_t(r->bandRows()) * 3);
        for (int y = 0; y < r->height(); y += r->bandRows()) {
            auto st = r->read(y, std::min(r->height(), y + r->bandRows()), 3, SampleType::U8, buf.data());
            if (!st) state.SkipWithError(st.message().c_str());
        }
        pixels += std::int64_t(r->width()) * r->height();
    }
    state.counters["MP/s"] = benchmark::Counter(double(pixels) / 1e6, benchmark::Counter::kIsRate);
}

void gdalDecoder(benchmark::State& state, TiffCompression c) {
    const fs::path& file = fixture(c);
    GDALAllRegister();
    std::int64_t pixels = 0;
    for (auto _ : state) {
        const char* open[] = {"NUM_THREADS=ALL_CPUS", nullptr};
        GDALDataset* ds =
            GDALDataset::FromHandle(GDALOpenEx(file.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, nullptr, open, nullptr));
        const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
        std::vector<std::uint8_t> buf(size_t(w) * 1024 * 3);
        int bands[3] = {1, 2, 3};
        for (int y = 0; y < h; y += 1024) {
            const int rows = std::min(1024, h - y);
            if (ds->RasterIO(GF_Read, 0, y, w, rows, buf.data(), w, rows, GDT_Byte, 3, bands, 3, 3 * w, 1, nullptr) !=
                CE_None)
                state.SkipWithError("GDAL read failed");
        }
        GDALClose(GDALDataset::ToHandle(ds));
        pixels += std::int64_t(w) * h;
    }
    state.counters["MP/s"] = benchmark::Counter(double(pixels) / 1e6, benchmark::Counter::kIsRate);
}

/// The Zstandard fixture rewritten tile by tile without the CRC trailers (GeoTiffStreamWriter's tiles, as a writer
/// that appends none would have left them).
fs::path untrailed() {
    const fs::path& src = fixture(TiffCompression::Zstd);
    const fs::path dst = src.parent_path() / "leafon_untrailed.tif";
    if (fs::exists(dst)) return dst;
    TIFF* in = TIFFOpen(src.c_str(), "r");
    TIFF* out = TIFFOpen(dst.c_str(), "w8");
    if (!in || !out) {
        std::fprintf(stderr, "%s: cannot open\n", src.c_str());
        std::exit(1);
    }
    std::uint32_t u32 = 0;
    std::uint16_t u16 = 0;
    for (ttag_t tag : {TIFFTAG_IMAGEWIDTH, TIFFTAG_IMAGELENGTH, TIFFTAG_TILEWIDTH, TIFFTAG_TILELENGTH})
        if (TIFFGetField(in, tag, &u32)) TIFFSetField(out, tag, u32);
    for (ttag_t tag : {TIFFTAG_SAMPLESPERPIXEL, TIFFTAG_BITSPERSAMPLE, TIFFTAG_SAMPLEFORMAT, TIFFTAG_PHOTOMETRIC,
                       TIFFTAG_PLANARCONFIG, TIFFTAG_COMPRESSION, TIFFTAG_PREDICTOR})
        if (TIFFGetField(in, tag, &u16)) TIFFSetField(out, tag, u16);
    std::vector<std::uint8_t> raw;
    for (std::uint32_t t = 0; t < TIFFNumberOfTiles(in); ++t) {
        raw.resize(size_t(TIFFGetStrileByteCount(in, t)));
        TIFFReadRawTile(in, t, raw.data(), tmsize_t(raw.size()));
        if (verifyTileChecksum(raw.data(), raw.size()) == TileChecksum::Matches) raw.resize(raw.size() - kTileChecksumBytes);
        TIFFWriteRawTile(out, t, raw.data(), tmsize_t(raw.size()));
    }
    TIFFClose(in);
    TIFFClose(out);
    return dst;
}

void tileCheck(benchmark::State& state, bool crc) {
    const fs::path file = crc ? fixture(TiffCompression::Zstd) : untrailed();
    std::uint32_t w = 0, h = 0;
    if (TIFF* t = TIFFOpen(file.c_str(), "r")) {
        TIFFGetField(t, TIFFTAG_IMAGEWIDTH, &w);
        TIFFGetField(t, TIFFTAG_IMAGELENGTH, &h);
        TIFFClose(t);
    }
    std::int64_t pixels = 0;
    for (auto _ : state) {
        ZstdTileCheck check; // each tile once per object: a fresh one checks them all again
        if (auto st = check.check(file, 0, 0, int(w), int(h)); !st) state.SkipWithError(st.message().c_str());
        pixels += std::int64_t(w) * h;
    }
    state.counters["MP/s"] = benchmark::Counter(double(pixels) / 1e6, benchmark::Counter::kIsRate);
}

void libtiffDecode(benchmark::State& state) {
    const fs::path& file = fixture(TiffCompression::Zstd);
    std::int64_t pixels = 0;
    for (auto _ : state) {
        TIFF* t = TIFFOpen(file.c_str(), "r");
        std::vector<std::uint8_t> tile(size_t(TIFFTileSize(t)));
        for (std::uint32_t i = 0; i < TIFFNumberOfTiles(t); ++i)
            if (TIFFReadEncodedTile(t, i, tile.data(), tmsize_t(tile.size())) < 0) state.SkipWithError("decode failed");
        std::uint32_t w = 0, h = 0;
        TIFFGetField(t, TIFFTAG_IMAGEWIDTH, &w);
        TIFFGetField(t, TIFFTAG_IMAGELENGTH, &h);
        TIFFClose(t);
        pixels += std::int64_t(w) * h;
    }
    state.counters["MP/s"] = benchmark::Counter(double(pixels) / 1e6, benchmark::Counter::kIsRate);
}

} // namespace

BENCHMARK_CAPTURE(tileCheck, crc, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(tileCheck, decode, false)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(libtiffDecode)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(ownDecoder, zstd, TiffCompression::Zstd)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(gdalDecoder, zstd, TiffCompression::Zstd)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(ownDecoder, deflate, TiffCompression::Deflate)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(gdalDecoder, deflate, TiffCompression::Deflate)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(ownDecoder, jpeg, TiffCompression::Jpeg)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(gdalDecoder, jpeg, TiffCompression::Jpeg)->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK_MAIN();
