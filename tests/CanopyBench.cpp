// The canopy view's compute passes alone, on a 1024² synthetic pair in a 512² clipmap, glFinish after each iteration:
//  - derive/METHOD: the GPU segmentation (shaders/canopy_derive.comp through CanopyClipmapGL::rederiveAll()) of every
//    resident block; `ms_per_block` is what the canopy view pays for each block that arrives while flying;
//  - derive_cpu/METHOD: the same rule on the CPU (CanopyDerive.h, what `--canopy-derive cpu`'s loader workers run), one
//    thread, every 64² block of level 0 with its halo, both seasons read through a PyramidBlockSource (warm cache);
//  - trunk_search/cpu, trunk_search/gpu: one crown-centre search of the trunks' level through TrunksGL::find(), on the
//    CPU (CrownSearch.h, what a worker runs while the frames go on) or the GPU (shaders/trunk_find.comp).
// Not a test: run by hand,
//   build/tests/seasonview_canopy_bench [--benchmark_repetitions=3]
// docs/performance.md quotes it. Needs a GL 4.5 context (headless EGL: llvmpipe without a GPU).
#include "BlockLoader.h"
#include "CanopyClipmapGL.h"
#include "CanopyDerive.h"
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

void deriveCpu(benchmark::State& state, SegmentationMethod method) {
    Fixture& f = fixture();
    if (!f.ok) return state.SkipWithError("no GL context or no synthetic scene");
    auto on = readImageU8(f.pyramids[0].levels[0].file, 3), off = readImageU8(f.pyramids[1].levels[0].file, 3);
    if (!on || !off) return state.SkipWithError("cannot read the pair");
    const SegmentationStats stats = statsFromHistograms(pairHistograms(*on, *off, true, true), method);
    PyramidBlockSource source({{f.pyramids[0].levels[0].file}, {f.pyramids[1].levels[0].file}});
    SegmentationParams params;
    params.method = method;
    const std::vector<CanopyGroup> groups = canopyGroups(params, 16, std::min(kSegMaxK, 3 * effectiveK(params)), 0);
    const int halo = canopyDeriveHalo(method, groups), block = 64;
    const glm::ivec2 size(f.pyramids[0].width(), f.pyramids[0].height());
    std::vector<std::uint8_t> a, b, values(size_t(block) * block);
    std::int64_t blocks = 0;
    for (auto _ : state) {
        for (int by = 0; by * block < size.y; ++by)
            for (int bx = 0; bx * block < size.x; ++bx) {
                const TexelRect t{bx * block, by * block, std::min(size.x, (bx + 1) * block),
                                  std::min(size.y, (by + 1) * block)};
                const TexelRect r{std::max(0, t.x0 - halo), std::max(0, t.y0 - halo), std::min(size.x, t.x1 + halo),
                                  std::min(size.y, t.y1 + halo)};
                a.resize(size_t(r.area()) * 4);
                b.resize(a.size());
                if (!source.read(0, 0, r, a.data()) || !source.read(1, 0, r, b.data()))
                    return state.SkipWithError("cannot read a block");
                deriveCanopyTexels(a.data(), b.data(), r, size, t, method, stats, groups, values.data());
                benchmark::DoNotOptimize(values.data());
                ++blocks;
            }
    }
    state.counters["ms_per_block"] = benchmark::Counter(double(blocks) * 1e-3, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void trunkSearch(benchmark::State& state, bool cpu) {
    Fixture& f = fixture();
    if (!f.ok) return state.SkipWithError("no GL context or no synthetic scene");
    auto canopy = canopyLayer(f, SegmentationMethod::Default);
    if (!canopy) return state.SkipWithError(canopy.message().c_str());
    (*canopy)->completeSynchronously();
    TrunkOptions to;
    to.cpuSearch = cpu;
    auto trunks = TrunksGL::create(*f.scene, *f.clip, **canopy, to);
    if (!trunks) return state.SkipWithError(trunks.message().c_str());
    int found = 0;
    for (auto _ : state) {
        found = (*trunks)->find(); // reads the count back: waits for the search
    }
    state.counters["trunks"] = found;
    state.counters["level"] = (*trunks)->level();
}

} // namespace

BENCHMARK_CAPTURE(trunkSearch, cpu, true)->Name("trunk_search/cpu")->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(trunkSearch, gpu, false)->Name("trunk_search/gpu")->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(derive, default_method, SegmentationMethod::Default)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(derive, pixel, SegmentationMethod::Pixel)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(derive, neighborhood, SegmentationMethod::Neighborhood)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(derive, equalized, SegmentationMethod::Equalized)->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK_CAPTURE(deriveCpu, default_method, SegmentationMethod::Default)->Name("derive_cpu/default_method")->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(deriveCpu, pixel, SegmentationMethod::Pixel)->Name("derive_cpu/pixel")->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(deriveCpu, equalized, SegmentationMethod::Equalized)->Name("derive_cpu/equalized")->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK_MAIN();
