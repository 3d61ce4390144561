#include "GeoFrame.h"

#include <GeographicLib/LocalCartesian.hpp>

namespace seasonview {

struct GeoFrame::Impl {
    GeographicLib::LocalCartesian lc;
};

GeoFrame::GeoFrame(const Crs& crs, glm::dvec2 centre) : m_crs(crs), m_centre(centre) {
    glm::dvec2 lonlat = convert(crs, Crs::geographic(), centre);
    m_centreLatLon = {lonlat.y, lonlat.x};
    if (crs.isGeographic()) m_impl = std::make_unique<Impl>(Impl{GeographicLib::LocalCartesian(lonlat.y, lonlat.x, 0.0)});
}

GeoFrame::~GeoFrame() = default;
GeoFrame::GeoFrame(const GeoFrame& o) : m_crs(o.m_crs), m_centre(o.m_centre), m_centreLatLon(o.m_centreLatLon) {
    if (o.m_impl) m_impl = std::make_unique<Impl>(*o.m_impl);
}
GeoFrame& GeoFrame::operator=(const GeoFrame& o) {
    if (this != &o) {
        m_crs = o.m_crs;
        m_centre = o.m_centre;
        m_centreLatLon = o.m_centreLatLon;
        m_impl = o.m_impl ? std::make_unique<Impl>(*o.m_impl) : nullptr;
    }
    return *this;
}

glm::dvec3 GeoFrame::toLocal(const Crs& from, glm::dvec2 p, double h) const {
    if (!m_impl) { // UTM frame: translate only
        glm::dvec2 q = convert(from, m_crs, p);
        return {q.x - m_centre.x, q.y - m_centre.y, h};
    }
    glm::dvec2 lonlat = convert(from, Crs::geographic(), p);
    double x = 0, y = 0, z = 0;
    m_impl->lc.Forward(lonlat.y, lonlat.x, h, x, y, z);
    return {x, y, z};
}

glm::dvec2 GeoFrame::fromLocal(const Crs& to, glm::dvec2 local) const {
    if (!m_impl) return convert(m_crs, to, local + m_centre);
    double lat = 0, lon = 0, h = 0;
    m_impl->lc.Reverse(local.x, local.y, 0.0, lat, lon, h);
    return convert(Crs::geographic(), to, {lon, lat});
}

} // namespace seasonview
