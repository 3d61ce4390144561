// The canopy view's compute passes alone, on a 1024² synthetic pair in a 512² clipmap, glFinish after each iteration:
//  - derive/METHOD: the GPU segmentation (shaders/canopy_derive.comp through CanopyClipmapGL::rederiveAll()) of every
//    resident block; `ms_per_block` is what the canopy view pays for each block that arrives while flying;
//  - trunk_search: one crown-centre search of the trunks' level (shaders/trunk_find.comp through TrunksGL::find()).
// Not a test: run by hand,
//   build/tests/seasonview_canopy_bench [--benchmark_repetitions=3]
// docs/performance.md quotes it. Needs a GL 4.5 context (headless EGL: llvmpipe without a GPU).
#include "CanopyClipmapGL.h"
#include "ClipmapGL.h"
#include "RenderJob.h"
#include "Segmentation.h"
#include "SegmentationStats.h"
#include "SyntheticScene.h"
#include "TrunksGL.h"
#include "TestUtil.h"

#include <benchmark/benchmark.h>

#include <cstdio>
#include <optional>

using namespace seasonview;

namespace {

struct Fixture {
    test::TempDir dir{"canopy-derive-bench"};
    std::optional<Scene> scene;
    std::vector<ImagePyramid> pyramids;
    std::unique_ptr<ClipmapGL> clip;
    bool ok = false;

    Fixture() {
        if (!test::headlessContext()) return;
        SynthOptions o;
        o.sizeM = 256;
        o.gsd = 0.25; // 1024² per season
        o.seed = 7;
        o.city = false;
        if (auto r = generateSyntheticScene(o, dir.path()); !r) {
            std::fprintf(stderr, "%s\n", r.message().c_str());
            return;
        }
        auto src = parseManifest(dir / "scene.json");
        if (!src) return;
        auto s = loadScene(*src, dir / "cache");
        if (!s) {
            std::fprintf(stderr, "%s\n", s.message().c_str());
            return;
        }
        scene = std::move(*s);
        auto p = app::preparePyramids(*scene, dir / "cache");
        if (!p) {
            std::fprintf(stderr, "%s\n", p.message().c_str());
            return;
        }
        pyramids = std::move(*p);
        ClipmapOptions co;
        co.size = 512;
        auto c = ClipmapGL::create(pyramids, co);
        if (!c) {
            std::fprintf(stderr, "%s\n", c.message().c_str());
            return;
        }
        clip = std::move(*c);
        const ClipmapLayout& L = clip->schedule().layout();
        clip->update(std::vector<glm::dvec2>(size_t(L.clipLevels()), glm::dvec2(512.0, 512.0)));
        clip->completeSynchronously();
        ok = true;
    }
};

Fixture& fixture() {
    static Fixture f;
    return f;
}

Result<std::unique_ptr<CanopyClipmapGL>> canopyLayer(const Fixture& f, SegmentationMethod method) {
    auto on = readImageU8(f.pyramids[0].levels[0].file, 3), off = readImageU8(f.pyramids[1].levels[0].file, 3);
    if (!on) return on.error();
    if (!off) return off.error();
    CanopyOptions o;
    o.params.method = method;
    return CanopyClipmapGL::create(*f.clip, statsFromHistograms(pairHistograms(*on, *off, true, true), method), o);
}

void derive(benchmark::State& state, SegmentationMethod method) {
    Fixture& f = fixture();
    if (!f.ok) return state.SkipWithError("no GL context or no synthetic scene");
    auto canopy = canopyLayer(f, method);
    if (!canopy) return state.SkipWithError(canopy.message().c_str());
    std::int64_t blocks = 0;
    for (auto _ : state) {
        blocks += (*canopy)->rederiveAll().blocksDerived;
        glFinish();
    }
    state.counters["blocks"] = benchmark::Counter(double(blocks) / double(state.iterations()));
    state.counters["ms_per_block"] = benchmark::Counter(double(blocks) * 1e-3, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void trunkSearch(benchmark::State& state) {
    Fixture& f = fixture();
    if (!f.ok) return state.SkipWithError("no GL context or no synthetic scene");
    auto canopy = canopyLayer(f, SegmentationMethod::Default);
    if (!canopy) return state.SkipWithError(canopy.message().c_str());
    (*canopy)->completeSynchronously();
    auto trunks = TrunksGL::create(*f.scene, *f.clip, **canopy);
    if (!trunks) return state.SkipWithError(trunks.message().c_str());
    int found = 0;
    for (auto _ : state) {
        found = (*trunks)->find(); // reads the count back: waits for the search
    }
    state.counters["trunks"] = found;
    state.counters["level"] = (*trunks)->level();
}

} // namespace

BENCHMARK(trunkSearch)->Name("trunk_search")->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(derive, default_method, SegmentationMethod::Default)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(derive, pixel, SegmentationMethod::Pixel)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(derive, neighborhood, SegmentationMethod::Neighborhood)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(derive, equalized, SegmentationMethod::Equalized)->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK_MAIN();
