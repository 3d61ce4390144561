#pragma once
// Hand-made blocks for the BlockMap tests (BlockMapTest, BlockMapGLTest): axis-aligned prisms as a city model.
#include "CityModel.h"

#include <array>
#include <vector>

namespace seasonview::test {

// An axis-aligned prism: x0..x1, y0..y1 (metres), from z `base` to `top`.
struct Prism {
    double x0, y0, x1, y1, top;
    double base = 0.0;
};

/// The prisms as a model, untextured: four walls and a roof each (a courtyard is four prisms around it). `faceOf`,
/// when given, receives per triangle the side it lies on: 0 −x, 1 +x, 2 −y, 3 +y, 4 the roof.
inline city::CityModel prismModel(const std::vector<Prism>& prisms, std::vector<int>* faceOf = nullptr) {
    city::CityModel m;
    m.buildingIds = {"b"};
    if (faceOf) faceOf->clear();
    auto quad = [&](glm::dvec3 a, glm::dvec3 b, glm::dvec3 c, glm::dvec3 d, int face) {
        for (auto tri : {std::array<glm::dvec3, 3>{a, b, c}, std::array<glm::dvec3, 3>{a, c, d}}) {
            city::TexturedTriangle t;
            t.v = tri;
            t.texture = -1;
            m.triangles.push_back(t);
            m.building.push_back(0);
            m.surface.push_back(face == 4 ? city::Surface::Roof : city::Surface::Wall);
            if (faceOf) faceOf->push_back(face);
        }
    };
    for (const Prism& p : prisms) {
        const glm::dvec3 a(p.x0, p.y0, p.base), b(p.x1, p.y0, p.base), c(p.x1, p.y1, p.base), d(p.x0, p.y1, p.base),
            up(0, 0, p.top - p.base);
        quad(a, d, d + up, a + up, 0);
        quad(b, c, c + up, b + up, 1);
        quad(a, b, b + up, a + up, 2);
        quad(d, c, c + up, d + up, 3);
        quad(a + up, b + up, c + up, d + up, 4);
    }
    return m;
}

/// A building with a sloped roof added to `m`, untextured: its footprint [x0, x1] × [y0, y1] from the ground up, the
/// roof a shed rising along y from `low` at y0 to `high` at y1, or (`gable`) two slopes from eaves at `low` to a ridge
/// at `high` along x, halfway across y, with the gable ends as walls.
inline void addSlopedBuilding(city::CityModel& m, double x0, double y0, double x1, double y1, double low, double high,
                              bool gable) {
    if (m.buildingIds.empty()) m.buildingIds = {"b"};
    auto tri = [&](glm::dvec3 a, glm::dvec3 b, glm::dvec3 c, city::Surface surface) {
        city::TexturedTriangle t;
        t.v = {a, b, c};
        t.texture = -1;
        m.triangles.push_back(t);
        m.building.push_back(0);
        m.surface.push_back(surface);
    };
    auto quad = [&](glm::dvec3 a, glm::dvec3 b, glm::dvec3 c, glm::dvec3 d, city::Surface surface) {
        tri(a, b, c, surface);
        tri(a, c, d, surface);
    };
    const city::Surface wall = city::Surface::Wall, roof = city::Surface::Roof;
    // The walls' tops: level eaves for a gable, the shed's slope on its sides.
    const double top1 = gable ? low : high, ym = 0.5 * (y0 + y1);
    quad({x0, y0, 0}, {x1, y0, 0}, {x1, y0, low}, {x0, y0, low}, wall);
    quad({x0, y1, 0}, {x1, y1, 0}, {x1, y1, top1}, {x0, y1, top1}, wall);
    quad({x0, y0, 0}, {x0, y1, 0}, {x0, y1, top1}, {x0, y0, low}, wall);
    quad({x1, y0, 0}, {x1, y1, 0}, {x1, y1, top1}, {x1, y0, low}, wall);
    if (gable) {
        tri({x0, y0, low}, {x0, y1, low}, {x0, ym, high}, wall);
        tri({x1, y0, low}, {x1, y1, low}, {x1, ym, high}, wall);
        quad({x0, y0, low}, {x1, y0, low}, {x1, ym, high}, {x0, ym, high}, roof);
        quad({x0, ym, high}, {x1, ym, high}, {x1, y1, low}, {x0, y1, low}, roof);
    } else {
        quad({x0, y0, low}, {x1, y0, low}, {x1, y1, high}, {x0, y1, high}, roof);
    }
}

} // namespace seasonview::test
