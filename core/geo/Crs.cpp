#include "Crs.h"

#include "GdalSupport.h"

#include <GeographicLib/Geodesic.hpp>
#include <ogr_spatialref.h>

#include <algorithm>
#include <cassert>
#include <cstdlib>
#include <cmath>
#include <deque>
#include <limits>
#include <mutex>
#include <unordered_map>

namespace seasonview {

namespace {

/// One distinct CRS of this process. Entries are never removed, so ids stay valid.
struct Entry {
    std::string wkt;       // WKT2 2019
    std::string name;
    int epsg = 0;
    bool geographic = false;
    double metresPerUnit = 1.0;
    bool northFirst = false;
    OGRSpatialReference srs; // used under the registry's lock only (IsSame, copies for transformations)
};

class Registry {
public:
    static Registry& get() {
        static Registry r;
        return r;
    }

    /// The id of `srs` (added when no entry is the same CRS).
    int intern(OGRSpatialReference& srs) {
        srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
        char* text = nullptr;
        const char* options[] = {"FORMAT=WKT2_2019", nullptr};
        srs.exportToWkt(&text, options);
        std::string wkt = text ? text : "";
        CPLFree(text);
        std::lock_guard lock(m_mutex);
        for (size_t i = 0; i < m_entries.size(); ++i)
            if (m_entries[i].wkt == wkt) return int(i);
        const char* same[] = {"IGNORE_DATA_AXIS_TO_SRS_AXIS_MAPPING=YES", "CRITERION=EQUIVALENT", nullptr};
        for (size_t i = 0; i < m_entries.size(); ++i)
            if (m_entries[i].srs.IsSame(&srs, same)) return int(i);
        Entry& e = m_entries.emplace_back();
        e.wkt = std::move(wkt);
        e.srs = srs;
        e.geographic = srs.IsGeographic() != 0;
        e.name = srs.GetName() ? srs.GetName() : "unnamed CRS";
        e.epsg = identifyEpsg(srs);
        e.northFirst = srs.EPSGTreatsAsLatLong() || srs.EPSGTreatsAsNorthingEasting();
        // Geographic: metres per unit of longitude on the equator (GetAngularUnits is radians per unit).
        e.metresPerUnit = e.geographic ? 6378137.0 * srs.GetAngularUnits() : srs.GetLinearUnits();
        return int(m_entries.size() - 1);
    }

    /// A copy of an entry's fields other than the spatial reference (cheap enough for the rare callers).
    template <class Fn> auto with(int id, Fn&& fn) {
        std::lock_guard lock(m_mutex);
        assert(id >= 0 && size_t(id) < m_entries.size() && "Crs: unknown id");
        return fn(m_entries[size_t(id)]);
    }

    const std::string& wkt(int id) {
        std::lock_guard lock(m_mutex);
        return m_entries[size_t(id)].wkt; // entries are never moved (deque) nor changed
    }

private:
    Registry() {
        gdal::init();
        OGRSpatialReference wgs84;
        wgs84.importFromEPSG(4326);
        intern(wgs84); // id 0: the default Crs
    }

    static int identifyEpsg(OGRSpatialReference& srs) {
        const char* authority = srs.GetAuthorityName(nullptr);
        const char* code = srs.GetAuthorityCode(nullptr);
        if (authority && code && EQUAL(authority, "EPSG")) return std::atoi(code);
        // A CRS given as WKT without its authority (GeoTIFF keys often are): PROJ's best full match.
        int matches = 0;
        int* confidence = nullptr;
        OGRSpatialReferenceH* found = srs.FindMatches(nullptr, &matches, &confidence);
        int epsg = 0;
        for (int i = 0; i < matches && epsg == 0; ++i) {
            auto* m = OGRSpatialReference::FromHandle(found[i]);
            const char* a = m->GetAuthorityName(nullptr);
            const char* c = m->GetAuthorityCode(nullptr);
            if (confidence[i] >= 100 && a && c && EQUAL(a, "EPSG")) epsg = std::atoi(c);
        }
        OSRFreeSRSArray(found);
        CPLFree(confidence);
        return epsg;
    }

