// The pyramid cache: keys, the manifest, validation, and the build-then-rename around buildPyramidLevels.
#include "ImagePyramid.h"
#include "JsonFile.h"

#include "AtomicFile.h"
#include "StableHash.h"
#include "WebSource.h"
#include "PyramidBuilder.h"

#include <OpenImageIO/imageio.h>
#include <nlohmann/json.hpp>

#include <cassert>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <stdexcept>

#include <unistd.h>

namespace seasonview {

namespace {

namespace fs = std::filesystem;

/// Bumped whenever the level files' content or layout changes: old caches then no longer match any key.
/// 2: RGBA, premultiplied, on the working grid. 3: tiles with Zstandard content checksums. 4: each tile followed by
/// a CRC-32 of its bytes (ZstdTileCheck.h).
constexpr int kPyramidFormatVersion = 4;
constexpr const char* kManifestName = "pyramid.json";

struct SourceId {
    std::string path; // what the pyramid is made from (older versions of it share this)
    std::string key;  // its identity | format version
};

std::string stretchKey(const Stretch& stretch) {
    if (stretch.identity) return "identity";
    std::string key;
    char v[64];
    for (size_t c = 0; c < size_t(stretch.channels) && c < 4; ++c) {
        std::snprintf(v, sizeof v, "%s%.9g:%.9g", c ? "," : "", double(stretch.low[c]), double(stretch.high[c]));
        key += v;
    }
    return key;
}

Result<SourceId> sourceId(const PyramidSource& source) {
    SourceId id;
    id.path = source.name;
    id.key = source.identity + "|v" + std::to_string(kPyramidFormatVersion);
    return id;
}

} // namespace

Result<PyramidSource> imagerySource(const ImageryLayer& layer) {
    PyramidSource s;
    const RasterMosaic& m = layer.source;
    const WorkingGrid grid = layer.grid();
    // The name finds older versions of the same pyramid (their files changed) to remove: a file, or a mosaic warped
    // onto one grid (the same files on another grid are another pyramid, kept).
    const std::string first = fs::weakly_canonical(fs::absolute(m.tiles.front().path)).string();
    s.name = layer.direct ? first
                          : std::to_string(m.tiles.size()) + " file(s) from " + first + " on " + grid.key();
    // The identity: the files as they are now (a file changed since the scene was loaded is a new pyramid).
    std::string files;
    for (const RasterInfo& t : m.tiles) {
        auto id = fileIdentity(t.path);
        if (!id) return id.error();
        files += *id + ";";
    }
    s.identity = files + "|" + m.key + "|" + stretchKey(layer.stretch) + "|" + grid.key() + "|" +
                 (layer.direct ? "direct" : std::string("warp ") + resamplingName(layer.resampling));
    s.width = grid.width;
    s.height = grid.height;
    s.format = TexelFormat::Rgba8;
    s.build = [&layer](const fs::path& folder, int tileSize,
                        const ProgressFn& progress) -> Result<std::vector<PyramidLevel>> {
        auto levels = buildPyramidLevels(layer, folder, tileSize, progress);
        // A tile service's tile failed: name its URL and status (GDAL's words leave them out).
        if (!levels && layer.source.tiles.size() == 1) {
            const RasterInfo& service = layer.source.tiles.front();
            if (auto tile = web::tileFailure(service.path, levels.message())) return *tile;
            // A tile that did not decode (a body cut short): GDAL names the rows of the description it was reading.
            long long r0 = -1, r1 = -1;
            const std::string& said = levels.message();
            if (const auto at = said.find(" in rows ");
                at != std::string::npos && std::sscanf(said.c_str() + at, " in rows %lld-%lld", &r0, &r1) == 2)
                if (auto tile = web::tileFailureIn(service.path, 0, r0, service.width, r1)) return *tile;
        }
        return levels;
    };
    return s;
}

namespace {

fs::path pyramidsDir(const fs::path& cacheDir) { return cacheDir / "pyramids"; }

fs::path folderFor(const fs::path& cacheDir, const SourceId& id) {
    char name[32];
    std::snprintf(name, sizeof name, "%016llx", static_cast<unsigned long long>(stableHash64(id.key)));
    return pyramidsDir(cacheDir) / name;
}

std::optional<nlohmann::json> readManifest(const fs::path& folder) {
    std::error_code ec;
    if (!fs::exists(folder / kManifestName, ec)) return std::nullopt;
    auto j = readJsonFile(folder / kManifestName, "pyramid index");
    if (!j || !j->is_object()) return nlohmann::json(nullptr);
    return std::move(*j);
}

/// A valid pyramid in `folder` for `id`, or the reason why there is none ("not prepared yet", "source changed",
/// "cache corrupt: ...").
struct Validation {
    std::optional<ImagePyramid> pyramid;
    std::string reason;
};

Validation validate(const fs::path& folder, const SourceId& id, const PyramidSource& source) {
    Validation v;
    std::error_code ec;
    if (!fs::exists(folder, ec)) {
        v.reason = "not prepared yet";
        return v;
    }
    const auto manifest = readManifest(folder);
    if (!manifest) {
        v.reason = "cache corrupt: pyramid.json missing";
        return v;
    }
    const nlohmann::json& j = *manifest;
    ImagePyramid p;
    p.folder = folder;
    p.format = source.format;
    std::vector<std::uintmax_t> bytes;
    try {
        if (!j.is_object()) throw std::runtime_error("not an object");
        const auto number = [](const nlohmann::json& o, const char* key) {
            const auto n = jsonMember<int>(o, key);
            if (!n) throw std::runtime_error(key);
            return *n;
        };
        p.sourceKey = j.at("source_key").get<std::string>();
        p.tileSize = number(j, "tile_size");
        for (const auto& l : j.at("levels")) {
            p.levels.push_back({folder / l.at("file").get<std::string>(), number(l, "width"), number(l, "height")});
            const auto b = jsonMember<std::uintmax_t>(l, "bytes");
            if (!b) throw std::runtime_error("bytes");
            bytes.push_back(*b);
        }
    } catch (const std::exception&) {
        v.reason = "cache corrupt: pyramid.json unreadable";
        return v;
    }
    if (p.sourceKey != id.key) {
        v.reason = "source changed";
        return v;
    }
    if (p.tileSize < 16 || p.tileSize > 4096 || p.tileSize % 16 != 0) { // 4096² RGBA: 64 MiB, a quarter of the tile cache
        v.reason = "cache corrupt: pyramid.json has tile size " + std::to_string(p.tileSize);
        return v;
    }
    const auto sizes = pyramidLevelSizes(source.width, source.height);
    if (p.levels.size() != sizes.size()) {
        v.reason = "cache corrupt: pyramid.json lists " + std::to_string(p.levels.size()) + " levels, expected " +
                   std::to_string(sizes.size());
        return v;
    }
    for (size_t k = 0; k < sizes.size(); ++k) {
        const PyramidLevel& l = p.levels[k];
        if (l.file.filename() != pyramidLevelFileName(int(k)) || l.width != sizes[k].first ||
            l.height != sizes[k].second) {
            v.reason = "cache corrupt: pyramid.json level " + std::to_string(k) + " is wrong";
            return v;
        }
        if (std::string e = checkLevelFile(l.file, bytes[k], l.width, l.height, p.tileSize, p.format);
            !e.empty()) {
            v.reason = "cache corrupt: " + e;
            return v;
        }
    }
    v.pyramid = std::move(p);
    return v;
}

/// Other folders in the cache that belong to the same source file (older versions of it).
std::vector<fs::path> siblingsOf(const fs::path& cacheDir, const fs::path& folder, const SourceId& id) {
    std::vector<fs::path> found;
    std::error_code ec;
    for (fs::directory_iterator it(pyramidsDir(cacheDir), ec), end; !ec && it != end; it.increment(ec)) {
        const fs::path& p = it->path();
        if (p == folder || p.filename().string().find(".partial-") != std::string::npos) continue;
        const auto m = readManifest(p);
        if (m && m->is_object() && m->value("source_path", std::string()) == id.path) found.push_back(p);
    }
    return found;
}

/// Removes older pyramids of the same source and partial folders left by processes that no longer run.
void removeStale(const fs::path& cacheDir, const fs::path& folder, const SourceId& id) {
    std::error_code ec;
    for (const fs::path& p : siblingsOf(cacheDir, folder, id)) fs::remove_all(p, ec);
    removeStaleTemporaries(pyramidsDir(cacheDir));
}

Status writeManifest(const fs::path& folder, const SourceId& id, int tileSize, const std::vector<PyramidLevel>& levels) {
    nlohmann::json j = {{"format", "seasonview image pyramid"},
                        {"version", kPyramidFormatVersion},
                        {"source_path", id.path},
                        {"source_key", id.key},
                        {"tile_size", tileSize},
                        {"levels", nlohmann::json::array()}};
    for (const PyramidLevel& l : levels) {
        std::error_code ec;
        const std::uintmax_t bytes = fs::file_size(l.file, ec);
        if (ec) return fileError(l.file.string(), "cannot read back the written file (" + ec.message() + ")");
        j["levels"].push_back(
            {{"file", l.file.filename().string()}, {"width", l.width}, {"height", l.height}, {"bytes", bytes}});
    }
    std::string err;
    if (!writeTextAtomic(folder / kManifestName, j.dump(2) + "\n", err))
        return fileError((folder / kManifestName).string(), err);
    return Ok{};
}

} // namespace

std::string checkLevelFile(const fs::path& file, std::uintmax_t bytes, int width, int height, int tileSize,
                           TexelFormat format) {
    const std::string name = file.filename().string();
    std::error_code ec;
    if (!fs::is_regular_file(file, ec)) return name + " missing";
    const std::uintmax_t actual = fs::file_size(file, ec);
    if (ec || actual != bytes)
        return name + " has " + std::to_string(actual) + " bytes, pyramid.json says " + std::to_string(bytes);
    auto in = OIIO::ImageInput::open(file.string());
    if (!in) {
        (void)OIIO::geterror(); // consume the message so OpenImageIO does not print it at exit
        return name + " unreadable";
    }
    const OIIO::ImageSpec& s = in->spec();
    const int channels = texelChannels(format);
    const OIIO::TypeDesc type = format == TexelFormat::R32F ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8;
    if (s.width != width || s.height != height || s.nchannels != channels || s.format != type ||
        s.tile_width != tileSize || s.tile_height != tileSize)
        return name + " is " + std::to_string(s.width) + "x" + std::to_string(s.height) + "x" +
               std::to_string(s.nchannels) + " " + s.format.c_str() + " in " + std::to_string(s.tile_width) + "x" +
               std::to_string(s.tile_height) + " tiles, expected " + std::to_string(width) + "x" +
               std::to_string(height) + "x" + std::to_string(channels) + " " + type.c_str() + " in " +
               std::to_string(tileSize) + "x" + std::to_string(tileSize) + " tiles";
    return {};
}

void invalidatePyramid(const ImagePyramid& pyramid) {
    std::error_code ec;
    fs::remove(pyramid.folder / kManifestName, ec);
}

bool invalidateDamagedPyramid(const std::string& message, const std::filesystem::path& cacheDir) {
    std::error_code ec;
    const std::string dir = fs::weakly_canonical(fs::absolute(pyramidsDir(cacheDir), ec), ec).string() + "/";
    const std::string named = fs::weakly_canonical(fs::absolute(message.substr(0, message.find(": ")), ec), ec).string();
    if (named.rfind(dir, 0) != 0) return false;
    const std::string folder = named.substr(0, named.find('/', dir.size()));
    if (!fs::exists(fs::path(folder) / kManifestName, ec)) return false;
    fs::remove(fs::path(folder) / kManifestName, ec);
    return !ec;
}

Result<ImagePyramid> openPyramid(const ImageryLayer& layer, const std::filesystem::path& cacheDir) {
    auto source = imagerySource(layer);
    if (!source) return source.error();
    return openPyramid(*source, cacheDir);
}

Result<PrepareReport> preparePyramid(const ImageryLayer& layer, const PrepareOptions& options) {
    auto source = imagerySource(layer);
    if (!source) return source.error();
    return preparePyramid(*source, options);
}

Result<ImagePyramid> openPyramid(const PyramidSource& layer, const std::filesystem::path& cacheDir) {
    auto id = sourceId(layer);
    if (!id) return id.error();
    const fs::path folder = folderFor(cacheDir, *id);
    Validation v = validate(folder, *id, layer);
    if (v.pyramid) return std::move(*v.pyramid);
    if (v.reason == "not prepared yet" && !siblingsOf(cacheDir, folder, *id).empty()) v.reason = "source changed";
    return fileError(folder.string(), "no valid pyramid for " + layer.name + ": " + v.reason +
                                          " (run seasonview prepare)");
}

Result<PrepareReport> preparePyramid(const PyramidSource& layer, const PrepareOptions& options) {
    assert(options.tileSize >= 16 && options.tileSize % 16 == 0 &&
           "preparePyramid(): tile size must be a positive multiple of 16 (TIFF tiles)");
    const auto t0 = std::chrono::steady_clock::now();
    auto seconds = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
    auto id = sourceId(layer);
    if (!id) return id.error();
    const fs::path folder = folderFor(options.cacheDir, *id);

    PrepareReport report;
    if (options.force) {
        report.reason = "forced";
    } else {
        Validation v = validate(folder, *id, layer);
        if (v.pyramid && v.pyramid->tileSize == options.tileSize) {
            report.pyramid = std::move(*v.pyramid);
            report.seconds = seconds();
            return report;
        }
        report.reason = v.pyramid ? "tile size changed" : v.reason;
        if (report.reason == "not prepared yet" && !siblingsOf(options.cacheDir, folder, *id).empty())
            report.reason = "source changed";
    }

    const fs::path dir = pyramidsDir(options.cacheDir);
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) return fileError(dir.string(), "cannot create the cache folder (" + ec.message() + ")");
    const fs::path tmp = folder.string() + ".partial-" + std::to_string(::getpid());
    fs::remove_all(tmp, ec);
    if (!fs::create_directory(tmp, ec) || ec)
        return fileError(dir.string(), "cannot write to the cache folder (" + ec.message() + ")");
    auto fail = [&](const Error& e) {
        std::error_code ignored;
        fs::remove_all(tmp, ignored);
        return e;
    };

    auto levels = layer.build(tmp, options.tileSize, options.progress);
    if (!levels) return fail(levels.error());
    if (auto st = writeManifest(tmp, *id, options.tileSize, *levels); !st) return fail(st.error());
    // rename() cannot replace a non-empty folder: remove the old pyramid first. Between the two steps there is no
    // pyramid under the final name, never a half one.
    fs::remove_all(folder, ec);
    if (ec) return fail(fileError(folder.string(), "cannot remove the old pyramid (" + ec.message() + ")"));
    fs::rename(tmp, folder, ec);
    if (ec) return fail(fileError(folder.string(), "cannot move the pyramid into place (" + ec.message() + ")"));
    removeStale(options.cacheDir, folder, *id);

    report.built = true;
    report.pyramid.folder = folder;
    report.pyramid.sourceKey = id->key;
    report.pyramid.tileSize = options.tileSize;
    report.pyramid.format = layer.format;
    report.pyramid.levels = std::move(*levels);
    for (PyramidLevel& l : report.pyramid.levels) l.file = folder / l.file.filename();
    report.seconds = seconds();
    return report;
}

} // namespace seasonview
