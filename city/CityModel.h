#pragma once
// A textured city model as seasonview draws it: a triangle soup in a local metric frame (x east, y north, z up,
// metres), each triangle with its texture, building and surface kind. Loaded from CityGML 1.0/2.0 (libcitygml) or
// OBJ+MTL (tinyobjloader); the atlas-tree build and the renderers consume it.
#include "AtlasLayout.h"

#include "Crs.h"
#include "Result.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace seasonview::city {

/// What a triangle is part of (CityGML boundary surfaces; OBJ and unclassified surfaces by their normal).
enum class Surface : std::uint8_t { Wall = 0, Roof = 1, Ground = 2, Other = 3 };

/// An image a model's triangles sample. `path` is absolute (or as given when the model named it so); `repeat`:
/// texture coordinates outside [0,1] repeat the image (CityGML wrap mode "wrap"/"mirror", OBJ always).
struct CityTexture {
    std::string path;
    bool repeat = true;
    int channels = 3; // 4: has alpha (goes to the RGBA tree)
    int width = 0, height = 0; // texels of the file
};

/// The model: triangles in the local frame of GeoFrame(crs, origin) (metres; z = the source's heights, metres).
/// triangles[i].texture indexes `textures`, or is -1 for an untextured triangle (drawn in a flat colour).
struct CityModel {
    std::string source;            // the file it came from
    Crs crs;                       // the source's CRS
    glm::dvec2 origin{0.0};        // the local frame's origin, in crs units
    bool sceneFrame = false;       // positions are already the scene's local frame (OBJ read with localFrame)
    std::vector<TexturedTriangle> triangles;
    std::vector<std::uint32_t> building; // per triangle: index into buildingIds
    std::vector<Surface> surface;        // per triangle
    std::vector<std::string> buildingIds;
    std::vector<CityTexture> textures;
    /// One line each: problems that did not stop the load (missing textures drawn untextured, degenerate polygons
    /// skipped, non-planar polygons triangulated as they are), naming the file.
    std::vector<std::string> warnings;

    glm::dvec3 boundsMin() const;
    glm::dvec3 boundsMax() const;
    std::size_t texturedTriangles() const;
    /// `message` with the first load warning appended (and how many there were): what a command that fails on the
    /// model prints, so the failure stays one line and names its likely cause (a cut .mtl, missing textures).
    std::string failureWithWarnings(const std::string& message) const;
};

/// Limits on a city model, checked before its polygons are triangulated and stored: polygons per file (a
/// country's LoD2 buildings are ~10^7), vertices per OBJ face (tinyobjloader counts them in a byte, so a longer face
/// would be read as another; real walls and roofs have tens; CityGML polygons are tessellated by libcitygml). A file
/// past them is refused with the limit named. A CityGML file's polygons are counted in its text before libcitygml
/// parses it (and builds every polygon in memory).
inline constexpr std::size_t kMaxCityPolygons = std::size_t(1) << 25;
inline constexpr std::size_t kMaxPolygonVertices = 255;

/// How to read a model.
struct CityLoadOptions {
    /// The CRS when the file names none (always for OBJ; CityGML without srsName). Without it such a file is an
    /// error, unless `localFrame` is set.
    std::optional<Crs> crs;
    /// OBJ only: positions are already metres in the scene's local frame (no CRS); the model's origin is (0, 0).
    bool localFrame = false;
    /// OBJ only: the file's up axis ('y', the OBJ convention, or 'z').
    char objUp = 'y';
    /// Polygons a file may hold (kMaxCityPolygons; lower in tests). CityGML files are counted before they are parsed.
    std::size_t maxPolygons = kMaxCityPolygons;
};

/// Loads CityGML (.gml, .xml, .citygml) or OBJ (.obj, with its .mtl). CityGML: every Building (and its parts) at the
/// highest LoD it has, textures of the theme "rgbTexture" or the first one; geographic CRSs are read in EPSG axis
/// order (latitude first). Errors (one line naming the file): missing/unreadable file, not well-formed XML, no CRS,
/// an unsupported CRS, no building geometry. Missing textures, degenerate and non-planar polygons are warnings.
Result<CityModel> loadCityModel(const std::string& path, const CityLoadOptions& options = {});

/// The EPSG code in a GML srsName ("EPSG:25833", "urn:ogc:def:crs:EPSG::25833", "http://www.opengis.net/def/crs/
/// EPSG/0/6697", compound "urn:ogc:def:crs,crs:EPSG::25833,crs:EPSG::7837" -> the first, German AdV
/// "urn:adv:crs:ETRS89_UTM33*DE_DHHN2016_NH" -> 25833); nullopt when there is none.
std::optional<int> epsgFromSrsName(const std::string& srsName);

/// The horizontal CRS a GML srsName (or a --city-crs value) names, through PROJ: any EPSG code, URN, OGC URL, WKT or
/// PROJ string, compound CRSs reduced to their horizontal part, and the German AdV names. The error says the name
/// is not a CRS PROJ knows.
Result<Crs> crsFromSrsName(const std::string& srsName);

/// Moves the model into another local frame (GeoFrame(crs, origin)): positions converted point by point, heights
/// kept. A no-op when the frames are the same or the model is in the scene's frame already (sceneFrame).
void reframe(CityModel& model, const Crs& crs, glm::dvec2 origin);

/// Sets every building on the terrain: shifts it vertically so its lowest vertex lies at the lowest terrain height
/// under its vertices (`heightAt(x, y)` in the model's local frame, metres). Returns the largest shift (metres).
double placeOnTerrain(CityModel& model, const std::function<double(double, double)>& heightAt);
/// Labels as one building each set of triangles joined by shared corners (exactly equal positions: a building's
/// walls meet its roofs at the eaves; buildings that touch are one), replacing model.building and buildingIds
/// ("part0", "part1", ...): for a model that keeps no buildings (an atlas tree's, modelOfTree).
void labelConnectedBuildings(CityModel& model);

} // namespace seasonview::city
