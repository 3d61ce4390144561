#include "Crs.h"

#include <GeographicLib/UTMUPS.hpp>

#include <cmath>

namespace seasonview {

Crs Crs::utm(int zone, bool north) {
    assert(zone >= 1 && zone <= 60 && "Crs::utm(): zone out of range");
    return Crs{Kind::Utm, (north ? 32600 : 32700) + zone, zone, north};
}

Result<Crs> Crs::fromEpsg(int epsg) {
    // Geographic: WGS84 and the datums within a metre of it for our purposes (ETRS89, JGD2011, NAD83).
    if (epsg == 4326 || epsg == 4258 || epsg == 6668 || epsg == 6697 || epsg == 4269 || epsg == 4979)
        return Crs::geographic(epsg);
    if (epsg > 32600 && epsg <= 32660) return Crs::utm(epsg - 32600, true);
    if (epsg > 32700 && epsg <= 32760) return Crs::utm(epsg - 32700, false);
    if (epsg >= 25828 && epsg <= 25838) { // ETRS89 / UTM zones 28N..38N
        Crs c = Crs::utm(epsg - 25800, true);
        c.epsg = epsg;
        return c;
    }
    return Error{"unsupported CRS EPSG:" + std::to_string(epsg) +
                 " (seasonview reads geographic WGS84/ETRS89 and UTM, EPSG:326xx/327xx/258xx)"};
}

std::string Crs::name() const {
    std::string s = "EPSG:" + std::to_string(epsg);
    if (kind == Kind::Utm) s += " (UTM " + std::to_string(zone) + (north ? "N)" : "S)");
    else s += " (geographic)";
    return s;
}

bool Crs::sameSpace(const Crs& o) const {
    if (kind != o.kind) return false;
    return kind == Kind::Geographic || (zone == o.zone && north == o.north);
}

glm::dvec2 convert(const Crs& from, const Crs& to, glm::dvec2 p) {
    if (from.sameSpace(to)) return p;
    double lat = 0, lon = 0;
    if (from.isGeographic()) {
        lon = p.x;
        lat = p.y;
    } else {
        GeographicLib::UTMUPS::Reverse(from.zone, from.north, p.x, p.y, lat, lon);
    }
    if (to.isGeographic()) return {lon, lat};
    int zone = 0;
    bool north = true;
    double x = 0, y = 0;
    // Force the target zone (points near a zone edge stay in the scene's zone).
    GeographicLib::UTMUPS::Forward(lat, lon, zone, north, x, y, to.zone, to.north);
    (void)zone;
    (void)north;
    return {x, y};
}

} // namespace seasonview
