#include "CityModel.h"

#include "CityLoaders.h"
#include "GeoFrame.h"

#include <OpenImageIO/imageio.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <limits>
#include <regex>
#include <unordered_map>

namespace seasonview::city {

glm::dvec3 CityModel::boundsMin() const {
    glm::dvec3 lo(std::numeric_limits<double>::max());
    for (const auto& t : triangles)
        for (const auto& v : t.v) lo = glm::min(lo, v);
    return triangles.empty() ? glm::dvec3(0.0) : lo;
}

glm::dvec3 CityModel::boundsMax() const {
    glm::dvec3 hi(std::numeric_limits<double>::lowest());
    for (const auto& t : triangles)
        for (const auto& v : t.v) hi = glm::max(hi, v);
    return triangles.empty() ? glm::dvec3(0.0) : hi;
}

std::size_t CityModel::texturedTriangles() const {
    return std::size_t(std::count_if(triangles.begin(), triangles.end(), [](const auto& t) { return t.texture >= 0; }));
}

std::string CityModel::failureWithWarnings(const std::string& message) const {
    if (warnings.empty()) return message;
    return message + " (after " + std::to_string(warnings.size()) + (warnings.size() == 1 ? " warning: " : " warnings, the first: ") +
           warnings.front() + ")";
}

std::optional<int> epsgFromSrsName(const std::string& srsName) {
    std::smatch m;
    // "EPSG:25833", "EPSG::25833", "EPSG/0/25833" (OGC URN and URL forms); the first code of a compound CRS.
    static const std::regex epsg(R"(EPSG[:/]+(?:[0-9.]*[:/]+)?([0-9]{4,6}))", std::regex::icase);
    if (std::regex_search(srsName, m, epsg)) return std::stoi(m[1].str());
    // German AdV names: ETRS89_UTM32 / ETRS89_UTM33 (+ height system) = EPSG 25832 / 25833.
    static const std::regex adv(R"(ETRS89_UTM([0-9]{2}))", std::regex::icase);
    if (std::regex_search(srsName, m, adv)) return 25800 + std::stoi(m[1].str());
    return std::nullopt;
}

Result<Crs> crsFromSrsName(const std::string& srsName) {
    if (auto crs = Crs::fromUserInput(srsName)) return *crs;
    if (const auto code = epsgFromSrsName(srsName))
        if (auto crs = Crs::fromEpsg(*code)) return *crs;
    return Error{"unsupported CRS '" + srsName + "' (not a CRS PROJ knows; give an EPSG code, URN or WKT)"};
}

void reframe(CityModel& model, const Crs& crs, glm::dvec2 origin) {
    if (model.sceneFrame || (model.crs == crs && model.origin == origin)) return;
    const GeoFrame from(model.crs, model.origin), to(crs, origin);
    const bool translateOnly = model.crs == crs && to.isTranslation();
    const glm::dvec2 shift = model.origin - origin;
    for (auto& t : model.triangles)
        for (auto& v : t.v) {
            if (translateOnly) {
                v.x += shift.x;
                v.y += shift.y;
            } else {
                const glm::dvec3 l = to.toLocal(model.crs, from.fromLocal(model.crs, glm::dvec2(v)), 0.0);
                v.x = l.x;
                v.y = l.y;
            }
        }
    model.crs = crs;
    model.origin = origin;
}

void labelConnectedBuildings(CityModel& m) {
    const std::size_t n = m.triangles.size();
    std::vector<std::uint32_t> parent(n);
    for (std::size_t i = 0; i < n; ++i) parent[i] = std::uint32_t(i);
    auto find = [&](std::uint32_t i) {
        while (parent[i] != i) i = parent[i] = parent[parent[i]];
        return i;
    };
    struct Key {
        double x, y, z;
        bool operator==(const Key&) const = default;
    };
    struct Hash {
        std::size_t operator()(const Key& k) const {
            return std::hash<double>()(k.x) ^ (std::hash<double>()(k.y) * 0x9E3779B97F4A7C15ull) ^
                   (std::hash<double>()(k.z) * 0xC2B2AE3D27D4EB4Full);
        }
    };
    std::unordered_map<Key, std::uint32_t, Hash> first;
    first.reserve(n * 2);
    for (std::size_t i = 0; i < n; ++i)
        for (const glm::dvec3& v : m.triangles[i].v) {
            const auto [it, added] = first.try_emplace(Key{v.x, v.y, v.z}, std::uint32_t(i));
            if (!added) parent[find(std::uint32_t(i))] = find(it->second);
        }
    std::unordered_map<std::uint32_t, std::uint32_t> label;
    m.buildingIds.clear();
    for (std::size_t i = 0; i < n; ++i) {
        const auto [it, added] = label.try_emplace(find(std::uint32_t(i)), std::uint32_t(label.size()));
        if (added) m.buildingIds.push_back("part" + std::to_string(it->second));
        m.building[i] = it->second;
    }
    if (m.buildingIds.empty()) m.buildingIds = {"city"};
}


double placeOnTerrain(CityModel& model, const std::function<double(double, double)>& heightAt) {
    const std::size_t n = model.buildingIds.size();
    std::vector<double> minZ(n, std::numeric_limits<double>::max());
    std::vector<double> ground(n, std::numeric_limits<double>::max());
    for (std::size_t i = 0; i < model.triangles.size(); ++i) {
        const auto b = model.building[i];
        for (const auto& v : model.triangles[i].v) {
            minZ[b] = std::min(minZ[b], v.z);
            ground[b] = std::min(ground[b], heightAt(v.x, v.y));
        }
    }
    double worst = 0.0;
    for (std::size_t i = 0; i < model.triangles.size(); ++i) {
        const auto b = model.building[i];
        for (auto& v : model.triangles[i].v) v.z += ground[b] - minZ[b];
    }
    for (std::size_t b = 0; b < n; ++b)
        if (minZ[b] < std::numeric_limits<double>::max()) worst = std::max(worst, std::abs(ground[b] - minZ[b]));
    return worst;
}

Result<CityModel> loadCityModel(const std::string& path, const CityLoadOptions& options) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) return fileError(path, "no such file");
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    if (ext == ".obj") return detail::loadObj(path, options);
    if (ext == ".gml" || ext == ".xml" || ext == ".citygml") return detail::loadCityGml(path, options);
    return fileError(path, "unknown city model format '" + ext + "' (CityGML .gml/.xml/.citygml or OBJ .obj)");
}

