// `seasonview segment`: the offline (CPU) deciduous-treetop segmentation of a season pair and its quality check
// against ground truth (foliage/SegmentFiles.h).
#include "AtomicFile.h"
#include "Commands.h"
#include "ImagePyramid.h"
#include "PairStats.h"
#include "RenderJob.h"
#include "SegmentFiles.h"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <thread>

namespace seasonview::app {

namespace {

struct SegmentArgs {
    SceneArgs scene;
    std::string method = "default";
    int k = kSegDefaultK;
    std::string truth, truthTrees, out, metrics, overlay, trees;
    int bandRows = 256;
    double memoryBudgetMb = double(kSegmentMemoryBudget) / (1 << 20);
};

// Below this many pixels no progress bar: it would only flicker.
constexpr double kProgressPixels = 4096.0 * 4096.0;

Status checkTextOutput(const std::filesystem::path& out) {
    std::error_code ec;
    const std::filesystem::path dir = out.parent_path();
    if (!dir.empty() && !std::filesystem::is_directory(dir, ec))
        return fileError(out.string(), "output folder " + dir.string() + " does not exist");
    if (std::filesystem::is_directory(out, ec)) return fileError(out.string(), "is a folder, not a file name");
    return Ok{};
}

// The pair's histograms cached with its prepared pyramids (`seasonview prepare`, render), when the cache holds
// them for exactly these sources: they spare the segmentation its histogram pass. Never builds anything.
std::optional<SegmentationHistograms> preparedHistograms(const Scene& scene, const std::filesystem::path& cacheDir) {
    auto on = openPyramid(scene.leafon, cacheDir);
    if (!on) return std::nullopt;
    auto off = openPyramid(scene.leafoff, cacheDir);
    if (!off) return std::nullopt;
    return cachedPairHistograms(*on, *off, cacheDir);
}

// Where the pair statistics came from; the only ones this command gives segmentScene are the cached ones.
const char* statsFrom(const SegmentReport& r) {
    return r.statsSource == StatsSource::Given ? "pair statistics cache" : statsSourceName(r.statsSource);
}

nlohmann::ordered_json metricsJson(const SegmentArgs& a, const Scene& scene, const SegmentJob& job,
                                   const SegmentReport& r, double endToEndSeconds) {
    using nlohmann::ordered_json;
    const double pixels = double(r.width) * double(r.height);
    auto perSecond = [&](double s) { return s > 0.0 ? ordered_json(pixels / 1e6 / s) : ordered_json(nullptr); };
    auto orNull = [](bool has, double v) { return has ? ordered_json(v) : ordered_json(nullptr); };
    const bool t = r.confusion.has_value();
    const Confusion c = r.confusion.value_or(Confusion{});
    ordered_json j;
    j["method"] = std::string(segmentationMethodName(job.params.method));
    j["k"] = effectiveK(job.params);
    j["leafon"] = scene.sources.leafon.describe();
    j["leafoff"] = scene.sources.leafoff.describe();
    j["grid_crs"] = scene.grid.georef.crs.identifier().size() < 40 ? scene.grid.georef.crs.identifier()
                                                                    : scene.grid.georef.crs.name();
    j["grid_pixel_size"] = {scene.grid.georef.pixelSize.x, scene.grid.georef.pixelSize.y};
    j["warped"] = scene.warped();
    j["truth"] = job.truth.empty() ? ordered_json(nullptr) : ordered_json(job.truth.string());
    j["width"] = r.width;
    j["height"] = r.height;
    j["pixels"] = std::uint64_t(r.width) * std::uint64_t(r.height);
    j["nodata_pixels"] = r.nodataPixels; // a season has no data there: marked, never scored
    j["scored_pixels"] = t ? ordered_json(c.pixels()) : ordered_json(nullptr);
    j["precision"] = orNull(t, c.precision());
    j["recall"] = orNull(t, c.recall());
    j["f1"] = orNull(t, c.f1());
    j["iou"] = orNull(t, c.iou());
    auto count = [t](std::uint64_t v) { return t ? ordered_json(v) : ordered_json(nullptr); };
    j["tp"] = count(c.tp);
    j["fp"] = count(c.fp);
    j["fn"] = count(c.fn);
    j["tn"] = count(c.tn);
    if (job.params.method == SegmentationMethod::Default)
        j["drop_threshold"] = double(r.stats.dropThreshold) / kSegDropScale;
    j["seconds"] = r.segmentSeconds;
    j["megapixels_per_second"] = perSecond(r.segmentSeconds);
    j["total_seconds"] = r.totalSeconds;
    j["total_megapixels_per_second"] = perSecond(r.totalSeconds);
    j["end_to_end_seconds"] = endToEndSeconds;
    j["end_to_end_megapixels_per_second"] = perSecond(endToEndSeconds);
    j["read_seconds"] = r.readSeconds;
    j["write_seconds"] = r.writeSeconds;
    j["crown_seconds"] = r.crownSeconds;
    j["threads"] = std::max(1u, std::thread::hardware_concurrency());
    j["band_rows"] = a.bandRows;
    j["stats_from"] = statsFrom(r);
    j["pair_in_memory"] = r.heldInMemory;
    j["input_passes"] = r.inputPasses;
    j["crowns"] = r.crowns;
    if (r.centres) {
        j["truth_trees"] = job.truthTrees.string();
        j["trees_truth"] = r.centres->truth;
        j["centres_matched"] = r.centres->matched;
        j["centres_precision"] = r.centres->precision();
        j["centres_recall"] = r.centres->recall();
    }
    return j;
}

} // namespace

Runner addSegmentCommand(CLI::App& app) {
    auto args = std::make_shared<SegmentArgs>();
    CLI::App* cmd = app.add_subcommand(
        "segment", "Segment deciduous treetops from the seasons (CPU) and check them against ground truth");
    // The scene (its truth.deciduous and truth.trees are used unless --truth is given), as every command takes it.
    args->scene.addTo(*cmd, false);
    cmd->add_option("--method", args->method, "pixel | neighborhood | equalized | default")->capture_default_str();
    cmd->add_option("--k", args->k, "Neighbourhood size (odd, 1.." + std::to_string(kSegMaxK) + "; pixel ignores it)")
        ->capture_default_str();
    cmd->add_option("--truth", args->truth,
                    "Truth mask (non-zero = deciduous treetop): on the working grid, or georeferenced on any grid");
    cmd->add_option("--truth-trees", args->truthTrees,
                    "True trees CSV (x, y, radius_m[, type]); default: trees.csv next to --truth when present");
    cmd->add_option("--out", args->out,
                    "Mask to write: .tif a georeferenced GeoTIFF on the working grid (1 treetop, 0 not, nodata 255 where "
                    "a season has no data); .png 255 treetop, 0 not")
        ->required();
    cmd->add_option("--metrics", args->metrics, "Metrics JSON: precision, recall, f1, iou, pixels, seconds, ...");
    cmd->add_option("--overlay", args->overlay,
                    "Leaf-on with the result drawn over it: yellow true positive (or detected), magenta false "
                    "positive, blue false negative");
    cmd->add_option("--trees", args->trees,
                    "Crown centres to write: .csv id,x,y,easting,northing,radius_m,lon,lat (easting/northing in the "
                    "working grid's CRS, named by a .prj beside it) or .geojson (WGS 84 points)");
    cmd->add_option("--band-rows", args->bandRows,
                    "Rows segmented at a time (memory; the output does not depend on it)")
        ->capture_default_str()
        ->check(CLI::Range(1, 1 << 20));
    cmd->add_option("--memory-budget", args->memoryBudgetMb,
                    "MB the decoded pair may take to be read once (larger pairs are read twice when the method needs "
                    "histograms; the output does not depend on it)")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 1e9));
    return [args]() -> int {
        const auto started = std::chrono::steady_clock::now();
        auto fail = [](const std::string& m) {
            std::fprintf(stderr, "seasonview segment: %s\n", m.c_str());
            return 1;
        };
        const auto method = parseSegmentationMethod(args->method);
        if (!method) return fail("--method '" + args->method + "': expected pixel, neighborhood, equalized or default");
        if (args->k < 1 || args->k > kSegMaxK || args->k % 2 == 0)
            return fail("--k " + std::to_string(args->k) + ": must be odd, 1.." + std::to_string(kSegMaxK));

        auto sources = args->scene.sources();
        if (!sources) return fail(sources.message());
        SceneSources src = std::move(*sources);
        src.elevation = SourceList(); // segmentation needs no DEM: do not load one

        SegmentJob job;
        job.params = {*method, args->k};
        job.mask = args->out;
        job.overlay = args->overlay;
        job.trees = args->trees;
        job.bandRows = args->bandRows;
        job.memoryBudget = std::uint64_t(args->memoryBudgetMb * double(1 << 20));
        job.truth = !args->truth.empty() ? std::filesystem::path(args->truth) : src.truthDeciduous;
        if (!args->truthTrees.empty()) job.truthTrees = args->truthTrees;
        else if (!args->truth.empty()) {
            const std::filesystem::path next = std::filesystem::path(args->truth).parent_path() / "trees.csv";
            std::error_code ec;
            if (std::filesystem::is_regular_file(next, ec)) job.truthTrees = next;
        } else job.truthTrees = src.truthTrees;

        for (const std::string* image : {&args->out, &args->overlay})
            if (!image->empty())
                if (auto st = checkImageOutput(*image); !st) return fail(st.message());
        for (const std::string* text : {&args->metrics, &args->trees})
            if (!text->empty())
                if (auto st = checkTextOutput(*text); !st) return fail(st.message());

        const std::filesystem::path cacheDir = args->scene.cacheDir();
        auto scene = loadScene(src, cacheDir);
        if (!scene) return fail(scene.message());
        printSceneNotes(*scene);
        if (scene->sources.stream)
            return fail("--stream: segment reads every full-resolution texel of both seasons; run it without --stream "
                        "(the seasons are then prepared whole)");
        std::vector<ImagePyramid> pyramids;
        if (scene->warped()) {
            // Seasons on other grids, in mosaics or with nodata: segmented on the working grid, from the pyramids
            // `prepare` warps them into (built here when missing), whose alpha says where each has data.
            auto p = preparePyramids(*scene, cacheDir);
            if (!p) return fail(p.message());
            pyramids = std::move(*p);
            job.levelZero = levelZeroOf(*scene, pyramids);
        }
        if (needsHistograms(job.params.method)) job.histograms = preparedHistograms(*scene, cacheDir);
        if (double(scene->leafon.info.width) * scene->leafon.info.height >= kProgressPixels)
            job.progress = terminalProgress("segment");

        auto report = segmentScene(*scene, job);
        if (!report && rebuildingDamaged(report.message(), cacheDir)) {
            // A level-0 tile damaged in the cache (the pair statistics did not read it: they came from the cache):
            // rebuilt from the source, and the segmentation run again.
            auto p = preparePyramids(*scene, cacheDir);
            if (!p) return fail(p.message());
            pyramids = std::move(*p);
            job.levelZero = levelZeroOf(*scene, pyramids);
            report = segmentScene(*scene, job);
        }
        if (!report) return fail(report.message());
        // From the command's start (arguments parsed) to the mask written.
        const double endToEnd = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
        if (!args->metrics.empty()) {
            std::string err;
            if (!writeTextAtomic(args->metrics, metricsJson(*args, *scene, job, *report, endToEnd).dump(2) + "\n",
                                 err))
                return fail(fileError(args->metrics, err).message);
        }
        const SegmentReport& r = *report;
        const double mp = double(r.width) * r.height / 1e6;
        std::printf("wrote %s: %dx%d, %s (k %d)", args->out.c_str(), r.width, r.height,
                    std::string(segmentationMethodName(job.params.method)).c_str(), effectiveK(job.params));
        if (r.nodataPixels)
            std::printf(", %.1f %% without data in a season", 100.0 * double(r.nodataPixels) / (double(r.width) * r.height));
        if (r.confusion)
            std::printf(", precision %.3f recall %.3f F1 %.3f IoU %.3f", r.confusion->precision(),
                        r.confusion->recall(), r.confusion->f1(), r.confusion->iou());
        if (r.centres)
            std::printf(", centres precision %.3f recall %.3f (%d crowns, %d trees)", r.centres->precision(),
                        r.centres->recall(), r.centres->detected, r.centres->truth);
        std::printf("; segmentation %.3f s (%.0f MP/s), end to end %.2f s (%.0f MP/s; read %.2f s, write %.2f s, "
                    "stats: %s)\n",
                    r.segmentSeconds, r.segmentSeconds > 0.0 ? mp / r.segmentSeconds : 0.0, endToEnd,
                    endToEnd > 0.0 ? mp / endToEnd : 0.0, r.readSeconds, r.writeSeconds,
                    statsFrom(r));
        return 0;
    };
}

} // namespace seasonview::app
