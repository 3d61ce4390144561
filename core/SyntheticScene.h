#pragma once
// Deterministic synthetic two-season landscape with ground truth (`seasonview synth`).
#include "Result.h"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>

namespace seasonview {

struct SynthOptions {
    double sizeM = 2048.0;             // side of the square scene, metres
    double gsd = 0.25;                 // imagery ground sample distance, metres per pixel
    std::uint64_t seed = 1;
    std::filesystem::path dem;         // optional real DEM: a crop of the scene's extent around its centre
    int threads = 0;                   // 0 = hardware concurrency; the output does not depend on it
};

/// What was generated, for the CLI summary.
struct SynthReport {
    int width = 0, height = 0;         // imagery pixels per season
    int demWidth = 0, demHeight = 0;   // elevation samples
    int deciduousTrees = 0, conifers = 0;
    double seconds = 0.0;              // wall time of the whole generation
    std::string crs;                   // e.g. "EPSG:32632 (UTM 32N)"
};

/// Progress callback: fraction done in [0,1] and a short stage name.
using ProgressFn = std::function<void(double fraction, const char* stage)>;

/// Generates the scene into `outDir` (created if needed): leafon.tif, leafoff.tif (8-bit RGB tiled UTM GeoTIFFs),
/// dem.tif (float32 UTM GeoTIFF), truth_deciduous.png, truth_conifer.png (8-bit, 255 = class, on the imagery grid),
/// trees.csv and scene.json (written last). Same options -> byte-identical files. Files appear atomically.
Result<SynthReport> generateSyntheticScene(const SynthOptions& options, const std::filesystem::path& outDir,
                                           const ProgressFn& progress = {});

} // namespace seasonview
