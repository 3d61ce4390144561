#pragma once
// Coordinate reference systems, through PROJ (GDAL's OGRSpatialReference): any EPSG code, URN, OGC URL, WKT or PROJ
// string. Geographic coordinates are (longitude, latitude) in degrees whatever the CRS's own axis order, projected
// ones (easting, northing) in the CRS's unit.
#include "Result.h"

#include <glm/vec2.hpp>

#include <memory>
#include <span>
#include <string>
#include <string_view>

namespace seasonview {

/// A CRS as PROJ knows it: an immutable, cheaply copied value. Two Crs that PROJ finds to be the same system
/// (OGRSpatialReference::IsSame, e.g. EPSG:2154 and the WKT a GeoTIFF stores for it) compare equal and share one id.
class Crs {
public:
    /// EPSG:4326 (WGS 84, longitude/latitude).
    Crs();

    /// Parses what a user or a file may give: "EPSG:2154", "epsg:2154", "urn:ogc:def:crs:EPSG::2154",
    /// "http://www.opengis.net/def/crs/EPSG/0/2154", a WKT or PROJ string. The error says what was not understood.
    static Result<Crs> fromUserInput(std::string_view text);
    static Result<Crs> fromEpsg(int code);
    /// A CRS from a WKT (as GDAL returns it for a dataset).
    static Result<Crs> fromWkt(const std::string& wkt);
    static Crs geographic() { return Crs(); }
    /// WGS 84 / UTM zone `zone` (1..60), EPSG:326zz (north) or 327zz (south).
    static Crs utm(int zone, bool north);
    /// The WGS 84 UTM zone of a longitude/latitude (degrees).
    static Crs utmAt(double lon, double lat);

    bool isGeographic() const;
    /// The EPSG code PROJ identifies this CRS with; 0 when it has none.
    int epsg() const;
    /// "EPSG:2154 (RGF93 v1 / Lambert-93)", or the CRS's name alone when it has no EPSG code.
    std::string name() const;
    /// "EPSG:2154", else the WKT: what identifies this CRS in cache keys and files.
    std::string identifier() const;
    /// WKT2 (2019) of the CRS.
    const std::string& wkt() const;
    /// The CRS as ESRI WKT, what a .prj file next to a shapefile or table holds.
    std::string esriWkt() const;
    /// Metres per unit of the projected axes (1 for metres, 0.3048 for feet); for geographic CRSs, metres per
    /// degree of latitude (about 111 km).
    double metresPerUnit() const;
    /// Whether the CRS's authority defines its first axis as north (latitude or northing): EPSG's geographic CRSs
    /// and some national grids. Files that follow the authority's order (GML) then give (north, east) pairs.
    bool northFirst() const;
    /// Small integer unique per distinct CRS in this process: equal ids are the same CRS.
    int id() const { return m_id; }

    bool operator==(const Crs& o) const { return m_id == o.m_id; }
    bool operator!=(const Crs& o) const { return m_id != o.m_id; }

private:
    explicit Crs(int id) : m_id(id) {}
    int m_id = 0;
};

/// Converts a point between two CRSs (PROJ, best available transformation, datum shifts included). `p` and the
/// result are in each CRS's own units (longitude/latitude in degrees for geographic ones). The same CRS returns `p`
/// exactly. A point the transformation cannot map returns NaN coordinates.
glm::dvec2 convert(const Crs& from, const Crs& to, glm::dvec2 p);

/// Converts many points in place (one PROJ call: for loops over lattices and meshes).
void convert(const Crs& from, const Crs& to, std::span<glm::dvec2> points);

/// The point scale factor of a projected CRS at a point given in it: ground metres per CRS metre, measured east
/// and north over ±1 unit (1 for geographic CRSs). About 0.9996..1.001 for UTM, 1.51 for Web Mercator at 48.7° N.
glm::dvec2 pointScale(const Crs& crs, glm::dvec2 p);

} // namespace seasonview
