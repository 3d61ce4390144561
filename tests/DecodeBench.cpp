// Side by side: BandReader's own parallel tile decoders against GDAL's multi-threaded reads (the GTiff driver with
// NUM_THREADS=ALL_CPUS, the same bands of 1024 rows), on a synthetic 4096² season written three ways (Zstandard,
// deflate, JPEG-in-TIFF YCbCr), as `seasonview synth --compression` writes them. Not a test: run by hand,
//   build/tests/seasonview_decode_bench [--benchmark_repetitions=3]
// docs/benchmarks.md quotes its MP/s. Fixtures go to $TMPDIR/seasonview-decode-bench (made once).
#include "BandReader.h"
#include "SyntheticScene.h"

#include <benchmark/benchmark.h>
#include <gdal_priv.h>

#include <cstdio>
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

} // namespace

BENCHMARK_CAPTURE(ownDecoder, zstd, TiffCompression::Zstd)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(gdalDecoder, zstd, TiffCompression::Zstd)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(ownDecoder, deflate, TiffCompression::Deflate)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(gdalDecoder, deflate, TiffCompression::Deflate)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(ownDecoder, jpeg, TiffCompression::Jpeg)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(gdalDecoder, jpeg, TiffCompression::Jpeg)->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK_MAIN();
