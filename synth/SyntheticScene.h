#pragma once
// Deterministic synthetic two-season landscape with ground truth (`seasonview synth`).
#include "Progress.h"
#include "Raster.h"
#include "Result.h"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>

#include <glm/vec2.hpp>
#include <string>

namespace seasonview {

/// Band height of SynthOptions::bandRows = 0: ~1.2 GB of band buffers at 65536 pixels per side, a few hundred MB at
/// 8192, and bands long enough that per-band costs (thread start-up, the tiles of a row) do not show.
constexpr int kDefaultSynthBandRows = 1024;

/// Largest supported size / gsd: memory is bounded by the band buffers and the whole DEM (4 GB at 131072).
constexpr int kMaxSynthPixels = 131072;

/// Version of what `synth` writes (scene.json's generator.version): 2 added the city model.
constexpr int kSynthGeneratorVersion = 2;

/// Above this many pixels per side the truth masks are tiled GeoTIFFs (truth_*.tif) instead of PNGs.
constexpr int kMaxSynthPngPixels = 32768;

struct SynthOptions {
    double sizeM = 2048.0;             // side of the square scene, metres
    double gsd = 0.25;                 // imagery ground sample distance, metres per pixel
    std::uint64_t seed = 1;
    std::filesystem::path dem;         // optional real DEM: a crop of the scene's extent around its centre
    double demSpacing = 0.0;           // DEM sample spacing, metres (0 = max(1 m, 4 gsd)); a real DEM is resampled
                                       // (bilinear) to it, so a fine spacing makes an upsampled DEM
    int threads = 0;                   // 0 = hardware concurrency; the output does not depend on it
    int bandRows = 0;                  // imagery rows generated at a time (0 = kDefaultSynthBandRows); memory grows
                                       // with it (~18 bytes per pixel of the band), the output does not depend on it
    int pngMasksUpTo = kMaxSynthPngPixels; // larger scenes get GeoTIFF truth masks (a parameter for the tests)
    std::optional<glm::dvec2> centreLonLat; // where the scene lies (its UTM zone's grid); default near Münster, or
                                            // the real DEM's centre
    bool city = true;                  // write the buildings as a textured OBJ city model (city/city.obj)
    std::filesystem::path facadePhotos; // facade photo folder for the city's textures (empty: procedural facades)
    int facadeSize = 256;              // facade texture side, texels
    int blockCity = 0;                 // > 0: a block city of this many buildings at the centre (placeBlockCity)
    TiffCompression compression = TiffCompression::Zstd; // of the imagery and truth GeoTIFFs (Deflate: for readers
                                                         // without Zstandard; decodes five times slower; Jpeg: the
                                                         // imagery only, the truth masks stay Zstandard)
};

/// What was generated, for the CLI summary.
struct SynthReport {
    int width = 0, height = 0;         // imagery pixels per season
    int demWidth = 0, demHeight = 0;   // elevation samples
    int deciduousTrees = 0, conifers = 0;
    std::size_t buildings = 0;         // in the city model (0: none written)
    std::uint64_t facadeBytes = 0;
    double seconds = 0.0;              // wall time of the whole generation
    std::string crs;                   // e.g. "EPSG:32632 (UTM 32N)"
};

/// Generates the scene into `outDir` (created if needed): leafon.tif, leafoff.tif (8-bit RGB tiled UTM GeoTIFFs,
/// BigTIFF past 2 GiB), dem.tif (float32 UTM GeoTIFF), truth_deciduous.png, truth_conifer.png (8-bit, 255 = class,
/// on the imagery grid; tiled 8-bit GeoTIFFs truth_deciduous.tif, truth_conifer.tif above pngMasksUpTo pixels),
/// trees.csv, the buildings as city/city.obj + city.mtl + city/facades/*.jpg (synth/SynthCity.h) and scene.json
/// (written last, naming the files). Same options -> byte-identical files, whatever
/// `threads` and `bandRows`. The imagery is generated and written in bands of rows, so memory does not grow with
/// the height; the layout (a list of objects) and the DEM are whole. Files appear atomically.
Result<SynthReport> generateSyntheticScene(const SynthOptions& options, const std::filesystem::path& outDir,
                                           const ProgressFn& progress = {});

} // namespace seasonview