    std::mutex m_mutex;
    std::deque<Entry> m_entries;
};

/// The transformations this thread has made (OGRCoordinateTransformation is not thread-safe), by (from, to) id.
OGRCoordinateTransformation* transformation(int from, int to) {
    thread_local std::unordered_map<std::uint64_t, std::unique_ptr<OGRCoordinateTransformation>> cache;
    const std::uint64_t key = (std::uint64_t(std::uint32_t(from)) << 32) | std::uint32_t(to);
    auto it = cache.find(key);
    if (it != cache.end()) return it->second.get();
    OGRSpatialReference a = Registry::get().with(from, [](const Entry& e) { return e.srs; });
    OGRSpatialReference b = Registry::get().with(to, [](const Entry& e) { return e.srs; });
    a.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    b.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    gdal::ErrorCapture quiet; // a missing transformation is reported as NaN points, not printed
    std::unique_ptr<OGRCoordinateTransformation> t(OGRCreateCoordinateTransformation(&a, &b));
    return cache.emplace(key, std::move(t)).first->second.get();
}

} // namespace

Crs::Crs() : m_id(0) { (void)Registry::get(); }

Result<Crs> Crs::fromUserInput(std::string_view text) {
    gdal::init();
    OGRSpatialReference srs;
    gdal::ErrorCapture quiet;
    const std::string s(text);
    // Compound CRSs (a horizontal one plus heights) are common in CityGML: the horizontal part is what is used.
    if (srs.SetFromUserInput(s.c_str(), OGRSpatialReference::SET_FROM_USER_INPUT_LIMITATIONS) != OGRERR_NONE) {
        const std::string why = firstLine(quiet.message());
        return Error{"unknown CRS '" + s.substr(0, 80) + "'" + (why.empty() ? "" : " (" + why + ")")};
    }
    if (srs.IsCompound()) srs.StripVertical();
    if (!srs.IsProjected() && !srs.IsGeographic())
        return Error{"CRS '" + s.substr(0, 80) + "' is neither projected nor geographic"};
    return Crs(Registry::get().intern(srs));
}

Result<Crs> Crs::fromEpsg(int code) {
    gdal::init();
    OGRSpatialReference srs;
    gdal::ErrorCapture quiet;
    if (srs.importFromEPSG(code) != OGRERR_NONE) return Error{"unknown CRS EPSG:" + std::to_string(code)};
    if (srs.IsCompound()) srs.StripVertical();
    if (!srs.IsProjected() && !srs.IsGeographic())
        return Error{"EPSG:" + std::to_string(code) + " is neither a projected nor a geographic CRS"};
    return Crs(Registry::get().intern(srs));
}

Result<Crs> Crs::fromWkt(const std::string& wkt) {
    gdal::init();
    OGRSpatialReference srs;
    gdal::ErrorCapture quiet;
    if (srs.importFromWkt(wkt.c_str()) != OGRERR_NONE) return Error{"unreadable CRS definition"};
    if (srs.IsCompound()) srs.StripVertical();
    if (!srs.IsProjected() && !srs.IsGeographic()) return Error{"CRS is neither projected nor geographic"};
    return Crs(Registry::get().intern(srs));
}

Crs Crs::utm(int zone, bool north) {
    assert(zone >= 1 && zone <= 60 && "Crs::utm(): zone out of range");
    auto c = fromEpsg((north ? 32600 : 32700) + zone);
    assert(c.ok() && "Crs::utm(): PROJ's database has no WGS 84 UTM zone");
    return *c;
}

Crs Crs::utmAt(double lon, double lat) {
    const int zone = std::clamp(int(std::floor((lon + 180.0) / 6.0)) + 1, 1, 60);
    return utm(zone, lat >= 0.0);
}

bool Crs::isGeographic() const {
    return Registry::get().with(m_id, [](const Entry& e) { return e.geographic; });
}
int Crs::epsg() const {
    return Registry::get().with(m_id, [](const Entry& e) { return e.epsg; });
}
std::string Crs::name() const {
    return Registry::get().with(m_id, [](const Entry& e) {
        return e.epsg ? "EPSG:" + std::to_string(e.epsg) + " (" + e.name + ")" : e.name;
    });
}
std::string Crs::identifier() const {
    return Registry::get().with(m_id, [](const Entry& e) { return e.epsg ? "EPSG:" + std::to_string(e.epsg) : e.wkt; });
}
const std::string& Crs::wkt() const { return Registry::get().wkt(m_id); }
std::string Crs::esriWkt() const {
    OGRSpatialReference srs = Registry::get().with(m_id, [](const Entry& e) { return e.srs; });
    char* text = nullptr;
    const char* options[] = {"FORMAT=WKT1_ESRI", nullptr};
    srs.exportToWkt(&text, options);
    std::string s = text ? text : "";
    CPLFree(text);
    return s;
}
bool Crs::northFirst() const {
    return Registry::get().with(m_id, [](const Entry& e) { return e.northFirst; });
}
double Crs::metresPerUnit() const {
    return Registry::get().with(m_id, [](const Entry& e) { return e.metresPerUnit; });
}

glm::dvec2 convert(const Crs& from, const Crs& to, glm::dvec2 p) {
    if (from == to) return p;
    convert(from, to, std::span<glm::dvec2>(&p, 1));
    return p;
}

void convert(const Crs& from, const Crs& to, std::span<glm::dvec2> points) {
    if (from == to || points.empty()) return;
    OGRCoordinateTransformation* t = transformation(from.id(), to.id());
    constexpr double nan = std::numeric_limits<double>::quiet_NaN();
    if (!t) {
        for (glm::dvec2& p : points) p = glm::dvec2(nan);
        return;
    }
    thread_local std::vector<double> x, y;
    thread_local std::vector<int> ok;
    x.resize(points.size());
    y.resize(points.size());
    ok.resize(points.size());
    for (size_t i = 0; i < points.size(); ++i) {
        x[i] = points[i].x;
        y[i] = points[i].y;
    }
    gdal::ErrorCapture quiet;
    t->Transform(int(points.size()), x.data(), y.data(), nullptr, ok.data());
    for (size_t i = 0; i < points.size(); ++i) points[i] = ok[i] ? glm::dvec2(x[i], y[i]) : glm::dvec2(nan);
}

glm::dvec2 pointScale(const Crs& crs, glm::dvec2 p) {
    if (crs.isGeographic()) return glm::dvec2(1.0);
    const Crs geo = Crs::geographic();
    glm::dvec2 q[4] = {p - glm::dvec2(0.5, 0.0), p + glm::dvec2(0.5, 0.0), p - glm::dvec2(0.0, 0.5),
                       p + glm::dvec2(0.0, 0.5)};
    convert(crs, geo, std::span<glm::dvec2>(q, 4));
    const GeographicLib::Geodesic& g = GeographicLib::Geodesic::WGS84();
    double east = 0.0, north = 0.0;
    g.Inverse(q[0].y, q[0].x, q[1].y, q[1].x, east);
    g.Inverse(q[2].y, q[2].x, q[3].y, q[3].x, north);
    const double unit = crs.metresPerUnit();
    return {unit / east, unit / north};
}

} // namespace seasonview
