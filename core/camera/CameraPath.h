#pragma once
// Camera paths for benchmarks and fly-throughs (plain C++): JSON keyframes or built-in named paths, defined in
// scene-relative units so they work on any scene. Every channel is a cubic Hermite spline in time through the keys
// (C1 however unevenly the keys are timed): x and y with Catmull-Rom tangents, heights, pitch, fov and headings
// (along the shortest arc) with monotone tangents, so they stay within the keys around them.
#include "Camera.h"
#include "Result.h"

#include <glm/vec2.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace seasonview {

struct CameraKeyframe {
    double time = 0.0;    // seconds (any monotonic unit)
    glm::dvec3 position{0.0};
    bool heightAboveTerrain = false; // position.z is metres above the terrain under the camera
    double yawDeg = 0.0, pitchDeg = -45.0, fovYDeg = 60.0;
};

/// What a named path needs to know about the scene.
struct PathScene {
    glm::dvec2 localMin{0.0}, localMax{0.0}; // extent of the imagery, local metres
    std::function<double(double, double)> terrainHeight; // metres under a local point
};

class CameraPath {
public:
    /// Named paths: flyover (straight across, 45° down), orbit (around the centre), dive (straight down from high
    /// to near-horizontal low), fast (streaming stress: high speed, the view snapping 90° round in the last tenth of
    /// each leg), random (seeded soak).
    static Result<CameraPath> named(const std::string& name, const PathScene& scene, std::uint64_t seed = 1);
    /// Keyframes from a JSON file: [{"time", "x", "y", "z" (number, or "+H" above the terrain), "yaw", "pitch",
    /// "fov"?}, ...] with at least two keyframes and increasing times.
    static Result<CameraPath> fromJson(const std::filesystem::path& file);
    /// "flyover|orbit|dive|fast|random".
    static std::string namedPaths();

    explicit CameraPath(std::vector<CameraKeyframe> keys) : m_keys(std::move(keys)) {}

    /// The camera at fraction `u` in [0,1] of the path's duration; "+H" keyframes resolved with `terrainHeight`.
    Camera at(double u, const std::function<double(double, double)>& terrainHeight) const;
    const std::vector<CameraKeyframe>& keyframes() const { return m_keys; }

private:
    std::vector<CameraKeyframe> m_keys;
};

} // namespace seasonview