namespace detail {

void PolygonChecks::addWarnings(CityModel& model) const {
    if (degenerate > 0)
        model.warnings.push_back(model.source + ": " + std::to_string(degenerate) +
                                 " degenerate polygon(s) (no area or fewer than 3 distinct vertices) skipped");
    if (nonPlanar > 0) {
        char worst[32];
        std::snprintf(worst, sizeof worst, "%.2f", worstOffPlane);
        model.warnings.push_back(model.source + ": " + std::to_string(nonPlanar) +
                                 " non-planar polygon(s) (up to " + worst + " m off their plane) triangulated as they are");
    }
}

void addPolygon(CityModel& model, const std::vector<glm::dvec3>& verts, const std::vector<glm::dvec2>& uvs,
                const std::vector<unsigned>& indices, int texture, std::uint32_t building, Surface surface,
                PolygonChecks& checks) {
    // Newell's normal: robust for any simple polygon, its length twice the projected area.
    glm::dvec3 normal(0.0), centre(0.0), lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
    for (std::size_t i = 0; i < verts.size(); ++i) {
        const auto& a = verts[i];
        const auto& b = verts[(i + 1) % verts.size()];
        normal += glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
        centre += a;
        lo = glm::min(lo, a);
        hi = glm::max(hi, a);
    }
    const double area2 = glm::length(normal);
    const double extent = verts.empty() ? 0.0 : glm::length(hi - lo);
    if (verts.size() < 3 || indices.size() < 3 || area2 <= 1e-9 * std::max(1.0, extent * extent)) {
        ++checks.degenerate;
        return;
    }
    centre /= double(verts.size());
    const glm::dvec3 n = normal / area2;
    double off = 0.0;
    for (const auto& v : verts) off = std::max(off, std::abs(glm::dot(v - centre, n)));
    if (off > std::max(0.05, 0.01 * extent)) {
        ++checks.nonPlanar;
        checks.worstOffPlane = std::max(checks.worstOffPlane, off);
    }
    const bool hasUv = uvs.size() == verts.size() && texture >= 0;
    for (std::size_t i = 0; i + 2 < indices.size(); i += 3) {
        TexturedTriangle t;
        for (int k = 0; k < 3; ++k) {
            const unsigned j = indices[i + std::size_t(k)];
            if (j >= verts.size()) return; // a reader's bug would show here; the polygon is dropped, not read wild
            t.v[std::size_t(k)] = verts[j];
            t.t[std::size_t(k)] = hasUv ? uvs[j] : glm::dvec2(0.0);
        }
        if (triangleArea(t) <= 1e-12) continue;
        t.texture = hasUv ? texture : -1;
        model.triangles.push_back(t);
        model.building.push_back(building);
        model.surface.push_back(surface == Surface::Other ? surfaceFromNormal(t) : surface);
    }
}

std::vector<unsigned> triangulatePolygon(const std::vector<glm::dvec3>& verts) {
    std::vector<unsigned> out;
    const std::size_t n = verts.size();
    if (n < 3) return out;
    glm::dvec3 normal(0.0);
    for (std::size_t i = 0; i < n; ++i) {
        const auto& a = verts[i];
        const auto& b = verts[(i + 1) % n];
        normal += glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
    }
    // Project by dropping the normal's largest axis; keep the orientation counter-clockwise.
    const glm::dvec3 an = glm::abs(normal);
    const int drop = an.x >= an.y && an.x >= an.z ? 0 : (an.y >= an.z ? 1 : 2);
    const int u = (drop + 1) % 3, v = (drop + 2) % 3;
    const bool flip = normal[drop] < 0.0;
    std::vector<glm::dvec2> p(n);
    for (std::size_t i = 0; i < n; ++i) p[i] = glm::dvec2(verts[i][u], flip ? -verts[i][v] : verts[i][v]);
    auto cross = [](glm::dvec2 a, glm::dvec2 b, glm::dvec2 c) { return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x); };
    std::vector<unsigned> ring(n);
    for (std::size_t i = 0; i < n; ++i) ring[i] = unsigned(i);
    while (ring.size() > 3) {
        bool clipped = false;
        for (std::size_t i = 0; i < ring.size() && !clipped; ++i) {
            const unsigned a = ring[(i + ring.size() - 1) % ring.size()], b = ring[i], c = ring[(i + 1) % ring.size()];
            if (cross(p[a], p[b], p[c]) <= 0.0) continue; // reflex or flat: not an ear
            bool inside = false;
            for (unsigned q : ring) {
                if (q == a || q == b || q == c) continue;
                if (cross(p[a], p[b], p[q]) >= 0.0 && cross(p[b], p[c], p[q]) >= 0.0 && cross(p[c], p[a], p[q]) >= 0.0) {
                    inside = true;
                    break;
                }
            }
            if (inside) continue;
            out.insert(out.end(), {a, b, c});
            ring.erase(ring.begin() + std::ptrdiff_t(i));
            clipped = true;
        }
        if (!clipped) { // no ear (self-intersecting or all collinear): fan the rest
            for (std::size_t i = 1; i + 1 < ring.size(); ++i) out.insert(out.end(), {ring[0], ring[i], ring[i + 1]});
            return out;
        }
    }
    out.insert(out.end(), {ring[0], ring[1], ring[2]});
    return out;
}

