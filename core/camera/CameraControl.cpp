#include "CameraControl.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>

namespace seasonview {

namespace {

constexpr double kDeg = M_PI / 180.0;

// Fraction of the way to the target after dt seconds of easing with time constant tau.
double easing(double dt, double tau) { return tau > 0.0 ? 1.0 - std::exp(-std::max(dt, 0.0) / tau) : 1.0; }

// Shortest signed difference b - a of two angles in degrees, in (-180, 180].
double angleDelta(double a, double b) {
    double d = std::fmod(b - a, 360.0);
    if (d > 180.0) d -= 360.0;
    if (d <= -180.0) d += 360.0;
    return d;
}

double wrapYaw(double yaw) {
    yaw = std::fmod(yaw, 360.0);
    return yaw < 0.0 ? yaw + 360.0 : yaw;
}

glm::dvec3 direction(double yawDeg, double pitchDeg) {
    const double y = yawDeg * kDeg, p = pitchDeg * kDeg;
    return {std::sin(y) * std::cos(p), std::cos(y) * std::cos(p), std::sin(p)};
}

// The ray through window pixel coordinates `cursor` (continuous, top-left origin).
glm::dvec3 rayThrough(const Camera& c, glm::dvec2 cursor, glm::ivec2 viewport) {
    const double th = std::tan(c.fovYDeg * kDeg / 2.0);
    const double aspect = double(viewport.x) / double(std::max(viewport.y, 1));
    const double nx = 2.0 * cursor.x / double(std::max(viewport.x, 1)) - 1.0;
    const double ny = 1.0 - 2.0 * cursor.y / double(std::max(viewport.y, 1));
    return glm::normalize(c.forward() + c.right() * (nx * th * aspect) + c.up() * (ny * th));
}

constexpr double kMinPitch = -89.9, kMaxPitch = 89.9;
constexpr double kOrbitMaxPitch = -2.0; // orbiting looks down at the pivot
constexpr double kMinOrbitDistance = 2.0;

} // namespace

const char* navModeName(NavMode m) {
    switch (m) {
    case NavMode::Map: return "map";
    case NavMode::Fly: return "fly";
    case NavMode::Orbit: return "orbit";
    }
    return "?";
}

std::optional<glm::dvec3> pickGround(const Camera& camera, glm::dvec2 cursor, glm::ivec2 viewport,
                                     const GroundHeightFn& ground, double maxDistance) {
    const glm::dvec3 d = rayThrough(camera, cursor, viewport);
    const glm::dvec3 o = camera.position;
    auto above = [&](double t) {
        const glm::dvec3 p = o + d * t;
        return p.z - ground(p.x, p.y);
    };
    double t0 = 0.0, h0 = above(0.0);
    if (h0 <= 0.0) return o; // under the ground already: the eye itself
    // March with steps a fraction of the height above the ground (safe for slopes up to about 3:1), no longer
    // than 1 % of the distance travelled plus 10 m, then bisect the step that crossed the surface.
    for (int i = 0; i < 100000 && t0 < maxDistance; ++i) {
        const double step = std::clamp(0.3 * h0, 0.05, 0.01 * t0 + 10.0);
        const double t1 = std::min(t0 + step, maxDistance), h1 = above(t1);
        if (h1 <= 0.0) {
            double a = t0, b = t1;
            while (b - a > 0.01) {
                const double m = 0.5 * (a + b);
                (above(m) > 0.0 ? a : b) = m;
            }
            const glm::dvec3 p = o + d * b;
            return glm::dvec3(p.x, p.y, ground(p.x, p.y));
        }
        t0 = t1;
        h0 = h1;
    }
    return std::nullopt;
}

CameraNavigator::CameraNavigator(const Camera& start, GroundHeightFn ground, NavSettings settings)
    : m_ground(std::move(ground)), m_settings(settings), m_camera(start), m_target(start) {
    keepAboveGround(m_target);
    m_camera = m_target;
}

double CameraNavigator::heightAboveGround(const Camera& c) const {
    return c.position.z - m_ground(c.position.x, c.position.y);
}

void CameraNavigator::keepAboveGround(Camera& c) const {
    const double floor = m_ground(c.position.x, c.position.y) + m_settings.clearance;
    if (c.position.z < floor) c.position.z = floor;
}

double CameraNavigator::flySpeed() const {
    return std::max(m_settings.minFlySpeed, m_settings.flySpeedPerHeight * heightAboveGround(m_target));
}

void CameraNavigator::setMode(NavMode mode, glm::ivec2 viewport, std::optional<glm::dvec3> pivot) {
    m_mode = mode;
    m_target = m_camera; // start from what is on screen
    if (mode == NavMode::Map) {
        // Straight down over the ground point at the centre of the view, from the same distance.
        const glm::dvec2 centre(viewport.x / 2.0, viewport.y / 2.0);
        const auto p = pickGround(m_target, centre, viewport, m_ground);
        const double dist = p ? glm::length(*p - m_target.position) : std::max(heightAboveGround(m_target), 10.0);
        const glm::dvec3 at = p ? *p : m_target.position;
        m_target.position = {at.x, at.y, m_ground(at.x, at.y) + dist};
        m_target.pitchDeg = -90.0;
    } else if (mode == NavMode::Orbit) {
        const glm::dvec2 centre(viewport.x / 2.0, viewport.y / 2.0);
        const auto p = pivot ? pivot : pickGround(m_target, centre, viewport, m_ground);
        m_pivot = p ? *p : m_target.position + m_target.forward() * 100.0;
        const glm::dvec3 toEye = m_target.position - m_pivot;
        m_orbitDistance = std::max(glm::length(toEye), kMinOrbitDistance);
        const glm::dvec3 look = -toEye / std::max(glm::length(toEye), 1e-9);
        m_target.yawDeg = wrapYaw(std::atan2(look.x, look.y) / kDeg);
        m_target.pitchDeg = std::clamp(std::asin(std::clamp(look.z, -1.0, 1.0)) / kDeg, kMinPitch, kOrbitMaxPitch);
        placeOrbitCamera();
    } else {
        m_target.pitchDeg = std::clamp(m_target.pitchDeg, kMinPitch, kMaxPitch);
    }
    keepAboveGround(m_target);
}

void CameraNavigator::jumpTo(const Camera& camera) {
    m_target = camera;
    keepAboveGround(m_target);
    if (m_mode == NavMode::Orbit) {
        m_mode = NavMode::Fly; // a bookmark has no pivot
    }
    m_camera = m_target;
}

void CameraNavigator::placeOrbitCamera() {
    m_target.position = m_pivot - direction(m_target.yawDeg, m_target.pitchDeg) * m_orbitDistance;
    // Under the terrain: look down more steeply at the pivot (it stays in the centre) before lifting the eye.
    for (int i = 0; i < 90 && m_target.position.z < m_ground(m_target.position.x, m_target.position.y) +
                                                        m_settings.clearance;
         ++i) {
        m_target.pitchDeg = std::max(m_target.pitchDeg - 1.0, kMinPitch);
        m_target.position = m_pivot - direction(m_target.yawDeg, m_target.pitchDeg) * m_orbitDistance;
    }
}

void CameraNavigator::updateMap(const NavInput& in, glm::ivec2 viewport) {
    Camera& t = m_target;
    t.pitchDeg = -90.0;
    const double h = std::max(heightAboveGround(t), m_settings.clearance);
    if (in.drag != glm::dvec2(0.0)) {
        // Ground metres per pixel straight below: the point under the cursor follows it.
        const double mpp = 2.0 * h * std::tan(t.fovYDeg * kDeg / 2.0) / double(std::max(viewport.y, 1));
        t.position += (-t.right() * in.drag.x + t.up() * in.drag.y) * mpp;
    }
    if (in.wheel != 0.0) {
        // Scale the eye's offset from the ground point under the cursor: that point keeps its pixel.
        const auto p = pickGround(t, in.cursor, viewport, m_ground);
        const glm::dvec3 at = p ? *p : glm::dvec3(t.position.x, t.position.y, t.position.z - h);
        const double s = std::pow(m_settings.zoomPerNotch, in.wheel);
        glm::dvec3 eye = at + (t.position - at) * s;
        const double floor = m_ground(eye.x, eye.y) + m_settings.clearance;
        if (eye.z < floor) eye = at + (t.position - at) * ((floor - at.z) / std::max(t.position.z - at.z, 1e-9));
        t.position = eye;
    }
}

void CameraNavigator::updateFly(const NavInput& in) {
    Camera& t = m_target;
    t.yawDeg = wrapYaw(t.yawDeg + in.drag.x * m_settings.lookDegPerPixel);
    t.pitchDeg = std::clamp(t.pitchDeg - in.drag.y * m_settings.lookDegPerPixel, kMinPitch, kMaxPitch);
    glm::dvec3 move = t.forward() * double(int(in.forward) - int(in.back)) +
                      t.right() * double(int(in.right) - int(in.left)) +
                      glm::dvec3(0.0, 0.0, 1.0) * double(int(in.up) - int(in.down));
    const double speed = flySpeed() * (in.fast ? 4.0 : 1.0);
    if (glm::length(move) > 0.0) t.position += glm::normalize(move) * speed * in.dt;
    // The wheel moves along the view by a tenth of the height above the ground per notch.
    if (in.wheel != 0.0) t.position += t.forward() * (in.wheel * 0.1 * std::max(heightAboveGround(t), 1.0));
}

void CameraNavigator::updateOrbit(const NavInput& in) {
    Camera& t = m_target;
    t.yawDeg = wrapYaw(t.yawDeg + in.drag.x * m_settings.lookDegPerPixel);
    t.pitchDeg = std::clamp(t.pitchDeg - in.drag.y * m_settings.lookDegPerPixel, kMinPitch, kOrbitMaxPitch);
    if (in.wheel != 0.0)
        m_orbitDistance = std::max(m_orbitDistance * std::pow(m_settings.zoomPerNotch, in.wheel), kMinOrbitDistance);
    placeOrbitCamera();
}

const Camera& CameraNavigator::update(const NavInput& in, glm::ivec2 viewport) {
    switch (m_mode) {
    case NavMode::Map: updateMap(in, viewport); break;
    case NavMode::Fly: updateFly(in); break;
    case NavMode::Orbit: updateOrbit(in); break;
    }
    keepAboveGround(m_target);
    const double a = easing(in.dt, m_settings.smoothing);
    if (m_mode == NavMode::Orbit) {
        // Ease the angles and the distance, not the position: the pivot stays in the centre all the way.
        m_camera.yawDeg = wrapYaw(m_camera.yawDeg + a * angleDelta(m_camera.yawDeg, m_target.yawDeg));
        m_camera.pitchDeg += a * (m_target.pitchDeg - m_camera.pitchDeg);
        const double d = glm::length(m_camera.position - m_pivot);
        const double dist = d + a * (m_orbitDistance - d);
        m_camera.position = m_pivot - direction(m_camera.yawDeg, m_camera.pitchDeg) * dist;
    } else {
        m_camera.position += a * (m_target.position - m_camera.position);
        m_camera.yawDeg = wrapYaw(m_camera.yawDeg + a * angleDelta(m_camera.yawDeg, m_target.yawDeg));
        m_camera.pitchDeg += a * (m_target.pitchDeg - m_camera.pitchDeg);
    }
    m_camera.fovYDeg = m_target.fovYDeg;
    keepAboveGround(m_camera);
    return m_camera;
}

} // namespace seasonview
