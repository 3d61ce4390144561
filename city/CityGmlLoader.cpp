// CityGML 1.0/2.0 through libcitygml: buildings at their highest LoD, with their appearance's textures.
#include "CityLoaders.h"

#include <citygml/citygml.h>
#include <citygml/citygmllogger.h>
#include <citygml/citymodel.h>
#include <citygml/cityobject.h>
#include <citygml/envelope.h>
#include <citygml/geometry.h>
#include <citygml/polygon.h>
#include <citygml/texture.h>

#include "GeoFrame.h"

#include <glm/common.hpp>

#include <cctype>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <optional>
#include <vector>

namespace seasonview::city::detail {
namespace {

using citygml::CityObject;
using citygml::Geometry;
using Cot = CityObject::CityObjectsType;

/// libcitygml reports through a logger; seasonview keeps its own warnings (one line per kind), so only errors are
/// remembered, to explain a failed parse.
class QuietLogger final : public citygml::CityGMLLogger {
public:
    QuietLogger() : CityGMLLogger(LOGLEVEL::LL_ERROR) {}
    void log(LOGLEVEL, const std::string& message, const char*, int) const override {
        if (lastError.empty()) lastError = firstLine(message);
    }
    mutable std::string lastError;
};

bool isBuilding(Cot t) { return t == Cot::COT_Building; }

Surface surfaceOf(Cot objectType, Geometry::GeometryType geometryType) {
    switch (objectType) {
    case Cot::COT_RoofSurface: return Surface::Roof;
    case Cot::COT_WallSurface: return Surface::Wall;
    case Cot::COT_GroundSurface: return Surface::Ground;
    default: break;
    }
    switch (geometryType) {
    case Geometry::GeometryType::GT_Roof: return Surface::Roof;
    case Geometry::GeometryType::GT_Wall: return Surface::Wall;
    case Geometry::GeometryType::GT_Ground: return Surface::Ground;
    default: return Surface::Other;
    }
}

unsigned maxLod(const Geometry& g) {
    unsigned lod = g.getPolygonsCount() > 0 ? g.getLOD() : 0;
    for (unsigned i = 0; i < g.getGeometriesCount(); ++i) lod = std::max(lod, maxLod(g.getGeometry(i)));
    return lod;
}

unsigned maxLod(const CityObject& o) {
    unsigned lod = 0;
    for (unsigned i = 0; i < o.getGeometriesCount(); ++i) lod = std::max(lod, maxLod(o.getGeometry(i)));
    for (unsigned i = 0; i < o.getChildCityObjectsCount(); ++i) lod = std::max(lod, maxLod(o.getChildCityObject(i)));
    return lod;
}

/// The first srsName found: the model's envelope, the objects' envelopes, their geometries.
std::string findSrsName(const citygml::Geometry& g) {
    if (!g.getSRSName().empty()) return g.getSRSName();
    for (unsigned i = 0; i < g.getGeometriesCount(); ++i)
        if (auto s = findSrsName(g.getGeometry(i)); !s.empty()) return s;
    return {};
}
std::string findSrsName(const CityObject& o) {
    if (!o.getEnvelope().srsName().empty()) return o.getEnvelope().srsName();
    for (unsigned i = 0; i < o.getGeometriesCount(); ++i)
        if (auto s = findSrsName(o.getGeometry(i)); !s.empty()) return s;
    for (unsigned i = 0; i < o.getChildCityObjectsCount(); ++i)
        if (auto s = findSrsName(o.getChildCityObject(i)); !s.empty()) return s;
    return {};
}

struct Reader {
    CityModel& model;
    const GeoFrame& frame;
    bool latFirst;           // geographic CRS in EPSG axis order
    std::string theme;
    std::filesystem::path dir;
    std::map<std::string, int> known;
    std::vector<std::string> missing;
    std::string unreadable; // the first texture that exists but does not read (an error)
    std::size_t untexturedByMissing = 0;
    PolygonChecks checks;

    glm::dvec3 toLocal(const TVec3d& p) const {
        const glm::dvec2 xy = latFirst ? glm::dvec2(p.y, p.x) : glm::dvec2(p.x, p.y);
        return frame.toLocal(model.crs, xy, p.z);
    }

    void geometry(const Geometry& g, unsigned lod, std::uint32_t building, Cot objectType) {
        if (g.getLOD() == lod) {
            const Surface surface = surfaceOf(objectType, g.getType());
            for (unsigned i = 0; i < g.getPolygonsCount(); ++i) polygon(*g.getPolygon(i), building, surface);
        }
        for (unsigned i = 0; i < g.getGeometriesCount(); ++i) geometry(g.getGeometry(i), lod, building, objectType);
    }

