// `seasonview synth`: the deterministic synthetic two-season scene with ground truth.
#include "Commands.h"
#include "JsonFile.h"

#include "SyntheticScene.h"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <fstream>
#include <memory>

#include <unistd.h>

namespace seasonview::app {

ProgressFn terminalProgress(const char* what) {
    if (!::isatty(2)) return {};
    return [what](double f, const char* stage) {
        const int n = int(f * 30.0 + 0.5);
        std::fprintf(stderr, "\r%s [%-30.*s] %3d%% %-24s", what, n, "##############################", int(f * 100 + 0.5),
                     stage);
        if (f >= 1.0) std::fprintf(stderr, "\n");
        std::fflush(stderr);
    };
}

Result<SynthOptions> loadSynthPreset(const std::filesystem::path& path) {
    auto parsed = readJsonFile(path, "preset");
    if (!parsed) return parsed.error();
    const nlohmann::json& j = *parsed;
    if (!j.is_object()) return fileError(path.string(), "malformed JSON preset (not an object)");
    SynthOptions o;
    const auto take = [&](const char* key, auto& out) {
        if (!j.contains(key)) return true;
        const auto v = jsonMember<std::decay_t<decltype(out)>>(j, key);
        if (v) out = *v;
        return v.has_value();
    };
    if (!take("size_m", o.sizeM) || !take("gsd", o.gsd) || !take("seed", o.seed) || !take("block_city", o.blockCity) ||
        !take("facade_size", o.facadeSize))
        return fileError(path.string(),
                         "preset keys size_m, gsd must be numbers, seed, block_city and facade_size integers");
    if (o.blockCity < 0 || o.facadeSize < 16 || o.facadeSize > 4096)
        return fileError(path.string(), "preset block_city must be >= 0 and facade_size in 16..4096");
    if (!(o.sizeM >= 16.0) || !(o.gsd >= 0.01)) return fileError(path.string(), "preset size_m or gsd out of range");
    return o;
}

Runner addSynthCommand(CLI::App& app) {
    struct Args {
        SynthOptions o;
        std::string out, dem, preset, facades, centre, compression = "zstd";
        bool noCity = false;
    };
    auto args = std::make_shared<Args>();
    CLI::App* cmd = app.add_subcommand("synth", "Generate a deterministic synthetic leaf-on/leaf-off scene with ground truth");
    cmd->add_option("--out", args->out, "Output folder")->required();
    cmd->add_option("--preset", args->preset,
                    "Preset JSON (data/presets/*.json: size_m, gsd, seed); explicit flags override it");
    cmd->add_option("--size-m", args->o.sizeM, "Scene side in metres")->capture_default_str()->check(CLI::Range(16.0, 1.0e6));
    cmd->add_option("--gsd", args->o.gsd, "Ground sample distance, metres per pixel")
        ->capture_default_str()
        ->check(CLI::Range(0.01, 100.0));
    cmd->add_option("--seed", args->o.seed, "Random seed (same seed -> identical files)")->capture_default_str();
    cmd->add_option("--dem", args->dem, "Real DEM GeoTIFF: terrain is a crop around its centre instead of fBm");
    cmd->add_option("--threads", args->o.threads, "Worker threads (0 = all cores; output does not depend on it)");
    cmd->add_option("--dem-spacing", args->o.demSpacing,
                    "DEM sample spacing in metres (0 = max(1, 4 x gsd)); with --dem the real DEM is resampled to it")
        ->capture_default_str();
    cmd->add_option("--band-rows", args->o.bandRows,
                    "Imagery rows generated at a time (0 = " + std::to_string(kDefaultSynthBandRows) +
                        "); memory grows with it, the output does not depend on it")
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--facades", args->facades,
                    "Folder of facade photos for the city model's textures (e.g. ../shared/data/city/berlin_facades); "
                    "default: procedural facades");
    cmd->add_option("--facade-size", args->o.facadeSize, "Facade texture side, texels")
        ->capture_default_str()
        ->check(CLI::Range(16, 4096));
    cmd->add_flag("--no-city", args->noCity, "Do not write the buildings as a city model (city/)");
    cmd->add_option("--block-city", args->o.blockCity,
                    "A block city of N buildings at the scene centre (benchmarks: 10,000 needs about 2 km)")
        ->check(CLI::Range(0, 1000000));
    cmd->add_option("--centre", args->centre,
                    "LON,LAT (degrees) of the scene's centre, on its UTM zone's grid (e.g. under a real city model); "
                    "default near Münster, or the --dem's centre");
    cmd->add_option("--compression", args->compression,
                    "Imagery GeoTIFF compression: zstd (decodes five times faster), deflate (for readers without "
                    "Zstandard) or jpeg (lossy YCbCr, as orthophotos usually come; masks stay lossless)")
        ->capture_default_str()
        ->check(CLI::IsMember({"zstd", "deflate", "jpeg"}));
    return [args, cmd]() -> int {
        if (!args->preset.empty()) {
            auto preset = loadSynthPreset(args->preset);
            if (!preset) {
                std::fprintf(stderr, "seasonview synth: %s\n", preset.message().c_str());
                return 1;
            }
            if (cmd->count("--size-m") == 0) args->o.sizeM = preset->sizeM;
            if (cmd->count("--gsd") == 0) args->o.gsd = preset->gsd;
            if (cmd->count("--seed") == 0) args->o.seed = preset->seed;
            if (cmd->count("--block-city") == 0) args->o.blockCity = preset->blockCity;
            if (cmd->count("--facade-size") == 0) args->o.facadeSize = preset->facadeSize;
        }
        args->o.dem = args->dem;
        args->o.facadePhotos = args->facades;
        if (!args->centre.empty()) {
            double lon = 0.0, lat = 0.0;
            char extra = 0;
            if (std::sscanf(args->centre.c_str(), "%lf,%lf%c", &lon, &lat, &extra) != 2) {
                std::fprintf(stderr, "seasonview synth: --centre '%s': expected LON,LAT in degrees\n", args->centre.c_str());
                return 1;
            }
            args->o.centreLonLat = glm::dvec2(lon, lat);
        }
        args->o.city = !args->noCity;
        args->o.compression = args->compression == "deflate" ? TiffCompression::Deflate
                              : args->compression == "jpeg"  ? TiffCompression::Jpeg
                                                             : TiffCompression::Zstd;
        const double pixels = args->o.sizeM / args->o.gsd;
        if (pixels > double(kMaxSynthPixels)) {
            std::fprintf(stderr, "seasonview synth: --size-m/--gsd gives %.0f pixels per side (max %d)\n", pixels,
                         kMaxSynthPixels);
            return 1;
        }
        auto report = generateSyntheticScene(args->o, args->out, terminalProgress("synth"));
        if (!report) {
            std::fprintf(stderr, "seasonview synth: %s\n", report.message().c_str());
            return 1;
        }
        std::printf("wrote %s: %dx%d px per season, DEM %dx%d, %d deciduous trees, %d conifers, %zu buildings "
                    "(%.1f MB of facades), %s, in %.1f s\n",
                    args->out.c_str(), report->width, report->height, report->demWidth, report->demHeight,
                    report->deciduousTrees, report->conifers, report->buildings, double(report->facadeBytes) / 1e6,
                    report->crs.c_str(), report->seconds);
        return 0;
    };
}

} // namespace seasonview::app
