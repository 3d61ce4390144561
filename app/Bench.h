#pragma once
// The frame benchmark shared by `seasonview bench` and `seasonview demo`: runs one or more modes interleaved along
// a camera path and writes frames.csv, summary.json, compare.json (several modes) and plot.png.
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
    int frames = 300, warmup = 10, coverageEvery = 1, clipSize = 2048;
    std::string compare;          // "centers=a,b,...", "renderer=clipmap,reference", "aniso=1,8", "canopy=off,16",
                                  // "segmentation=upload,perframe", "scene=terrain,full" or "city=atlas,original,flat";
                                  // empty: one mode
    std::string renderer = "clipmap", centers = "footprint", view = "leafon";
    std::uint64_t seed = 1;
    float anisotropy = 8.0f;      // clipmap footprint filter / reference sampler (1 = isotropic)
    int gridSize = 255;
    int clipLevels = 0;           // toroidal levels allocated at least (ClipmapOptions::minClipLevels)           // geometry clipmap n (vertices per level side, 2^k - 1)
    std::int64_t uploadBudget = std::int64_t(1) << 20;
    // canopy view: stacked layers ("off" or 1..32), the canopy layer's segmentation method and k.
    std::string canopyLayers = "16", method = "default", groundUnder = "leafoff", groundElsewhere = "leafon";
    std::string trunks = "on", canopyDraw = "march";
    int k = 5;
    std::filesystem::path cacheDir;
    // The scene's city model: off | atlas | original | flat, its tree (empty: built into the cache), capacity, τ.
    std::string city = "off", cityTree, cityUpload = "auto", cityOcclusion = "on";
    std::string terrain = "on"; // off: the terrain is not drawn, only the city (its roofs still read the imagery)
    std::string terrainShading = "deferred"; // forward|deferred (ImagerySettings::path)
    double cityCapacityMb = 256.0, cityTpp = 1.0;
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
