#pragma once
// The scene's local metric frame: x east, y north, z up, metres.
//  - UTM data: the frame is the UTM grid translated to the scene centre (z = height). Exact, no curvature.
//  - Geographic data: GeographicLib::LocalCartesian (ENU tangent plane) at the scene centre.
#include "Crs.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <memory>

namespace seasonview {

class GeoFrame {
public:
    /// A frame for data in `crs`, centred on `centre` (in crs units).
    GeoFrame(const Crs& crs, glm::dvec2 centre);
    ~GeoFrame();
    GeoFrame(const GeoFrame&);
    GeoFrame& operator=(const GeoFrame&);

    const Crs& crs() const { return m_crs; }
    glm::dvec2 centre() const { return m_centre; }
    /// Latitude, longitude (degrees) of the centre.
    glm::dvec2 centreLatLon() const { return m_centreLatLon; }

    /// A point given in `from` (its units) at ellipsoidal/orthometric height h (metres) -> local (metres).
    glm::dvec3 toLocal(const Crs& from, glm::dvec2 p, double h = 0.0) const;
    /// A local point (metres, z ignored) -> the point in `to` (its units).
    glm::dvec2 fromLocal(const Crs& to, glm::dvec2 local) const;

private:
    Crs m_crs;
    glm::dvec2 m_centre;
    glm::dvec2 m_centreLatLon;
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

} // namespace seasonview