    void polygon(const citygml::Polygon& p, std::uint32_t building, Surface surface) {
        std::vector<glm::dvec3> verts;
        verts.reserve(p.getVertices().size());
        for (const auto& v : p.getVertices()) verts.push_back(toLocal(v));
        int texture = -1;
        std::vector<glm::dvec2> uvs;
        bool front = true;
        auto tex = p.getTextureFor(theme, true);
        if (!tex) {
            tex = p.getTextureFor(theme, false);
            front = false;
        }
        if (tex && !tex->getUrl().empty()) {
            const auto coords = p.getTexCoordsForTheme(theme, front);
            const std::filesystem::path url(tex->getUrl());
            const std::string file = (url.is_absolute() ? url : dir / url).lexically_normal().string();
            // CityGML's default wrap mode is "none" (outside [0,1] transparent): only wrap and mirror repeat.
            const bool repeat = tex->getWrapMode() == citygml::Texture::WrapMode::WM_WRAP ||
                                tex->getWrapMode() == citygml::Texture::WrapMode::WM_MIRROR;
            texture = textureIndex(model, file, repeat, known, missing, unreadable);
            if (texture < 0) ++untexturedByMissing;
            for (const auto& c : coords) uvs.emplace_back(double(c.x), double(c.y));
        }
        addPolygon(model, verts, uvs, p.getIndices(), texture, building, surface, checks);
    }

    void object(const CityObject& o, unsigned lod, std::uint32_t building) {
        for (unsigned i = 0; i < o.getGeometriesCount(); ++i) geometry(o.getGeometry(i), lod, building, o.getType());
        for (unsigned i = 0; i < o.getChildCityObjectsCount(); ++i) object(o.getChildCityObject(i), lod, building);
    }
};

/// Polygon elements in a GML file's text (`<gml:Polygon` or `<Polygon` with any namespace prefix, not
/// `<gml:PolygonPatch`), read in chunks: what libcitygml would build, counted before it allocates anything. Stops
/// counting once past `limit`. Nullopt when the file cannot be read.
std::optional<std::size_t> countGmlPolygons(const std::string& path, std::size_t limit) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return std::nullopt;
    constexpr std::size_t kChunk = std::size_t(1) << 20, kKeep = 256; // a tag name with its prefix fits in kKeep
    std::string buf;
    std::size_t count = 0, from = 0; // buf[0, from): kept only as the context before the next matches
    std::vector<char> chunk(kChunk);
    while (in) {
        in.read(chunk.data(), std::streamsize(kChunk));
        const auto got = std::size_t(in.gcount());
        if (got == 0) break;
        buf.append(chunk.data(), got);
        const bool last = !in;
        // Tags starting before `end` are complete in buf (their name is shorter than kKeep).
        const std::size_t end = last ? buf.size() : (buf.size() > kKeep ? buf.size() - kKeep : 0);
        std::size_t at = from;
        for (; (at = buf.find("Polygon", at)) != std::string::npos && at < end; at += 7) {
            std::size_t q = at; // back over "prefix:" to the '<' that opens the tag
            if (q > 0 && buf[q - 1] == ':') {
                --q;
                while (q > 0 && at - q < 64 &&
                       (std::isalnum(static_cast<unsigned char>(buf[q - 1])) || std::strchr("_-.", buf[q - 1]) != nullptr))
                    --q;
            }
            if (q == 0 || buf[q - 1] != '<') continue; // another name ending in Polygon, or text
            const std::size_t after = at + 7;
            if (after < buf.size() && (std::isalnum(static_cast<unsigned char>(buf[after])) || buf[after] == '_'))
                continue; // <gml:PolygonPatch>
            if (++count > limit) return count;
        }
        const std::size_t drop = end > 64 ? end - 64 : 0; // keep a prefix's room before `end`
        buf.erase(0, drop);
        from = end - drop;
    }
    return count;
}

} // namespace

