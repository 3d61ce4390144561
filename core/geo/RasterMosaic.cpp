#include "RasterMosaic.h"

#include "GdalSupport.h"
#include "WebSource.h"

#include <glm/common.hpp>

#include <algorithm>
#include <cctype>
#include <set>

#include <glob.h>

namespace seasonview {

namespace {

namespace fs = std::filesystem;

bool hasGlobCharacters(const std::string& s) { return s.find_first_of("*?[") != std::string::npos; }

std::string lower(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return s;
}

/// Side files of rasters and other files a folder of tiles holds that are never rasters themselves.
bool isSideFile(const fs::path& p) {
    static const char* kSide[] = {".aux", ".xml", ".prj", ".tfw", ".tifw", ".wld", ".jgw", ".pgw", ".j2w", ".msk",
                                  ".ovr", ".txt", ".md", ".json", ".csv", ".qml", ".sld", ".html", ".dbf", ".cpg",
                                  ".shp", ".shx", ".geojson", ".gpkg", ".zip", ".md5", ".sha256"};
    const std::string ext = lower(p.extension().string());
    for (const char* e : kSide)
        if (ext == e) return true;
    return p.filename().string().front() == '.';
}

/// Every raster in a folder (not recursive), sorted.
Result<std::vector<fs::path>> rastersIn(const fs::path& dir) {
    std::vector<fs::path> files;
    std::error_code ec;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        if (!it->is_regular_file(ec) || isSideFile(it->path())) continue;
        gdal::init();
        gdal::ErrorCapture quiet;
        if (GDALIdentifyDriver(it->path().c_str(), nullptr)) files.push_back(it->path());
    }
    if (ec) return fileError(dir.string(), "cannot list the folder (" + ec.message() + ")");
    if (files.empty()) return fileError(dir.string(), "no rasters in this folder");
    std::sort(files.begin(), files.end());
    return files;
}

Result<std::vector<fs::path>> expand(const SourceList& sources) {
    std::vector<fs::path> files;
    for (const fs::path& item : sources.items) {
        const std::string text = item.string();
        std::error_code ec;
        if (web::isUrl(text)) {
            files.push_back(web::gdalPath(text)); // read by HTTP ranges (WebSource.h)
        } else if (fs::is_directory(item, ec)) {
            auto in = rastersIn(item);
            if (!in) return in.error();
            files.insert(files.end(), in->begin(), in->end());
        } else if (!fs::exists(item, ec) && hasGlobCharacters(text)) {
            glob_t g{};
            const int rc = ::glob(text.c_str(), GLOB_NOSORT, nullptr, &g);
            std::vector<fs::path> matched;
            for (size_t i = 0; rc == 0 && i < g.gl_pathc; ++i)
                if (!isSideFile(g.gl_pathv[i]) && fs::is_regular_file(g.gl_pathv[i], ec)) matched.emplace_back(g.gl_pathv[i]);
            ::globfree(&g);
            if (matched.empty()) return fileError(text, "matches no file");
            std::sort(matched.begin(), matched.end());
            files.insert(files.end(), matched.begin(), matched.end());
        } else {
            files.push_back(item); // a file (or a VRT), checked when opened
        }
    }
    // The same tile named twice (a folder and a glob over it) is read once.
    std::vector<fs::path> unique;
    std::set<fs::path> seen;
    for (const fs::path& f : files) {
        std::error_code ec;
        if (seen.insert(fs::weakly_canonical(fs::absolute(f, ec), ec)).second) unique.push_back(f);
    }
    if (unique.size() > kMaxMosaicTiles)
        return fileError(sources.describe(), std::to_string(unique.size()) + " tiles, over the limit of " +
                                                 std::to_string(kMaxMosaicTiles) + " (build a VRT of them: gdalbuildvrt)");
    return unique;
}

int colourBands(const RasterInfo& i) { return i.channels - (i.alphaBand ? 1 : 0); }

} // namespace

std::string SourceList::describe() const {
    if (items.empty()) return "(none)";
    std::string s = items.front().string();
    if (items.size() > 1) s += " (and " + std::to_string(items.size() - 1) + " more)";
    return s;
}

