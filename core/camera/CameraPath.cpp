#include "CameraPath.h"
#include "JsonFile.h"

#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>

namespace seasonview {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Keyframe curves are cubic Hermite splines in time: each key is hit exactly, and the velocity is continuous at the
// keys whatever their spacing in time (C1). Positions take Catmull-Rom tangents measured in time; heights, angles
// and the field of view take monotone (Fritsch-Carlson / PCHIP) tangents, so they never leave the range of the
// keys around them: a camera held at +2 m between keys stays there, a heading held between two keys does not wobble.
double hermite(double a, double b, double ma, double mb, double h, double s) {
    const double s2 = s * s, s3 = s2 * s;
    return (2 * s3 - 3 * s2 + 1) * a + (s3 - 2 * s2 + s) * h * ma + (-2 * s3 + 3 * s2) * b + (s3 - s2) * h * mb;
}

/// The tangent (per unit time) at key k of n keys with times t(j) and values v(j).
template <class T, class V>
double tangent(const T& t, const V& v, std::size_t n, std::size_t k, bool monotone) {
    if (n < 2) return 0.0;
    auto slope = [&](std::size_t j) { return (v(j + 1) - v(j)) / (t(j + 1) - t(j)); }; // over [j, j+1]
    if (n == 2) return slope(0);
    if (k == 0 || k == n - 1) {
        // One-sided three-point derivative (exact on quadratics, so a linear ramp stays linear to the end).
        const bool first = k == 0;
        const std::size_t j = first ? 0 : n - 2, j2 = first ? 1 : n - 3;
        const double h0 = t(j + 1) - t(j), h1 = t(j2 + 1) - t(j2), d0 = slope(j), d1 = slope(j2);
        double m = ((2 * h0 + h1) * d0 - h0 * d1) / (h0 + h1);
        if (monotone) {
            if (m * d0 <= 0.0) m = 0.0;
            else if (d0 * d1 < 0.0 && std::fabs(m) > 3.0 * std::fabs(d0)) m = 3.0 * d0;
        }
        return m;
    }
    const double h0 = t(k) - t(k - 1), h1 = t(k + 1) - t(k), d0 = slope(k - 1), d1 = slope(k);
    if (!monotone) return (v(k + 1) - v(k - 1)) / (h0 + h1);
    if (d0 * d1 <= 0.0) return 0.0; // a turning point or a held value: flat there
    const double w1 = 2 * h1 + h0, w2 = h1 + 2 * h0;
    return (w1 + w2) / (w1 / d0 + w2 / d1);
}

/// Shortest-arc difference b - a in (-180, 180].
double angleStep(double a, double b) {
    double d = std::fmod(b - a, 360.0);
    if (d > 180.0) d -= 360.0;
    if (d <= -180.0) d += 360.0;
    return d;
}

// A splitmix64 stream: deterministic on every platform (std:: distributions are not).
struct Rng {
    std::uint64_t s;
    double next() {
        std::uint64_t z = (s += 0x9E3779B97F4A7C15ull);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return double((z ^ (z >> 31)) >> 11) * (1.0 / 9007199254740992.0);
    }
};

CameraKeyframe key(double t, double x, double y, double h, double yaw, double pitch) {
    CameraKeyframe k;
    k.time = t;
    k.position = {x, y, h};
    k.heightAboveTerrain = true;
    k.yawDeg = yaw;
    k.pitchDeg = pitch;
    return k;
}

} // namespace

std::string CameraPath::namedPaths() { return "flyover|orbit|dive|fast|random"; }

