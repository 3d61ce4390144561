#include "CameraPath.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>

namespace seasonview {

namespace {

constexpr double kPi = 3.14159265358979323846;

glm::dvec3 catmullRom(const glm::dvec3& p0, const glm::dvec3& p1, const glm::dvec3& p2, const glm::dvec3& p3, double t) {
    const double t2 = t * t, t3 = t2 * t;
    return 0.5 * ((2.0 * p1) + (-p0 + p2) * t + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * t2 +
                  (-p0 + 3.0 * p1 - 3.0 * p2 + p3) * t3);
}

double lerpAngle(double a, double b, double t) {
    double d = std::fmod(b - a, 360.0);
    if (d > 180.0) d -= 360.0;
    if (d < -180.0) d += 360.0;
    return a + d * t;
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
            k.push_back(key(i, x, y, 0.15 * s, std::fmod(a * 180.0 / kPi, 360.0), -35.0));
        }
    } else if (name == "dive") {
        // Straight down from high up to a low, near-horizontal view, moving north.
        for (int i = 0; i <= 8; ++i) {
            const double f = i / 8.0;
            k.push_back(key(i, c.x, c.y - 0.5 * s + 0.6 * s * f, 0.6 * s * std::pow(1.0 - f, 2.0) + 0.01 * s, 0.0,
                            -90.0 + 85.0 * f));
        }
    } else if (name == "fast") {
        // Zig-zag at high speed with sudden 90° turns, low above the terrain: streaming stress.
        const double h = 0.03 * s;
        const glm::dvec2 pts[] = {{-0.8, -0.8}, {0.8, -0.8}, {0.8, -0.3}, {-0.8, -0.3}, {-0.8, 0.2},
                                  {0.8, 0.2},   {0.8, 0.7},  {-0.8, 0.7}};
        const double yaws[] = {90, 0, 270, 0, 90, 0, 270, 270};
        for (int i = 0; i < 8; ++i) k.push_back(key(i, c.x + pts[i].x * s, c.y + pts[i].y * s, h, yaws[i], -30.0));
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
    std::ifstream in(file);
    if (!in) return fileError(f, "file not found");
    auto j = nlohmann::json::parse(in, nullptr, false);
    if (j.is_discarded()) return fileError(f, "malformed JSON camera path");
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
    size_t i = 0;
    while (i + 2 < m_keys.size() && m_keys[i + 1].time <= t) ++i;
    const CameraKeyframe& a = m_keys[i];
    const CameraKeyframe& b = m_keys[i + 1];
    const double f = std::clamp((t - a.time) / (b.time - a.time), 0.0, 1.0);
    const CameraKeyframe& p = m_keys[i == 0 ? 0 : i - 1];
    const CameraKeyframe& q = m_keys[std::min(i + 2, m_keys.size() - 1)];
    Camera c;
    // Terrain-relative heights interpolate as heights, then sit on the terrain under the interpolated point.
    c.position = catmullRom(p.position, a.position, b.position, q.position, f);
    if (a.heightAboveTerrain && terrainHeight) c.position.z += terrainHeight(c.position.x, c.position.y);
    c.yawDeg = std::fmod(lerpAngle(a.yawDeg, b.yawDeg, f) + 360.0, 360.0);
    c.pitchDeg = std::clamp(a.pitchDeg + (b.pitchDeg - a.pitchDeg) * f, -90.0, 90.0);
    c.fovYDeg = a.fovYDeg + (b.fovYDeg - a.fovYDeg) * f;
    return c;
}

} // namespace seasonview
