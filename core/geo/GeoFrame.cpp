#include "GeoFrame.h"

#include <GeographicLib/LocalCartesian.hpp>

#include <cmath>

namespace seasonview {

struct GeoFrame::Impl {
    GeographicLib::LocalCartesian lc;
};

bool isMetricAt(const Crs& crs, glm::dvec2 p) {
    if (crs.isGeographic()) return false;
    const glm::dvec2 k = pointScale(crs, p);
    return std::abs(k.x - 1.0) < 0.01 && std::abs(k.y - 1.0) < 0.01;
}

GeoFrame::GeoFrame(const Crs& crs, glm::dvec2 centre) : m_crs(crs), m_centre(centre) {
    const glm::dvec2 lonlat = convert(crs, Crs::geographic(), centre);
    m_centreLatLon = {lonlat.y, lonlat.x};
    if (!isMetricAt(crs, centre))
        m_impl = std::make_unique<Impl>(Impl{GeographicLib::LocalCartesian(lonlat.y, lonlat.x, 0.0)});
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
    if (!m_impl) { // metric projected frame: translate only
        const glm::dvec2 q = convert(from, m_crs, p);
        return {q.x - m_centre.x, q.y - m_centre.y, h};
    }
    const glm::dvec2 lonlat = convert(from, Crs::geographic(), p);
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