Result<CameraPath> CameraPath::named(const std::string& name, const PathScene& scene, std::uint64_t seed) {
    const glm::dvec2 c = 0.5 * (scene.localMin + scene.localMax);
    const glm::dvec2 half = 0.5 * (scene.localMax - scene.localMin);
    const double s = std::min(half.x, half.y); // half the scene's smaller side
    std::vector<CameraKeyframe> k;
    if (name == "flyover") {
        // South to north across 80 % of the scene, 45° down, at 7.5 % of the scene's size above the terrain.
        for (int i = 0; i <= 8; ++i) k.push_back(key(i, c.x, c.y - 0.8 * s + 0.2 * s * i, 0.075 * s, 0.0, -45.0));
    } else if (name == "orbit") {
        for (int i = 0; i <= 16; ++i) {
            const double a = 2.0 * kPi * i / 16.0;
            const double x = c.x + 0.6 * s * std::sin(a), y = c.y - 0.6 * s * std::cos(a);
            // Looking at the centre: from (sin a, -cos a) the heading (0 = north, 90 = east) is -a.
            k.push_back(key(i, x, y, 0.15 * s, std::fmod(360.0 - a * 180.0 / kPi, 360.0), -35.0));
        }
    } else if (name == "dive") {
        // Straight down from high up to a low, near-horizontal view, moving north.
        for (int i = 0; i <= 8; ++i) {
            const double f = i / 8.0;
            k.push_back(key(i, c.x, c.y - 0.5 * s + 0.6 * s * f, 0.6 * s * std::pow(1.0 - f, 2.0) + 0.01 * s, 0.0,
                            -90.0 + 85.0 * f));
        }
    } else if (name == "fast") {
        // Zig-zag at high speed, low above the terrain, looking along each leg until the last tenth of it, where
        // the view snaps round to the next leg's heading: streaming stress (the clipmaps' fine levels must follow
        // a sudden turn). Keys at the start of a leg, at 90 % of it and at its end: constant speed along the legs.
        const double h = 0.03 * s;
        const glm::dvec2 pts[] = {{-0.8, -0.8}, {0.8, -0.8}, {0.8, -0.3}, {-0.8, -0.3}, {-0.8, 0.2},
                                  {0.8, 0.2},   {0.8, 0.7},  {-0.8, 0.7}};
        const int legs = 7;
        auto heading = [&](int i) { // compass heading of leg i (0 = north, 90 = east)
            const glm::dvec2 d = pts[i + 1] - pts[i];
            return std::fmod(std::atan2(d.x, d.y) * 180.0 / kPi + 360.0, 360.0);
        };
        double t = 0.0;
        for (int i = 0; i < legs; ++i) {
            const double len = glm::length(pts[i + 1] - pts[i]) / 1.6; // legs of 1.6 s take 1 time unit
            const glm::dvec2 a = c + pts[i] * s, b = c + pts[i + 1] * s, late = a + 0.9 * (b - a);
            k.push_back(key(t, a.x, a.y, h, heading(i), -30.0));
            k.push_back(key(t + 0.9 * len, late.x, late.y, h, heading(i), -30.0));
            t += len;
        }
        const glm::dvec2 end = c + pts[legs] * s;
        k.push_back(key(t, end.x, end.y, h, heading(legs - 1), -30.0)); // the path ends looking along its last leg
    } else if (name == "random") {
        Rng rng{seed * 0x2545F4914F6CDD1Dull + 1};
        double yaw = rng.next() * 360.0;
        for (int i = 0; i < 64; ++i) {
            yaw += (rng.next() - 0.5) * 120.0;
            k.push_back(key(i, c.x + (rng.next() * 1.8 - 0.9) * s, c.y + (rng.next() * 1.8 - 0.9) * s,
                            (0.01 + 0.2 * rng.next()) * s, std::fmod(yaw + 360.0, 360.0), -10.0 - 80.0 * rng.next()));
        }
    } else {
        return Error{"--path '" + name + "': expected " + namedPaths() + " or a keyframe JSON file"};
    }
    return CameraPath(std::move(k));
}

