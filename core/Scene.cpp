#include "Scene.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

namespace seasonview {

namespace {

using nlohmann::json;

std::string lineColumn(const std::string& text, size_t byte) {
    size_t line = 1, col = 1;
    for (size_t i = 0; i < byte && i < text.size(); ++i) {
        if (text[i] == '\n') {
            ++line;
            col = 1;
        } else {
            ++col;
        }
    }
    return "line " + std::to_string(line) + ", column " + std::to_string(col);
}

} // namespace

Result<SceneSources> parseManifest(const std::filesystem::path& manifest) {
    const std::string name = manifest.string();
    std::error_code ec;
    if (!std::filesystem::exists(manifest, ec)) return fileError(name, "file not found");
    if (std::filesystem::is_directory(manifest, ec))
        return fileError(name, "is a directory; give the scene's manifest (scene.json)");
    std::ifstream f(manifest, std::ios::binary);
    if (!f) return fileError(name, "cannot read file");
    std::stringstream buf;
    buf << f.rdbuf();
    const std::string text = buf.str();
    json j;
    try {
        j = json::parse(text);
    } catch (const json::parse_error& e) {
        return fileError(name, "malformed JSON manifest (" + lineColumn(text, e.byte ? e.byte - 1 : 0) + ")");
    }
    if (!j.is_object()) return fileError(name, "manifest must be a JSON object");

    SceneSources s;
    s.manifest = manifest;
    const std::filesystem::path base = manifest.parent_path();
    auto path = [&](const json& obj, const char* key, bool required, std::filesystem::path& out,
                    const std::string& prefix) -> Status {
        auto it = obj.find(key);
        if (it == obj.end() || it->is_null()) {
            if (required) return fileError(name, "missing required key '" + prefix + key + "'");
            return Ok{};
        }
        if (!it->is_string() || it->get<std::string>().empty())
            return fileError(name, "'" + prefix + key + "' must be a non-empty string (a path relative to the manifest)");
        std::filesystem::path p = it->get<std::string>();
        out = p.is_absolute() ? p : base / p;
        return Ok{};
    };
    static const char* known[] = {"name", "leafon", "leafoff", "elevation", "buildings", "truth", "parameters",
                                  "generator", "description"};
    for (auto& [k, v] : j.items()) {
        (void)v;
        if (std::find_if(std::begin(known), std::end(known), [&](const char* n) { return k == n; }) == std::end(known))
            s.warnings.push_back(name + ": unknown key '" + k + "' ignored");
    }
    if (auto it = j.find("name"); it != j.end()) {
        if (!it->is_string()) return fileError(name, "'name' must be a string");
        s.name = it->get<std::string>();
    }
    if (auto st = path(j, "leafon", true, s.leafon, ""); !st) return st.error();
    if (auto st = path(j, "leafoff", true, s.leafoff, ""); !st) return st.error();
    if (auto st = path(j, "elevation", false, s.elevation, ""); !st) return st.error();
    if (auto st = path(j, "buildings", false, s.buildings, ""); !st) return st.error();
    if (auto it = j.find("truth"); it != j.end() && !it->is_null()) {
        if (!it->is_object()) return fileError(name, "'truth' must be an object {deciduous, conifer, trees}");
        if (auto st = path(*it, "deciduous", false, s.truthDeciduous, "truth."); !st) return st.error();
        if (auto st = path(*it, "conifer", false, s.truthConifer, "truth."); !st) return st.error();
        if (auto st = path(*it, "trees", false, s.truthTrees, "truth."); !st) return st.error();
    }
    if (auto it = j.find("parameters"); it != j.end() && !it->is_null()) {
        if (!it->is_object()) return fileError(name, "'parameters' must be an object");
        if (auto t = it->find("tree_height_m"); t != it->end()) {
            if (!t->is_number() || !(t->get<double>() > 0.0) || !std::isfinite(t->get<double>()))
                return fileError(name, "'parameters.tree_height_m' must be a positive number of metres");
            s.treeHeightM = t->get<double>();
        }
    }
    if (s.name.empty()) s.name = manifest.parent_path().filename().string();
    return s;
}

namespace {

Result<ImageryLayer> openImagery(const std::filesystem::path& path, const char* role,
                                 const std::filesystem::path& cacheDir) {
    auto info = readRasterInfo(path);
    if (!info) return info.error();
    if (info->geotransformWithoutCrs) return fileError(path.string(), "has no CRS (give one with --crs EPSG:CODE)");
    if (!info->georef)
        return fileError(path.string(), std::string(role) +
                                            " image has no georeferencing (no GeoTIFF keys, world file or .prj)");
    if (info->channels < 3)
        return fileError(path.string(), std::string(role) + " image needs RGB bands, has " +
                                            std::to_string(info->channels));
    if (info->type != SampleType::U8 && info->type != SampleType::U16)
        return fileError(path.string(), std::string(role) + " image must be 8- or 16-bit, is " +
                                            sampleTypeName(info->type));
    auto stretch = stretchFor(*info, cacheDir);
    if (!stretch) return stretch.error();
    return ImageryLayer{std::move(*info), *stretch};
}

} // namespace

Result<Scene> loadScene(const SceneSources& sources, const std::filesystem::path& cacheDir) {
    Scene scene;
    scene.sources = sources;
    if (sources.leafon.empty()) return Error{"scene: no leaf-on image given (--leafon or a manifest)"};
    if (sources.leafoff.empty()) return Error{"scene: no leaf-off image given (--leafoff or a manifest)"};
    // Header checks first (cheap), then the expensive stretch.
    auto onInfo = readRasterInfo(sources.leafon);
    if (!onInfo) return onInfo.error();
    auto offInfo = readRasterInfo(sources.leafoff);
    if (!offInfo) return offInfo.error();
    if (onInfo->width != offInfo->width || onInfo->height != offInfo->height)
        return fileError(sources.leafoff.string(),
                         "leaf-off is " + std::to_string(offInfo->width) + "x" + std::to_string(offInfo->height) +
                             " pixels but leaf-on " + sources.leafon.string() + " is " +
                             std::to_string(onInfo->width) + "x" + std::to_string(onInfo->height) +
                             " (seasons must cover the same grid)");
    auto on = openImagery(sources.leafon, "leaf-on", cacheDir);
    if (!on) return on.error();
    auto off = openImagery(sources.leafoff, "leaf-off", cacheDir);
    if (!off) return off.error();
    scene.leafon = std::move(*on);
    scene.leafoff = std::move(*off);

    const Georef& a = *scene.leafon.info.georef;
    const Georef& b = *scene.leafoff.info.georef;
    const int w = scene.leafon.info.width, h = scene.leafon.info.height;
    double worst = 0.0;
    for (glm::dvec2 c : {glm::dvec2(0, 0), glm::dvec2(w, 0), glm::dvec2(0, h), glm::dvec2(w, h)}) {
        const glm::dvec2 pb = convert(b.crs, a.crs, b.pixelToCrs(c));
        const glm::dvec2 d = a.crsToPixel(pb) - c;
        worst = std::max(worst, std::max(std::fabs(d.x), std::fabs(d.y)));
    }
    if (worst > 0.5) {
        char buf[64];
        std::snprintf(buf, sizeof buf, "%.2f", worst);
        return fileError(sources.leafoff.string(), "georeferencing disagrees with leaf-on " + sources.leafon.string() +
                                                       " by " + buf +
                                                       " pixels (seasons must be registered on the same grid)");
    }

    scene.frame = GeoFrame(a.crs, a.pixelToCrs({w * 0.5, h * 0.5}));
    scene.localMin = glm::dvec2(1e300);
    scene.localMax = glm::dvec2(-1e300);
    for (int i = 0; i <= 4; ++i)
        for (int k = 0; k <= 4; ++k) {
            const glm::dvec3 p = scene.frame.toLocal(a.crs, a.pixelToCrs({w * i / 4.0, h * k / 4.0}));
            scene.localMin = glm::min(scene.localMin, glm::dvec2(p));
            scene.localMax = glm::max(scene.localMax, glm::dvec2(p));
        }
    {
        const glm::dvec3 p0 = scene.frame.toLocal(a.crs, a.pixelToCrs({w * 0.5, h * 0.5}));
        const glm::dvec3 p1 = scene.frame.toLocal(a.crs, a.pixelToCrs({w * 0.5 + 1.0, h * 0.5}));
        scene.gsd = glm::length(glm::dvec2(p1 - p0));
    }

    if (!sources.elevation.empty()) {
        auto hf = loadHeightfield(sources.elevation);
        if (!hf) return hf.error();
        if (hf->filledSamples > 0)
            scene.notes.push_back(sources.elevation.string() + ": filled " + std::to_string(hf->filledSamples) +
                                  " NaN/nodata samples from their neighbours");
        // The DEM must overlap the imagery, else the user gave the wrong file.
        const Georef& g = hf->georef;
        const glm::dvec2 c = g.crsToPixel(convert(a.crs, g.crs, a.pixelToCrs({w * 0.5, h * 0.5})));
        if (c.x < 0 || c.y < 0 || c.x > hf->heights.width || c.y > hf->heights.height)
            return fileError(sources.elevation.string(), "DEM does not cover the imagery (its centre lies outside it)");
        scene.elevation = std::move(*hf);
    }
    return scene;
}

} // namespace seasonview
