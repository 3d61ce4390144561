#pragma once
// The offline segmentation of a scene's imagery files (`seasonview segment`): reads both seasons band by band
// through core's BandReader (8- or 16-bit; 16-bit through the scene's stored 0.5–99.5 % stretch), segments each
// band with the rows around it it needs (Segmentation.h), and streams the mask and the overlay out through
// ImageStreamWriter on a writer thread. Each input is decoded once: when the method needs the pair's histograms and
// they are not given (PairStats.h caches them with the pyramids), the decoded pair is held whole if it fits the
// memory budget; only a pair larger than that is read twice (histograms, then segmentation), so memory stays a few
// bands whatever the image size. Every path gives the same mask, byte for byte. Optionally scores the mask against
// a truth mask (pixels) and true trees (crown centres), and lists the crowns it finds (CrownCentres.h).
#include "Scene.h"
#include "Segmentation.h"
#include "SegmentationMetrics.h"
#include "Progress.h"

#include <array>
#include <filesystem>
#include <optional>
#include <vector>

namespace seasonview {

/// Default SegmentJob::memoryBudget: 2 GiB, a pair of 18,900² RGB images.
inline constexpr std::uint64_t kSegmentMemoryBudget = std::uint64_t(2) << 30;

/// Where the segmentation's pair statistics came from.
enum class StatsSource { None, Given, HeldPair, HistogramPass };

/// The value of pixels without data in a GeoTIFF mask (where either season has no data).
inline constexpr std::uint8_t kMaskNodata = 255;

struct SegmentJob {
    SegmentationParams params;
    /// Required. By extension: .png 8-bit, 255 treetop, 0 not (and where a season has no data); .tif a georeferenced
    /// GeoTIFF on the working grid: 1 treetop, 0 not, kMaskNodata where a season has no data (its nodata value).
    std::filesystem::path mask;
    std::filesystem::path overlay;    // optional: leaf-on with the result (and truth) drawn over it, RGB (.tif: GeoTIFF)
    /// Optional crown centres: .csv id,x,y,easting,northing,radius_m,lon,lat (easting/northing in the working grid's
    /// CRS, written beside it as a .prj), or .geojson points in WGS 84.
    std::filesystem::path trees;
    /// Optional truth mask (non-zero = deciduous treetop): on the working grid, or georeferenced on any grid.
    std::filesystem::path truth;
    std::filesystem::path truthTrees; // optional: true trees CSV (synth's trees.csv: x, y, radius_m[, type])
    int bandRows = 256;               // output rows per band; memory grows with it, the output does not depend on it
    /// Bytes the decoded pair (2 × width × height × 3) may take when the histograms must be computed: within it the
    /// pair is held whole and each input decoded once, above it both are streamed twice. The output does not
    /// depend on it.
    std::uint64_t memoryBudget = kSegmentMemoryBudget;
    /// The pair's histograms when they are known already (cachedPairHistograms of PairStats.h, from the same 8-bit
    /// values): no histogram pass. They must be those of this pair, or the mask is wrong.
    std::optional<SegmentationHistograms> histograms;
    /// The pair's prepared pyramid level 0 (leaf-on, leaf-off; premultiplied RGBA, alpha the season's coverage).
    /// Required when the scene is warped (Scene::warped()); read instead of the scene's files when given.
    std::optional<std::array<std::filesystem::path, 2>> levelZero;
    ProgressFn progress;
};

struct SegmentReport {
    int width = 0, height = 0;
    SegmentationStats stats;                 // what the rule used (drop threshold, tables)
    std::optional<Confusion> confusion;      // with a truth mask
    std::uint64_t nodataPixels = 0;          // pixels where a season has no data (marked, never scored)
    int crowns = 0;                          // crowns found (with `trees` or `truthTrees`)
    std::optional<CentreScores> centres;     // with true trees
    StatsSource statsSource = StatsSource::None; // none needed (pixel, neighborhood), given, or computed
    bool heldInMemory = false;               // the decoded pair was held whole (else streamed in bands)
    int inputPasses = 1;                     // times each input was decoded (2: streamed histogram pass)
    double segmentSeconds = 0.0;             // the rule itself: histograms + segmentation of every band
    double crownSeconds = 0.0;               // distance transform and maxima
    double readSeconds = 0.0;                // reading and decoding the inputs (both seasons in parallel)
    double writeSeconds = 0.0;               // encoding and writing the mask, overlay and trees (the mask and
                                             // overlay on a writer thread, alongside the segmentation)
    double totalSeconds = 0.0;               // wall time of the whole job
};

/// "none", "given", "held pair", "histogram pass".
const char* statsSourceName(StatsSource source);

/// Overlay colours, blended half and half over the leaf-on image: true positive (or, without truth, detected),
/// false positive, false negative. RGB.
inline constexpr std::uint8_t kOverlayTruePositive[3] = {255, 220, 0};
inline constexpr std::uint8_t kOverlayFalsePositive[3] = {255, 0, 200};
inline constexpr std::uint8_t kOverlayFalseNegative[3] = {0, 150, 255};

/// A true tree list: the rows of a CSV with columns x, y (local metres) and radius_m; rows whose `type` column (if
/// any) is not "deciduous" are skipped. Errors name the file and the line.
Result<std::vector<CrownPoint>> readTrueTrees(const std::filesystem::path& csv);

/// Segments `scene`'s imagery as `job` says. Inputs are checked first (truth size, true trees), outputs opened
/// before any work, and every output is written under a temporary name and renamed at the end: on error nothing
/// appears under an output's name. Errors are one line naming the file and the problem.
Result<SegmentReport> segmentScene(const Scene& scene, const SegmentJob& job);

} // namespace seasonview
