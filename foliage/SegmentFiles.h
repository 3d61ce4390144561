#pragma once
// The offline segmentation of a scene's imagery files (`seasonview segment`): streams both seasons band by band
// through core's BandReader (8- or 16-bit; 16-bit through the scene's stored 0.5–99.5 % stretch), segments each
// band with the rows around it it needs (Segmentation.h), and streams the mask and the overlay out through
// ImageStreamWriter, so memory stays a few bands whatever the image size. Optionally scores the mask against a truth
// mask (pixels) and true trees (crown centres), and lists the crowns it finds (CrownCentres.h).
#include "Scene.h"
#include "Segmentation.h"
#include "SegmentationMetrics.h"
#include "SyntheticScene.h" // ProgressFn

#include <filesystem>
#include <optional>
#include <vector>

namespace seasonview {

struct SegmentJob {
    SegmentationParams params;
    std::filesystem::path mask;       // required: 8-bit, 255 = treetop (format by extension: .png, .tif)
    std::filesystem::path overlay;    // optional: leaf-on with the result (and truth) drawn over it, RGB
    std::filesystem::path trees;      // optional: crown centres CSV id,x,y,easting,northing,radius_m
    std::filesystem::path truth;      // optional: truth mask on the imagery grid (non-zero = deciduous treetop)
    std::filesystem::path truthTrees; // optional: true trees CSV (synth's trees.csv: x, y, radius_m[, type])
    int bandRows = 256;               // output rows per band; memory grows with it, the output does not depend on it
    ProgressFn progress;
};

struct SegmentReport {
    int width = 0, height = 0;
    SegmentationStats stats;                 // what the rule used (drop threshold, tables)
    std::optional<Confusion> confusion;      // with a truth mask
    int crowns = 0;                          // crowns found (with `trees` or `truthTrees`)
    std::optional<CentreScores> centres;     // with true trees
    double segmentSeconds = 0.0;             // the rule itself: histograms + segmentation of every band
    double crownSeconds = 0.0;               // distance transform and maxima
    double readSeconds = 0.0;                // reading and decoding the inputs (both seasons in parallel)
    double writeSeconds = 0.0;               // encoding and writing the mask, overlay and trees
    double totalSeconds = 0.0;               // wall time of the whole job
};

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
