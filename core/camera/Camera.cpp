#include "Camera.h"

#include <glm/gtc/matrix_transform.hpp>

#include <charconv>
#include <cmath>
#include <sstream>
#include <vector>

namespace seasonview {

namespace {
double rad(double deg) { return deg * 3.14159265358979323846 / 180.0; }
} // namespace

glm::dvec3 Camera::forward() const {
    const double y = rad(yawDeg), p = rad(pitchDeg);
    return {std::sin(y) * std::cos(p), std::cos(y) * std::cos(p), std::sin(p)};
}

glm::dvec3 Camera::right() const {
    const double y = rad(yawDeg);
    return {std::cos(y), -std::sin(y), 0.0};
}

glm::dvec3 Camera::up() const { return glm::cross(right(), forward()); }

glm::dmat4 Camera::viewMatrix() const {
    const glm::dvec3 f = forward(), r = right(), u = up();
    glm::dmat4 m(1.0);
    m[0][0] = r.x; m[1][0] = r.y; m[2][0] = r.z;
    m[0][1] = u.x; m[1][1] = u.y; m[2][1] = u.z;
    m[0][2] = -f.x; m[1][2] = -f.y; m[2][2] = -f.z;
    m[3][0] = -glm::dot(r, position);
    m[3][1] = -glm::dot(u, position);
    m[3][2] = glm::dot(f, position);
    return m;
}

glm::dmat4 Camera::projectionMatrix(double aspect, double near) const {
    // Reversed-Z, infinite far plane, clip depth in [0,1]: z_ndc = near / -z_eye.
    const double f = 1.0 / std::tan(rad(fovYDeg) * 0.5);
    glm::dmat4 m(0.0);
    m[0][0] = f / aspect;
    m[1][1] = f;
    m[2][3] = -1.0;
    m[3][2] = near;
    return m;
}

std::string Camera::toString() const {
    std::ostringstream s;
    s.precision(10);
    // Round to 0.1 mm / 1e-7 degrees so float noise does not print as 1e-11.
    auto clean = [](double v) { return std::round(v * 1e7) / 1e7; };
    s << clean(position.x) << ',' << clean(position.y) << ',' << clean(position.z) << ',' << clean(yawDeg) << ','
      << clean(pitchDeg) << ',' << clean(fovYDeg);
    return s.str();
}

Camera CameraSpec::resolve(const std::function<double(double, double)>& terrainHeight) const {
    Camera c = camera;
    if (heightAboveTerrain) c.position.z = terrainHeight(c.position.x, c.position.y) + *heightAboveTerrain;
    return c;
}

Result<CameraSpec> parseCamera(const std::string& text) {
    auto bad = [&](const std::string& why) { return Error{"camera '" + text + "': " + why}; };
    std::vector<std::string> fields;
    size_t start = 0;
    while (true) {
        size_t comma = text.find(',', start);
        fields.push_back(text.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
        if (comma == std::string::npos) break;
        start = comma + 1;
    }
    if (fields.size() != 5 && fields.size() != 6)
        return bad("expected X,Y,Z,YAW,PITCH[,FOV] (Z may be +H), got " + std::to_string(fields.size()) + " fields");
    static const char* names[] = {"X", "Y", "Z", "YAW", "PITCH", "FOV"};
    double v[6] = {0, 0, 0, 0, 0, 60.0};
    CameraSpec spec;
    for (size_t i = 0; i < fields.size(); ++i) {
        std::string f = fields[i];
        while (!f.empty() && f.front() == ' ') f.erase(f.begin());
        while (!f.empty() && f.back() == ' ') f.pop_back();
        bool relative = false;
        if (i == 2 && !f.empty() && f.front() == '+') {
            relative = true;
            f.erase(f.begin());
        }
        const char* b = f.data();
        const char* e = f.data() + f.size();
        auto [ptr, ec] = std::from_chars(b, e, v[i]);
        if (f.empty() || ec != std::errc() || ptr != e || !std::isfinite(v[i]))
            return bad(std::string(names[i]) + " '" + fields[i] + "' is not a number");
        if (relative) spec.heightAboveTerrain = v[i];
    }
    if (v[4] < -90.0 || v[4] > 90.0) return bad("PITCH must be within [-90, 90] degrees");
    if (!(v[5] > 0.0 && v[5] < 180.0)) return bad("FOV must be within (0, 180) degrees");
    spec.camera.position = {v[0], v[1], spec.heightAboveTerrain ? 0.0 : v[2]};
    spec.camera.yawDeg = v[3];
    spec.camera.pitchDeg = v[4];
    spec.camera.fovYDeg = v[5];
    return spec;
}

} // namespace seasonview