Result<CameraPath> CameraPath::fromJson(const std::filesystem::path& file) {
    const std::string f = file.string();
    auto parsed = readJsonFile(file, "camera path");
    if (!parsed) return parsed.error();
    nlohmann::json j = std::move(*parsed);
    if (j.is_object() && j.contains("keyframes")) j = j["keyframes"];
    if (!j.is_array() || j.size() < 2) return fileError(f, "a camera path needs an array of at least 2 keyframes");
    std::vector<CameraKeyframe> keys;
    for (size_t i = 0; i < j.size(); ++i) {
        const auto& o = j[i];
        const std::string where = "keyframe " + std::to_string(i) + ": ";
        if (!o.is_object()) return fileError(f, where + "must be an object");
        CameraKeyframe k;
        auto num = [&](const char* name, double& out, bool required) -> bool {
            if (!o.contains(name)) return !required;
            if (!o[name].is_number()) return false;
            out = o[name].get<double>();
            return std::isfinite(out);
        };
        for (const char* n : {"time", "x", "y", "yaw", "pitch"}) {
            double v = 0;
            if (!num(n, v, true)) return fileError(f, where + "'" + n + "' must be a number");
            if (std::string(n) == "time") k.time = v;
            else if (std::string(n) == "x") k.position.x = v;
            else if (std::string(n) == "y") k.position.y = v;
            else if (std::string(n) == "yaw") k.yawDeg = v;
            else k.pitchDeg = v;
        }
        if (!num("fov", k.fovYDeg, false) || !(k.fovYDeg > 0 && k.fovYDeg < 180))
            return fileError(f, where + "'fov' must be a number in (0, 180)");
        if (!o.contains("z")) return fileError(f, where + "'z' is missing");
        if (o["z"].is_number()) {
            k.position.z = o["z"].get<double>();
        } else if (o["z"].is_string()) {
            auto spec = parseCamera("0,0," + o["z"].get<std::string>() + ",0,0");
            if (!spec || !spec->heightAboveTerrain) return fileError(f, where + "'z' must be a number or \"+H\"");
            k.position.z = *spec->heightAboveTerrain;
            k.heightAboveTerrain = true;
        } else {
            return fileError(f, where + "'z' must be a number or \"+H\"");
        }
        if (k.pitchDeg < -90 || k.pitchDeg > 90) return fileError(f, where + "'pitch' must be within [-90, 90]");
        if (!keys.empty() && !(k.time > keys.back().time)) return fileError(f, where + "times must increase");
        keys.push_back(k);
    }
    return CameraPath(std::move(keys));
}

Camera CameraPath::at(double u, const std::function<double(double, double)>& terrainHeight) const {
    const double t0 = m_keys.front().time, t1 = m_keys.back().time;
    const double t = t0 + std::clamp(u, 0.0, 1.0) * (t1 - t0);
    const std::size_t n = m_keys.size();
    std::size_t i = 0;
    while (i + 2 < n && m_keys[i + 1].time <= t) ++i;
    const double h = m_keys[i + 1].time - m_keys[i].time;
    const double f = std::clamp((t - m_keys[i].time) / h, 0.0, 1.0);
    const auto time = [&](std::size_t j) { return m_keys[j].time; };
    // One channel: Hermite between keys i and i+1 with the tangents their neighbours give.
    const auto curve = [&](const auto& v, bool monotone) {
        return hermite(v(i), v(i + 1), tangent(time, v, n, i, monotone), tangent(time, v, n, i + 1, monotone), h, f);
    };
    Camera c;
    c.position.x = curve([&](std::size_t j) { return m_keys[j].position.x; }, false);
    c.position.y = curve([&](std::size_t j) { return m_keys[j].position.y; }, false);
    // Heights: every key's height as it would be here ("+H" keys sit on the terrain under the interpolated point),
    // so a key is met exactly whichever kind its neighbours are, and a run of "+H" keys follows the terrain.
    const double ground = terrainHeight ? terrainHeight(c.position.x, c.position.y) : 0.0;
    c.position.z = curve([&](std::size_t j) { return m_keys[j].position.z + (m_keys[j].heightAboveTerrain ? ground : 0.0); },
                         true);
    // Headings unwrapped along the shortest arc from key to key, from key i's value.
    const auto yaw = [&](std::size_t j) {
        double y = m_keys[i].yawDeg;
        for (std::size_t q = i; q < j; ++q) y += angleStep(m_keys[q].yawDeg, m_keys[q + 1].yawDeg);
        for (std::size_t q = i; q > j; --q) y -= angleStep(m_keys[q - 1].yawDeg, m_keys[q].yawDeg);
        return y;
    };
    c.yawDeg = std::fmod(std::fmod(curve(yaw, true), 360.0) + 360.0, 360.0);
    c.pitchDeg = std::clamp(curve([&](std::size_t j) { return m_keys[j].pitchDeg; }, true), -90.0, 90.0);
    c.fovYDeg = std::clamp(curve([&](std::size_t j) { return m_keys[j].fovYDeg; }, true), 1.0, 179.0);
    return c;
}

} // namespace seasonview
