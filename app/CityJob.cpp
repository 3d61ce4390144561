#include "CityJob.h"

#include "AtlasTreeBuild.h"
#include "BlockMap.h"
#include "CityModel.h"
#include "Commands.h"
#include "StableHash.h"

#include <chrono>
#include <cstdio>

namespace seasonview::app {


Result<std::filesystem::path> prepareCityTree(const Scene& scene, const std::filesystem::path& cacheDir,
                                              const std::string& explicitTree) {
    if (!explicitTree.empty()) return std::filesystem::path(explicitTree);
    const std::filesystem::path model = scene.sources.buildings;
    if (model.empty())
        return Error{(scene.sources.manifest.empty() ? std::string("the scene") : scene.sources.manifest.string()) +
                     ": no 'buildings' model for --city (or give --city-tree)"};
    std::error_code ec;
    const auto abs = std::filesystem::absolute(model, ec);
    const auto size = std::filesystem::file_size(model, ec);
    if (ec) return fileError(model.string(), "no such city model");
    const auto mtime = std::filesystem::last_write_time(model, ec).time_since_epoch().count();
    std::optional<Crs> modelCrs;
    if (!scene.sources.buildingsCrs.empty()) {
        auto crs = city::crsFromSrsName(scene.sources.buildingsCrs);
        if (!crs) return Error{"--city-crs: " + crs.message()};
        modelCrs = *crs;
    }
    const std::string key = abs.string() + "|" + std::to_string(size) + "|" + std::to_string(mtime) + "|v" +
                            std::to_string(city::AtlasTreeFile::kVersion) + "|defaults1" +
                            (modelCrs ? "|" + modelCrs->identifier() : std::string());
    char name[64];
    std::snprintf(name, sizeof name, "%016llx.svat", (unsigned long long)stableHash64(key));
    const auto dir = cacheDir / "atlas";
    const auto tree = dir / name;
    if (std::filesystem::exists(tree, ec) && city::AtlasTreeFile::open(tree.string())) return tree;
    std::filesystem::create_directories(dir, ec);
    if (ec) return fileError(dir.string(), "cannot create cache folder: " + ec.message());

    const auto t0 = std::chrono::steady_clock::now();
    city::CityLoadOptions options;
    // An OBJ that comes with a scene and names no CRS is in the scene's frame (seasonview synth's city.obj), unless
    // --city-crs / buildings_crs says which CRS its coordinates are in.
    options.localFrame = !modelCrs;
    options.crs = modelCrs;
    auto m = city::loadCityModel(model.string(), options);
    if (!m) return m.error();
    city::AtlasBuildSettings bs;
    bs.progress = terminalProgress("atlas tree");
    auto r = city::buildAtlasTree(*m, bs, tree.string());
    // The model's warnings after the build: a failure is one line, with the first warning as its likely cause.
    if (!r) return Error{m->failureWithWarnings(r.error().message)};
    for (const auto& w : m->warnings) std::fprintf(stderr, "seasonview: warning: %s\n", w.c_str());
    std::printf("city: built the atlas tree of %s in %.1f s: %zu nodes, %.1f MB, %s\n", model.string().c_str(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), r->nodes,
                double(r->fileBytes) / 1e6, tree.string().c_str());
    std::fflush(stdout);
    return tree;
}

Status prepareCityBlockMaps(const Scene& scene, const std::filesystem::path& tree, const std::filesystem::path& cacheDir,
                            city::CitySettings& settings) {
    if (settings.mode != city::CityMode::BlockMap || !settings.blockMaps.empty()) return Ok{};
    auto file = city::AtlasTreeFile::open(tree.string());
    if (!file) return file.error();
    city::placeInSceneFrame(scene, *file, settings.placeOnTerrain);
    const city::CityModel model = city::modelOfTree(*file);
    // The key: the placed triangles, their textures and coordinates, the texture files, the build settings.
    std::string key = "blockmaps|v5|64|32|1", chunk;
    auto flush = [&] {
        key += "|" + std::to_string(stableHash64(chunk));
        chunk.clear();
    };
    for (const auto& t : model.triangles) {
        chunk.append(reinterpret_cast<const char*>(t.v.data()), sizeof t.v);
        chunk.append(reinterpret_cast<const char*>(t.t.data()), sizeof t.t);
        chunk.append(reinterpret_cast<const char*>(&t.texture), sizeof t.texture);
        if (chunk.size() > (1u << 20)) flush();
    }
    flush();
    // Wall colours are read through the tree's atlases: theirs too.
    for (const auto& tr : file->trees)
        for (const auto& n : tr.nodes) chunk.append(reinterpret_cast<const char*>(&n.atlasCrc), sizeof n.atlasCrc);
    flush();
    for (const auto& t : model.textures) {
        std::error_code ec;
        const auto mtime = std::filesystem::last_write_time(t.path, ec).time_since_epoch().count();
        key += "|" + t.path + "|" + std::to_string(ec ? 0 : mtime);
    }
    char name[64];
    std::snprintf(name, sizeof name, "%016llx.svbm", (unsigned long long)stableHash64(key));
    const auto dir = cacheDir / "atlas";
    const auto path = dir / name;
    std::error_code ec;
    if (std::filesystem::exists(path, ec) && city::BlockMapFile::open(path)) {
        settings.blockMaps = path.string();
        return Ok{};
    }
    std::filesystem::create_directories(dir, ec);
    if (ec) return fileError(dir.string(), "cannot create cache folder: " + ec.message());
    const auto t0 = std::chrono::steady_clock::now();
    city::CityBlockMapSettings bs;
    bs.progress = terminalProgress("BlockMaps");
    bs.atlasTree = &*file;
    auto r = city::buildCityBlockMaps(model, bs, path);
    if (!r) return r.error();
    std::printf("city: built %zu BlockMaps of %s in %.1f s: %.1f MB, %s\n", r->maps, tree.string().c_str(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), double(r->fileBytes) / 1e6,
                path.string().c_str());
    std::fflush(stdout);
    settings.blockMaps = path.string();
    return Ok{};
}

bool removeDamagedCityTree(const std::string& message, const std::filesystem::path& cacheDir) {
    namespace fs = std::filesystem;
    std::error_code ec;
    const std::string dir = fs::weakly_canonical(fs::absolute(cacheDir / "atlas", ec), ec).string() + "/";
    const fs::path named = fs::weakly_canonical(fs::absolute(message.substr(0, message.find(": ")), ec), ec);
    if (named.string().rfind(dir, 0) != 0 || (named.extension() != ".svat" && named.extension() != ".svbm"))
        return false;
    return fs::remove(named, ec) && !ec;
}

} // namespace seasonview::app
