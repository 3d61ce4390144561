#pragma once
// The scene's local metric frame: x east, y north, z up, metres, origin at the scene centre.
//  - A projected CRS whose scale at the centre is within 1 % of true (UTM, national grids such as Lambert-93, RD New,
//    LV95, British National Grid): the frame is that grid translated to the centre (z = height). Exact, no curvature.
//  - Anything else (geographic longitude/latitude, Web Mercator, whose scale is 1/cos(latitude)): GeographicLib's
//    LocalCartesian (an east-north-up tangent plane) at the centre, reached through geographic coordinates.
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
    /// True when local = the frame CRS's coordinates minus the centre (a metric projected CRS); false for the
    /// tangent-plane frame.
    bool isTranslation() const { return !m_impl; }

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

/// Whether a projected CRS is close enough to true scale at `p` (within 1 % east and north) to serve as a metric
/// frame by translation; false for geographic CRSs.
bool isMetricAt(const Crs& crs, glm::dvec2 p);

} // namespace seasonview
