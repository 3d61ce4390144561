// `seasonview prepare`: builds (or checks) the tiled mip pyramid of each imagery layer in the cache, then the pair's
// segmentation statistics (foliage/PairStats.h) from them, the canopy layer precomputed for the canopy view's
// parameters (foliage/CanopyPyramid.h) and the DEM's elevation pyramid.
#include "Commands.h"
#include "ElevationPyramid.h"
#include "ImagePyramid.h"
#include "PairStats.h"
#include "StreamedPyramid.h"
#include "RenderJob.h"

#include <cstdio>
#include <memory>

namespace seasonview::app {

namespace {
struct PrepareArgs {
    SceneArgs scene;
    bool force = false;
    CanopyArgs canopy; // --method, --k, --canopy-layers: the canopy layer's parameters (the canopy view's defaults)
};
} // namespace

Runner addPrepareCommand(CLI::App& app) {
    auto args = std::make_shared<PrepareArgs>();
    CLI::App* cmd = app.add_subcommand(
        "prepare", "Build the tiled mip pyramids of a scene's imagery, the pair's segmentation statistics, the canopy "
        "layer and the elevation pyramid in the cache (skipped when up to date)");
    args->scene.addTo(*cmd);
    cmd->add_flag("--force", args->force, "Rebuild the pyramids and statistics even when they are up to date");
    cmd->add_option("--method", args->canopy.method,
                    "the canopy layer's segmentation method (as the canopy view's --method), "
                    "pixel|neighborhood|equalized|default")
        ->capture_default_str();
    cmd->add_option("--k", args->canopy.k, "the canopy layer's neighbourhood size (as the canopy view's --k)")
        ->capture_default_str();
    cmd->add_option("--canopy-layers", args->canopy.layers,
                    "the canopy layer's stacked layers (as the canopy view's --canopy-layers), 1..32, or off (no "
                    "canopy layer prepared)")
        ->capture_default_str();
    return [args]() -> int {
        auto fail = [](const std::string& m) {
            std::fprintf(stderr, "seasonview prepare: %s\n", m.c_str());
            return 1;
        };
        auto canopy = args->canopy.settings();
        if (!canopy) return fail(canopy.message());
        auto scene = args->scene.load();
        if (!scene) return fail(scene.message());
        printSceneNotes(*scene);
        PrepareOptions options;
        options.cacheDir = args->scene.cache.empty() ? defaultCacheDir() : std::filesystem::path(args->scene.cache);
        options.force = args->force;
        const std::pair<const char*, const ImageryLayer*> layers[] = {{"leafon", &scene->leafon},
                                                                      {"leafoff", &scene->leafoff}};
        std::vector<ImagePyramid> pyramids;
        for (const auto& [name, layer] : layers) {
            const LayerPrepareProgress progress(name, *layer, options.cacheDir);
            options.progress = progress.fn();
            auto report = prepareSeasonPyramid(*scene, name, options);
            if (!report) return fail(report.message());
            const ImagePyramid& p = report->pyramid;
            const std::string fetched = report->built ? progress.note() : std::string();
            const std::string streamed =
                p.streamedLevels > 0 ? " (levels 0-" + std::to_string(p.streamedLevels - 1) + " streamed)" : "";
            if (report->built)
                std::printf("%s: built in %.2f s (%s): %dx%d, %zu levels%s, %s%s%s\n", name, report->seconds,
                            report->reason.c_str(), p.width(), p.height(), p.levels.size(), streamed.c_str(),
                            p.folder.c_str(), fetched.empty() ? "" : "; ", fetched.c_str());
            else
                std::printf("%s: up to date: %dx%d, %zu levels%s, %s\n", name, p.width(), p.height(), p.levels.size(),
                            streamed.c_str(), p.folder.c_str());
            std::fflush(stdout);
            pyramids.push_back(report->pyramid);
        }
        const std::vector<ImagePyramid> seasons = pyramids;
        std::optional<SegmentationHistograms> histograms;
        {
            // The histograms behind the segmentation's equalisation tables and drop threshold, from level 0.
            pyramids = preparedPart(pyramids); // streamed seasons: from the first level both have on disk
            if (args->force) {
                std::error_code ec;
                std::filesystem::remove(pairHistogramsFile(pyramids[0], pyramids[1], options.cacheDir), ec);
            }
            PairHistogramsReport report;
            auto h = preparePairHistograms(pyramids[0], pyramids[1], options.cacheDir,
                                           terminalProgress("pair stats"), &report);
            if (!h) return fail(h.message());
            const double drop = double(dropThresholdFromHistogram(h->drop)) / kSegDropScale;
            if (report.built)
                std::printf("pair statistics: built in %.2f s (%s): drop threshold %.3f, %s\n", report.seconds,
                            args->force ? "forced" : report.reason.c_str(), drop, report.file.c_str());
            else
                std::printf("pair statistics: up to date: drop threshold %.3f, %s\n", drop, report.file.c_str());
            std::fflush(stdout);
            histograms = std::move(*h);
        }
        if (canopy->layers > 0 && seasons[0].streamedLevels == 0 && seasons[1].streamedLevels == 0) {
            // The canopy view's layer for these parameters, read by its loader instead of derived while flying.
            CanopyOptions co;
            co.params = canopy->params;
            co.layers = canopy->layers;
            options.progress = terminalProgress("canopy");
            auto report = preparePyramid(
                canopyLayerSource(seasons, co, statsFromHistograms(*histograms, co.params.method)), options);
            if (!report) return fail(report.message());
            const std::string what = canopyLayerName(co);
            if (report->built)
                std::printf("canopy layer: built in %.2f s (%s): %s, %s\n", report->seconds, report->reason.c_str(),
                            what.c_str(), report->pyramid.folder.c_str());
            else
                std::printf("canopy layer: up to date: %s, %s\n", what.c_str(), report->pyramid.folder.c_str());
            std::fflush(stdout);
        } else if (canopy->layers > 0) {
            std::printf("canopy layer: not prepared (a season streams: the view derives it as it flies)\n");
            std::fflush(stdout);
        }
        if (scene->elevation) {
            const ElevationGrid grid = elevationGrid(*scene);
            options.progress = terminalProgress("elevation");
            auto report = preparePyramid(elevationPyramidSource(*scene, grid), options);
            if (!report) return fail(report.message());
            const ImagePyramid& p = report->pyramid;
            std::printf("elevation: %s: %dx%d samples at %.2f m, %zu levels, %s\n",
                        report->built ? ("built in " + std::to_string(report->seconds) + " s (" + report->reason + ")").c_str()
                                      : "up to date",
                        p.width(), p.height(), grid.spacing, p.levels.size(), p.folder.c_str());
            std::fflush(stdout);
        }
        return 0;
    };
}

} // namespace seasonview::app
