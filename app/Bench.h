#pragma once
// The frame benchmark shared by `seasonview bench` and `seasonview demo`: runs one or more modes interleaved along
// a camera path and writes frames.csv, summary.json, compare.json (several modes) and plot.png.
#include "CliOptions.h"
#include "Result.h"
#include "Scene.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace seasonview::app {

struct BenchSettings {
    std::string path = "flyover"; // named path or keyframe JSON file
    int width = 1920, height = 1080;
    int frames = 300, warmup = 10, coverageEvery = 1;
    std::string compare;          // "KEY=A,B,...": the modes run interleaved (BenchCommand.cpp lists the keys);
                                  // empty: one mode
    std::uint64_t seed = 1;       // of the random path
    std::string stages;           // "finish" or "issue": each measured frame's stages timed (gl/FrameStages.h),
                                  // stages.csv; empty: not
    std::int64_t uploadBudget = std::int64_t(1) << 20;
    std::filesystem::path cacheDir;
    // The options shared with render and view (CliOptions.h): what is shown, the clipmaps, the canopy view and the
    // scene's city model.
    ImageryArgs imagery;
    ClipmapArgs clipmap;
    CanopyArgs canopy;
    CityArgs city;
};

struct BenchModeResult {
    std::string mode;
    double medianFrameMs = 0, p95FrameMs = 0, maxFrameMs = 0, ratioToFirst = 1, coverageMean = 0,
           uploadOverMinimum = 0;
};

struct BenchResult {
    std::vector<BenchModeResult> modes;
    std::string device;
    double seconds = 0;
    std::string table; // the printed comparison table
};

/// Validates the settings (errors: one line), runs the benchmark headless, writes its files into `out`.
Result<BenchResult> runBench(const Scene& scene, const BenchSettings& settings, const std::filesystem::path& out);

} // namespace seasonview::app
