#pragma once
// Where each clipmap level is centred (plain C++, no GL). Ropinski et al. 2007 §3:
//  - concentric (§3.1): every level centred on the ground point below the camera;
//  - offset (§3.2): level 0's front edge on the line where the frustum's bottom plane meets the ground, every
//    coarser level's front edge on the same line (levels shifted by half their size along the ground vector);
//    concentric again when the view is within ~15° of nadir;
//  - footprint (ours): each level centred where the pixels that need it are, found by casting a coarse grid of
//    screen rays onto the ground (greedy per level, nested so trilinear blending always has both levels).
// Coordinates: the scene's local frame (metres, x east, y north); the ground is the plane z = groundHeight.
#include "Camera.h"

#include <glm/vec2.hpp>

#include <optional>
#include <string>
#include <vector>

namespace seasonview {

enum class CenterPlacement { Concentric, Offset, Footprint };

/// "concentric", "offset", "footprint".
const char* placementName(CenterPlacement p);
/// Parses a placement name; nullopt when unknown.
std::optional<CenterPlacement> parsePlacement(const std::string& name);
/// The names joined with '|' (for --help).
std::string placementNames();

/// The clipmap's level layout: level l has `size` × `size` texels of texelSize0 × 2^l metres.
struct ClipmapGeometry {
    int levels = 6;
    int size = 1024;          // texels per side of every level
    double texelSize0 = 0.25; // metres per texel of level 0 (the imagery's ground sample distance)
    double texelSize(int level) const { return texelSize0 * double(1 << level); }
    double extent(int level) const { return double(size) * texelSize(level); } // metres per side
};

/// The view the centres are placed for.
struct ViewSetup {
    Camera camera;
    double aspect = 16.0 / 9.0; // viewport width / height
    int width = 1920, height = 1080; // viewport pixels (footprint placement and coverage)
    double groundHeight = 0.0;  // height of the ground plane (terrain under the camera), metres
};

/// Angle below which `offset` falls back to concentric: between the view direction and straight down (degrees).
constexpr double kNadirSwitchDeg = 15.0;

/// The ground point of a screen position (normalised device coordinates, -1..1, y up) on z = groundHeight;
/// nullopt when the ray does not descend to the ground.
std::optional<glm::dvec2> groundHit(const ViewSetup& view, double ndcX, double ndcY);

/// One centre per level (local metres). Deterministic; no snapping to texels (the clipmap does that).
std::vector<glm::dvec2> placeCenters(CenterPlacement placement, const ViewSetup& view, const ClipmapGeometry& geometry);

/// Coverage of a placement, measured on a grid of screen samples of the flat ground (the GPU measures the real
/// frame later with the same definitions).
struct CoverageStats {
    double coverage = 0.0;        // fraction of ground samples whose used level <= the level their footprint needs
    double meanLevelDeficit = 0.0; // mean over ground samples of max(0, used - needed)
    std::vector<double> usedLevelHistogram; // fraction of ground samples per used level (size levels + 1: the
                                            // last bin is "outside every level": the resident coarse pyramid)
    int groundSamples = 0;
};

/// The level a sample needs: the coarsest level whose texels are no larger than the pixel's ground footprint
/// (texel:pixel <= 1), clamped to [0, levels]; `footprint` in metres per pixel (max of the two pixel axes).
int neededLevel(double footprint, const ClipmapGeometry& geometry);

/// Coverage of `centres` for `view`, sampling every `step`-th pixel of the viewport.
CoverageStats measureCoverage(const ViewSetup& view, const ClipmapGeometry& geometry,
                              const std::vector<glm::dvec2>& centres, int step = 4);

} // namespace seasonview