Result<CityModel> loadCityGml(const std::string& path, const CityLoadOptions& options) {
    // Resource limit before parsing: libcitygml builds every polygon of the file in memory.
    if (const auto n = countGmlPolygons(path, options.maxPolygons); n && *n > options.maxPolygons)
        return fileError(path, "more than " + std::to_string(options.maxPolygons) + " polygons, over the limit of " +
                                   std::to_string(options.maxPolygons));
    citygml::ParserParams params;
    params.tesselate = true;
    params.optimize = false;
    auto logger = std::make_shared<QuietLogger>();
    std::shared_ptr<const citygml::CityModel> city;
    try {
        city = citygml::load(path, params, logger);
    } catch (...) {
        // Xerces throws its own types (SAXParseException) for malformed XML; libcitygml ships no headers for them.
        return fileError(path, "not well-formed CityGML/XML (truncated or corrupt)" +
                                   (logger->lastError.empty() ? std::string() : ": " + logger->lastError));
    }
    if (!city) return fileError(path, "not a CityGML file" + (logger->lastError.empty() ? std::string() : ": " + logger->lastError));

    // Buildings: root Building objects (their BuildingParts and boundary surfaces are children).
    std::vector<const CityObject*> buildings;
    for (const CityObject* o : city->getRootCityObjects())
        if (isBuilding(o->getType())) buildings.push_back(o);
    if (buildings.empty()) return fileError(path, "no buildings (no bldg:Building objects)");

    CityModel model;
    model.source = path;
    std::string srsName = city->getEnvelope().srsName();
    for (std::size_t i = 0; srsName.empty() && i < buildings.size(); ++i) srsName = findSrsName(*buildings[i]);
    if (srsName.empty()) {
        if (!options.crs) return fileError(path, "names no CRS (no srsName); give one (--city-crs EPSG:CODE)");
        model.crs = *options.crs;
    } else {
        auto crs = crsFromSrsName(srsName);
        if (!crs) return fileError(path, crs.message());
        model.crs = *crs;
    }

    // The frame's origin: the centre of the buildings' vertices, in the CRS's own axis order.
    const bool latFirst = model.crs.northFirst();
    glm::dvec2 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
    std::size_t polygons = 0;
    std::function<void(const Geometry&)> bound = [&](const Geometry& g) {
        polygons += g.getPolygonsCount();
        for (unsigned i = 0; i < g.getPolygonsCount(); ++i)
            for (const auto& v : g.getPolygon(i)->getVertices()) {
                const glm::dvec2 xy = latFirst ? glm::dvec2(v.y, v.x) : glm::dvec2(v.x, v.y);
                lo = glm::min(lo, xy);
                hi = glm::max(hi, xy);
            }
        for (unsigned i = 0; i < g.getGeometriesCount(); ++i) bound(g.getGeometry(i));
    };
    std::function<void(const CityObject&)> boundObject = [&](const CityObject& o) {
        for (unsigned i = 0; i < o.getGeometriesCount(); ++i) bound(o.getGeometry(i));
        for (unsigned i = 0; i < o.getChildCityObjectsCount(); ++i) boundObject(o.getChildCityObject(i));
    };
    for (const CityObject* b : buildings) boundObject(*b);
    if (polygons > options.maxPolygons)
        return fileError(path, std::to_string(polygons) + " polygons, over the limit of " +
                                   std::to_string(options.maxPolygons));
    if (lo.x > hi.x) return fileError(path, "no building geometry (no polygons)");
    if (model.crs.isGeographic() && (std::abs(lo.y) > 90.0 || std::abs(hi.y) > 90.0 || std::abs(lo.x) > 180.0))
        return fileError(path, "coordinates out of range for " + model.crs.name() + " (wrong CRS?)");
    model.origin = 0.5 * (lo + hi);
    const GeoFrame frame(model.crs, model.origin);

    std::string theme;
    const auto themes = city->themes();
    for (const auto& t : themes)
        if (t == "rgbTexture") theme = t;
    if (theme.empty() && !themes.empty()) theme = themes.front();

    Reader reader{model, frame, latFirst, theme, std::filesystem::path(path).parent_path(), {}, {}, {}, 0, {}};
    for (const CityObject* b : buildings) {
        const auto id = std::uint32_t(model.buildingIds.size());
        model.buildingIds.push_back(b->getId());
        reader.object(*b, maxLod(*b), id);
    }
    if (!reader.unreadable.empty()) return Error{reader.unreadable};
    if (model.triangles.empty()) return fileError(path, "no building geometry with area (all polygons degenerate)");
    reader.checks.addWarnings(model);
    if (!reader.missing.empty())
        model.warnings.push_back(path + ": " + std::to_string(reader.missing.size()) +
                                 " texture file(s) missing (first: " + reader.missing.front() + "); " +
                                 std::to_string(reader.untexturedByMissing) + " polygon(s) drawn untextured");
    return model;
}

} // namespace seasonview::city::detail
