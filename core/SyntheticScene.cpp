// `seasonview synth`: the pipeline from options to files. The pieces:
//   SynthLayout      parcels, roads, river (vector, layout space)
//   SynthSettlement  houses, farmsteads, sports ground, parking, cars
//   SynthVegetation  trees
//   SynthTerrain     fBm or real DEM elevation
//   SynthRaster      ground and object maps (shared by both seasons)
//   SynthShadow      cast shadows per season
//   SynthCamera      sun, sky, exposure, haze, noise per season
//   SynthMaterials / SynthPaint  pixel colours
#include "SyntheticScene.h"

#include "AtomicFile.h"
#include "Raster.h"
#include "SynthCamera.h"
#include "SynthLayout.h"
#include "SynthObjects.h"
#include "SynthPaint.h"
#include "SynthRandom.h"
#include "SynthRaster.h"
#include "SynthShadow.h"
#include "SynthTerrain.h"

#include <glm/common.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <thread>

namespace seasonview {

namespace {

using namespace synth;

// The tallest object (trees are clamped to 34 m) casts its shadow this far at the lowest leaf-off sun (19°):
// objects that far outside the scene still shadow it.
constexpr double kMaxCasterHeight = 35.0;

std::string treesCsv(const Objects& o, float half, glm::dvec2 centre, double& meanDeciduousHeight, int& nd, int& nc) {
    std::string s = "id,type,x,y,easting,northing,radius_m,height_m\n";
    double sum = 0.0;
    nd = nc = 0;
    char line[256];
    for (size_t i = 0; i < o.trees.size(); ++i) {
        const Tree& t = o.trees[i];
        // Every tree whose crown disc reaches into the scene (its centre may lie just outside).
        const float dx = std::max(std::abs(t.centre.x) - half, 0.0f), dy = std::max(std::abs(t.centre.y) - half, 0.0f);
        if (dx * dx + dy * dy >= t.radius * t.radius) continue;
        std::snprintf(line, sizeof line, "%zu,%s,%.3f,%.3f,%.3f,%.3f,%.3f,%.2f\n", i + 1, t.conifer ? "conifer" : "deciduous",
                      double(t.centre.x), double(t.centre.y), centre.x + double(t.centre.x), centre.y + double(t.centre.y),
                      double(t.radius), double(t.height));
        s += line;
        if (t.conifer) ++nc;
        else {
            ++nd;
            sum += double(t.height);
        }
    }
    meanDeciduousHeight = nd > 0 ? sum / nd : 0.0;
    return s;
}

} // namespace

Result<SynthReport> generateSyntheticScene(const SynthOptions& options, const std::filesystem::path& outDir,
                                           const ProgressFn& progress) {
    const auto start = std::chrono::steady_clock::now();
    auto stage = [&](double f, const char* name) {
        if (progress) progress(f, name);
    };
    if (!std::isfinite(options.sizeM) || options.sizeM <= 0.0)
        return Error{"synth: the scene size must be a positive number of metres"};
    if (!std::isfinite(options.gsd) || options.gsd <= 0.0)
        return Error{"synth: the ground sample distance must be a positive number of metres"};
    const double pixels = options.sizeM / options.gsd;
    if (!(pixels >= 16.0 && pixels <= 32768.0))
        return Error{"synth: size / gsd must give 16 to 32768 pixels per side (got " + std::to_string(std::lround(pixels)) + ")"};
    const int size = static_cast<int>(std::lround(pixels));
    const int threads = options.threads > 0 ? options.threads : std::max(1, int(std::thread::hardware_concurrency()));
    const double gsd = options.gsd, extent = double(size) * gsd;
    // DEM spacing max(1 m, 4 gsd), adjusted to a whole number of samples covering exactly the imagery's extent.
    const int demSamples = std::max(2, static_cast<int>(std::lround(extent / std::max(1.0, 4.0 * gsd))));
    const double demSpacing = extent / demSamples;
    const std::uint64_t seed = mixSeed(options.seed, 0x5EA50F5EEDull);

    std::error_code ec;
    std::filesystem::create_directories(outDir, ec);
    if (ec) return fileError(outDir.string(), "cannot create folder (" + ec.message() + ")");
    // A stale manifest must not describe files that are about to be replaced.
    std::filesystem::remove(outDir / "scene.json", ec);

    // Where the scene is: near Münster (UTM 32N), or centred on the real DEM in its own UTM zone.
    stage(0.0, "layout");
    Crs crs = Crs::utm(32, true);
    glm::dvec2 centre(405000.0, 5757000.0);
    std::optional<DemSource> dem;
    if (!options.dem.empty()) {
        auto d = openDem(options.dem);
        if (!d) return d.error();
        const glm::dvec2 ll = d->centreLonLat;
        crs = Crs::utm(std::clamp(int(std::floor((ll.x + 180.0) / 6.0)) + 1, 1, 60), ll.y >= 0.0);
        centre = glm::round(convert(Crs::geographic(), crs, ll));
        dem = std::move(*d);
    }
    const glm::dvec2 origin = centre + glm::dvec2(-0.5 * extent, 0.5 * extent);
    const Georef georef{crs, origin, glm::dvec2(gsd)};
    const Georef demGeoref{crs, origin, glm::dvec2(demSpacing)};

    const SeasonLook looks[2] = {makeSeasonLook(true, seed, !crs.north), makeSeasonLook(false, seed, !crs.north)};
    const double lowestSun = std::min(looks[0].sunElevationDeg, looks[1].sunElevationDeg) * 0.017453292519943295;
    const double marginM = kMaxCasterHeight / std::tan(lowestSun) + 2.0 * gsd;
    const float half = static_cast<float>(0.5 * extent);

    Layout layout = buildLayout(half + static_cast<float>(marginM) + 10.0f, seed);
    Objects objects;
    placeSettlement(layout, objects);
    placeVegetation(layout, objects, half);

    stage(0.1, "terrain");
    Terrain terrain;
    if (dem) {
        auto t = resampleDem(*dem, demSamples, static_cast<float>(demSpacing), crs, centre, threads);
        if (!t) return t.error();
        terrain = std::move(*t);
        dem.reset();
    } else {
        terrain = makeFbmTerrain(demSamples, static_cast<float>(demSpacing), layout, seed, threads);
    }
    if (auto s = writeGeoTiff(outDir / "dem.tif", terrain.z.data(), SampleType::F32, demSamples, demSamples, 1, demGeoref);
        !s)
        return s.error();

    stage(0.15, "rasterising");
    SceneMaps maps;
    maps.grid = PixelGrid{size, static_cast<int>(std::ceil(marginM / gsd)), static_cast<float>(gsd), half};
    rasterizeGround(layout, maps, threads);
    rasterizeObjects(layout, objects, maps, threads);

    std::vector<std::uint8_t> rgb, shadow;
    for (int s = 0; s < 2; ++s) {
        const SeasonLook& look = looks[s];
        stage(0.25 + 0.3 * s, look.leafOn ? "leaf-on" : "leaf-off");
        const std::vector<float> shade = terrainShading(terrain, look.towardSun, threads);
        castShadows(maps, objects, terrain, look.towardSun, look.leafOn, shadow);
        paintSeason(PaintInput{layout, objects, maps, terrain, shade, shadow}, look, rgb, threads);
        const char* name = look.leafOn ? "leafon.tif" : "leafoff.tif";
        if (auto w = writeGeoTiff(outDir / name, rgb.data(), SampleType::U8, size, size, 3, georef); !w) return w.error();
    }
    rgb = {};
    shadow = {};

    stage(0.85, "truth");
    {
        const size_t n = size_t(size), e = size_t(maps.grid.extSize()), m = size_t(maps.grid.margin);
        std::vector<std::uint8_t> deciduous(n * n, 0), conifer(n * n, 0);
        for (size_t r = 0; r < n; ++r)
            for (size_t c = 0; c < n; ++c) {
                const std::uint32_t id = maps.object[(r + m) * e + c + m];
                if (!maps.isTree(id)) continue;
                (objects.trees[id - 1].conifer ? conifer : deciduous)[r * n + c] = 255;
            }
        if (auto w = writeImageAtomic(outDir / "truth_deciduous.png", deciduous.data(), size, size, 1); !w) return w.error();
        if (auto w = writeImageAtomic(outDir / "truth_conifer.png", conifer.data(), size, size, 1); !w) return w.error();
    }

    SynthReport report;
    double meanHeight = 0.0;
    const std::string csv = treesCsv(objects, half, centre, meanHeight, report.deciduousTrees, report.conifers);
    std::string err;
    if (!writeTextAtomic(outDir / "trees.csv", csv, err)) return fileError((outDir / "trees.csv").string(), err);

    nlohmann::ordered_json j;
    j["name"] = "synthetic seed " + std::to_string(options.seed) + (options.dem.empty() ? "" : " on " + options.dem.stem().string());
    j["leafon"] = "leafon.tif";
    j["leafoff"] = "leafoff.tif";
    j["elevation"] = "dem.tif";
    j["truth"] = {{"deciduous", "truth_deciduous.png"}, {"conifer", "truth_conifer.png"}, {"trees", "trees.csv"}};
    j["parameters"] = {{"tree_height_m", std::round(meanHeight * 100.0) / 100.0}};
    j["generator"] = {{"program", "seasonview synth"}, {"version", 1},      {"seed", options.seed},
                      {"size_m", options.sizeM},       {"gsd", options.gsd}, {"dem", options.dem.string()}};
    if (!writeTextAtomic(outDir / "scene.json", j.dump(2) + "\n", err))
        return fileError((outDir / "scene.json").string(), err);

    stage(1.0, "done");
    report.width = report.height = size;
    report.demWidth = report.demHeight = demSamples;
    report.crs = crs.name();
    report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return report;
}

} // namespace seasonview
