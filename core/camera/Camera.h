#pragma once
// The seasonview camera: position in the scene's local frame (x east, y north, z up, metres), yaw = compass
// heading in degrees (0 = north, 90 = east, clockwise), pitch in degrees (0 = horizontal, -90 = straight down),
// vertical field of view in degrees.
#include "Result.h"

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include <functional>
#include <optional>
#include <string>

namespace seasonview {

struct Camera {
    glm::dvec3 position{0.0};
    double yawDeg = 0.0;
    double pitchDeg = -90.0;
    double fovYDeg = 60.0;

    /// Unit view direction in the local frame.
    glm::dvec3 forward() const;
    /// Unit right vector: horizontal, well defined at any pitch including straight down.
    glm::dvec3 right() const;
    /// Unit up vector of the image plane (right-handed with forward and right).
    glm::dvec3 up() const;

    /// World -> eye transform (OpenGL eye space: looking down -z).
    glm::dmat4 viewMatrix() const;
    /// Reversed-Z infinite perspective (depth 1 at `near`, 0 at infinity; needs glClipControl(.., GL_ZERO_TO_ONE)).
    glm::dmat4 projectionMatrix(double aspect, double near) const;

    /// "X,Y,Z,YAW,PITCH,FOV" with enough digits to round-trip.
    std::string toString() const;
};

/// A parsed camera string whose Z may still be relative to the terrain.
struct CameraSpec {
    Camera camera;
    std::optional<double> heightAboveTerrain; // set when Z was written "+H"
    /// Resolves "+H" with `terrainHeight(x, y)` (metres, local frame).
    Camera resolve(const std::function<double(double, double)>& terrainHeight) const;
};

/// Parses "X,Y,Z,YAW,PITCH[,FOV]" (Z may be "+H": H metres above the terrain under the camera). Errors say
/// which field is wrong. Pitch must lie in [-90, 90], fov in (0, 180).
Result<CameraSpec> parseCamera(const std::string& text);

} // namespace seasonview
