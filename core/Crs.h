#pragma once
// Coordinate reference systems seasonview understands: geographic (WGS84-like) and UTM.
#include "Result.h"

#include <glm/vec2.hpp>

#include <string>

namespace seasonview {

/// A supported CRS. Geographic coordinates are (longitude, latitude) in degrees, UTM ones (easting, northing) in
/// metres. EPSG 4326/4258/6697/4269 are all treated as WGS84 (sub-metre differences); UTM is WGS84 326xx/327xx or
/// ETRS89 258xx.
struct Crs {
    enum class Kind { Geographic, Utm };
    Kind kind = Kind::Geographic;
    int epsg = 4326;
    int zone = 0;       // UTM zone 1..60 (Utm only)
    bool north = true;  // UTM hemisphere (Utm only)

    static Crs geographic(int epsg = 4326) { return Crs{Kind::Geographic, epsg, 0, true}; }
    static Crs utm(int zone, bool north);
    /// Crs from an EPSG code; an error names the code when it is not supported.
    static Result<Crs> fromEpsg(int epsg);

    bool isGeographic() const { return kind == Kind::Geographic; }
    std::string name() const; // "EPSG:32632 (UTM 32N)"
    /// Same coordinate space (datum differences between WGS84 and ETRS89 ignored).
    bool sameSpace(const Crs& o) const;
};

/// Converts a point between two supported CRSs (GeographicLib). `p` and the result are in each CRS's own units.
glm::dvec2 convert(const Crs& from, const Crs& to, glm::dvec2 p);

} // namespace seasonview