Surface surfaceFromNormal(const TexturedTriangle& tri) {
    const glm::dvec3 n = glm::normalize(glm::cross(tri.v[1] - tri.v[0], tri.v[2] - tri.v[0]));
    if (n.z > 0.5) return Surface::Roof;    // within 60° of straight up
    if (n.z < -0.5) return Surface::Ground; // facing down: a base or an overhang's underside
    return Surface::Wall;
}

int textureIndex(CityModel& model, const std::string& path, bool repeat, std::map<std::string, int>& known,
                 std::vector<std::string>& missing, std::string& unreadable) {
    if (const auto it = known.find(path); it != known.end()) return it->second;
    int index = -1;
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) {
        missing.push_back(path);
    } else if (auto in = OIIO::ImageInput::open(path)) {
        // The header only: its pixels are read (and checked) by the atlas build and the renderers' loader.
        index = int(model.textures.size());
        const auto& spec = in->spec();
        model.textures.push_back(CityTexture{path, repeat, spec.nchannels >= 4 ? 4 : 3, spec.width, spec.height});
        in->close();
    } else if (unreadable.empty()) {
        std::string why = OIIO::geterror();
        if (const auto nl = why.find('\n'); nl != std::string::npos) why.resize(nl);
        unreadable = path + ": texture does not read as an image" + (why.empty() ? std::string() : " (" + why + ")");
    }
    known.emplace(path, index);
    return index;
}

} // namespace detail
} // namespace seasonview::city
