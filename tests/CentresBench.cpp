// The clipmap level centres of one frame (clipmap/ClipmapCenters.h), placed on the render thread before the frame's
// uploads: `footprint` (the default) casts three rays per screen sample and mean-shifts a window per level over them.
// Run by hand; docs/benchmarks.md quotes it.
#include "ClipmapCenters.h"

#include <benchmark/benchmark.h>

using namespace seasonview;

namespace {

// An oblique view over the demo's scene (8192² at 0.25 m, a 1024² clip size: seven levels), as the flyover path
// sees it: 150 m up, 30° below the horizon.
void place(benchmark::State& state, CenterPlacement placement) {
    ViewSetup v;
    v.width = int(state.range(0));
    v.height = int(state.range(1));
    v.aspect = double(v.width) / double(v.height);
    v.camera.position = {0.0, -600.0, 150.0};
    v.camera.yawDeg = 35.0;
    v.camera.pitchDeg = -30.0;
    ClipmapGeometry g;
    g.levels = 7;
    g.size = 1024;
    g.texelSize0 = 0.25;
    for (auto _ : state) benchmark::DoNotOptimize(placeCenters(placement, v, g));
}

} // namespace

BENCHMARK_CAPTURE(place, footprint, CenterPlacement::Footprint)
    ->Args({640, 360})
    ->Args({1280, 720})
    ->Args({1920, 1080})
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(place, offset, CenterPlacement::Offset)->Args({640, 360})->Unit(benchmark::kMicrosecond);

BENCHMARK_MAIN();