bool RasterMosaic::hasNodata() const {
    return std::any_of(tiles.begin(), tiles.end(), [](const RasterInfo& t) { return t.nodataKind != NodataKind::None; });
}

const RasterInfo& RasterMosaic::finest() const {
    return *std::min_element(tiles.begin(), tiles.end(), [](const RasterInfo& a, const RasterInfo& b) {
        return a.georef->pixelSize.x * a.georef->pixelSize.y < b.georef->pixelSize.x * b.georef->pixelSize.y;
    });
}

Result<std::string> fileIdentity(const std::filesystem::path& p) {
    if (web::isRemote(p)) return web::identity(web::urlOf(p));
    if (auto service = web::serviceIdentity(p)) return *service; // what it describes, not the run's options
    std::error_code ec;
    if (!fs::is_regular_file(p, ec)) return fileError(p.string(), fs::exists(p, ec) ? "not a file" : "file not found");
    const std::string path = fs::weakly_canonical(fs::absolute(p, ec), ec).string();
    const auto size = fs::file_size(p, ec);
    if (ec) return fileError(p.string(), "cannot read file size (" + ec.message() + ")");
    const auto mtime = fs::last_write_time(p, ec).time_since_epoch().count();
    if (ec) return fileError(p.string(), "cannot read modification time (" + ec.message() + ")");
    return path + "|" + std::to_string(size) + "|" + std::to_string(mtime);
}

Result<RasterMosaic> openMosaic(const SourceList& sources, const std::string& role,
                                const std::optional<Crs>& assumedCrs) {
    if (sources.empty()) return Error{"scene: no " + role + " input given"};
    auto files = expand(sources);
    if (!files) return files.error();
    RasterMosaic m;
    for (const fs::path& f : *files) {
        // A URL: the server asked first, so that an HTTP error is said as such (WebSource.h).
        std::optional<std::string> remoteId;
        if (web::isRemote(f)) {
            auto id = web::identity(web::urlOf(f));
            if (!id) return id.error();
            remoteId = *id;
        }
        auto info = readRasterInfo(f, assumedCrs);
        if (!info) return info.error();
        const std::string name = web::urlOf(f); // a URL as the user gave it
        if (info->geotransformWithoutCrs) return fileError(name, "has no CRS (give one with --crs EPSG:CODE)");
        if (!info->georef)
            return fileError(name, role + " raster has no georeferencing (no GeoTIFF keys, world file or .prj)");
        if (m.tiles.empty()) {
            m.crs = info->georef->crs;
            m.bands = colourBands(*info);
            m.type = info->type;
        } else {
            const RasterInfo& first = m.tiles.front();
            if (colourBands(*info) != m.bands)
                return fileError(name, std::to_string(colourBands(*info)) + " bands but " + first.path.string() +
                                           " has " + std::to_string(m.bands) + " (tiles of one mosaic must agree)");
            if (info->georef->crs != m.crs)
                return fileError(name, "CRS " + info->georef->crs.name() + " but " + first.path.string() + " is in " +
                                           m.crs.name() + " (tiles of one mosaic must share a CRS)");
            if (info->type != m.type)
                return fileError(name, std::string(sampleTypeName(info->type)) + " samples but " + first.path.string() +
                                           " has " + sampleTypeName(m.type) + " (tiles of one mosaic must agree)");
        }
        const Georef& g = *info->georef;
        const glm::dvec2 lo(g.origin.x, g.origin.y - g.pixelSize.y * info->height);
        const glm::dvec2 hi(g.origin.x + g.pixelSize.x * info->width, g.origin.y);
        m.min = m.tiles.empty() ? lo : glm::min(m.min, lo);
        m.max = m.tiles.empty() ? hi : glm::max(m.max, hi);
        auto id = remoteId ? Result<std::string>(*remoteId) : fileIdentity(f);
        if (!id) return id.error();
        m.key += *id + ";";
        m.tiles.push_back(std::move(*info));
    }
    if (assumedCrs) m.key += "assumed " + assumedCrs->identifier();
    return m;
}

} // namespace seasonview
