#pragma once
// Interactive navigation for the viewer (`seasonview view`), plain C++ so it is tested without a window. Three
// controllers share one smoothed camera:
// - Map: top-down 3-DoF navigation as in Ropinski et al. 2007 §3.1: drag pans (the ground point under the cursor
//   stays under it), the wheel zooms towards the cursor, the view stays straight down.
// - Fly: free 6-DoF flight: W/S forward/back, A/D sideways, Q/E down/up, drag (or mouse look) turns; the speed
//   scales with the height above the ground, so crossing a city block and a valley take similar times.
// - Orbit: around a ground point (the one clicked): drag turns around it, the wheel moves closer or further; the
//   pivot stays at the centre of the view.
// Every controller keeps the camera at least `clearance` metres above the terrain, and eases towards where the
// input sends it (exponential smoothing with a time constant), so navigation never jumps.
#include "Camera.h"

#include <glm/vec2.hpp>

#include <functional>
#include <optional>

namespace seasonview {

/// Terrain height (metres) under a local point.
using GroundHeightFn = std::function<double(double x, double y)>;

/// Input since the last update, as the window reported it.
struct NavInput {
    double dt = 0.0;              // seconds since the last update
    glm::dvec2 cursor{0.0};       // window pixels, top-left origin
    glm::dvec2 drag{0.0};         // cursor motion with the primary button held, pixels
    double wheel = 0.0;           // wheel notches, positive = towards the scene (zoom in)
    bool forward = false, back = false, left = false, right = false, up = false, down = false;
    bool fast = false;            // shift: four times the speed
};

enum class NavMode { Map, Fly, Orbit };
const char* navModeName(NavMode m);

struct NavSettings {
    double clearance = 1.5;        // metres the eye keeps above the terrain
    double smoothing = 0.08;       // seconds: time constant of the easing towards the target pose
    double lookDegPerPixel = 0.15; // fly and orbit: degrees turned per pixel dragged
    double zoomPerNotch = 0.85;    // map and orbit: distance factor per wheel notch
    double flySpeedPerHeight = 0.6; // fly: metres per second per metre of height above the ground
    double minFlySpeed = 2.0;      // metres per second, near the ground
};

/// Where the ray through window pixel `cursor` first meets the terrain (marched against `ground`, then refined by
/// bisection to a centimetre), or nothing when it meets no ground within `maxDistance` metres.
std::optional<glm::dvec3> pickGround(const Camera& camera, glm::dvec2 cursor, glm::ivec2 viewport,
                                     const GroundHeightFn& ground, double maxDistance = 1e6);

class CameraNavigator {
public:
    CameraNavigator(const Camera& start, GroundHeightFn ground, NavSettings settings = {});

    /// Switches mode from the current pose. Map: straight down over the point in view. Orbit: around `pivot`, or
    /// the ground point at the centre of the view when none is given.
    void setMode(NavMode mode, glm::ivec2 viewport, std::optional<glm::dvec3> pivot = std::nullopt);
    NavMode mode() const { return m_mode; }

    /// Applies one update's input and eases the camera towards the result. Returns the camera to draw.
    const Camera& update(const NavInput& input, glm::ivec2 viewport);

    /// Jumps to a pose (a bookmark) without easing; stays in the current mode.
    void jumpTo(const Camera& camera);

    const Camera& camera() const { return m_camera; }
    const Camera& target() const { return m_target; }
    /// Fly speed at the current height above the ground, metres per second (without `fast`).
    double flySpeed() const;
    /// The orbit's pivot (meaningful in Orbit mode).
    glm::dvec3 pivot() const { return m_pivot; }

private:
    void keepAboveGround(Camera& c) const;
    double heightAboveGround(const Camera& c) const;
    void updateMap(const NavInput& in, glm::ivec2 viewport);
    void updateFly(const NavInput& in);
    void updateOrbit(const NavInput& in);
    void placeOrbitCamera();

    GroundHeightFn m_ground;
    NavSettings m_settings;
    NavMode m_mode = NavMode::Fly;
    Camera m_camera, m_target;
    glm::dvec3 m_pivot{0.0};
    double m_orbitDistance = 100.0;
};

} // namespace seasonview
