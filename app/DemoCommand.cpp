// `seasonview demo`: generates (once, cached) the synthetic scene and writes stills plus an index.html.
#include "AtlasTree.h"
#include "JsonFile.h"
#include "Bench.h"
#include "CityJob.h"
#include "Commands.h"
#include "RenderJob.h"

#include "AtomicFile.h"
#include "Raster.h"
#include "SegmentFiles.h"
#include "SyntheticScene.h"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>
#include <thread>
#include <tuple>
#include <algorithm>

namespace seasonview::app {

namespace {

struct DemoArgs {
    std::string out = "out/demo", preset;
    FrameArgs frame;  // the stills' size, --window
    SceneArgs scene;  // --cache (the scene is generated)
    SynthOptions synth;
    bool noCity = false;
    int benchFrames = 24;
};

// True when `dir` holds a complete scene generated with the same options.
bool cachedSceneMatches(const std::filesystem::path& dir, const SynthOptions& o) {
    auto parsed = readJsonFile(dir / "scene.json", "manifest");
    if (!parsed || !parsed->is_object() || !parsed->contains("generator") || !(*parsed)["generator"].is_object())
        return false;
    const nlohmann::json& j = *parsed;
    const auto& g = j["generator"];
    return jsonValue(g, "version", 0) == kSynthGeneratorVersion && jsonValue(g, "seed", std::uint64_t(0)) == o.seed &&
           jsonValue(g, "size_m", 0.0) == o.sizeM && jsonValue(g, "gsd", 0.0) == o.gsd &&
           jsonValue(g, "dem", std::string()) == o.dem.string() &&
           jsonValue(g, "compression", std::string("deflate")) == tiffCompressionName(o.compression) &&
           jsonValue(g, "block_city", 0) == o.blockCity &&
           (!j.contains("buildings") || jsonValue(g, "facade_size", 256) == o.facadeSize);
}

// One method of the demo's offline segmentation.
struct SegmentRow {
    SegmentationMethod method;
    int k = kSegDefaultK;
    SegmentReport report;
};

// Box-averages an RGB image down by an integer factor (the overlay's thumbnail for the page).
Image<std::uint8_t> downsample(const Image<std::uint8_t>& im, int factor) {
    Image<std::uint8_t> r;
    r.width = std::max(1, im.width / factor);
    r.height = std::max(1, im.height / factor);
    r.channels = im.channels;
    r.pixels.assign(size_t(r.width) * size_t(r.height) * size_t(r.channels), 0);
    for (int y = 0; y < r.height; ++y)
        for (int x = 0; x < r.width; ++x)
            for (int c = 0; c < r.channels; ++c) {
                unsigned sum = 0, n = 0;
                for (int j = y * factor; j < std::min(im.height, (y + 1) * factor); ++j)
                    for (int i = x * factor; i < std::min(im.width, (x + 1) * factor); ++i, ++n) sum += im.at(i, j, c);
                r.at(x, y, c) = std::uint8_t((sum + n / 2) / std::max(n, 1u));
            }
    return r;
}

Image<std::uint8_t> crop(const Image<std::uint8_t>& im, int x0, int y0, int w, int h) {
    Image<std::uint8_t> r;
    r.width = std::min(w, im.width - x0);
    r.height = std::min(h, im.height - y0);
    r.channels = im.channels;
    r.pixels.resize(size_t(r.width) * size_t(r.height) * size_t(r.channels));
    for (int y = 0; y < r.height; ++y)
        std::copy_n(&im.at(x0, y0 + y), size_t(r.width) * size_t(r.channels), &r.at(0, y));
    return r;
}

// The offline (CPU) segmentation of the scene with every method, scored against the generator's truth
// (`seasonview segment`'s engine, foliage/SegmentFiles.h): masks in DIR/segment, and for `default` the overlay
// (true positives, false positives, false negatives over the leaf-on image) as a thumbnail of the whole scene and a
// full-resolution crop of its centre. The full overlay would be as large as the imagery: it is not kept.
Result<std::vector<SegmentRow>> segmentDemo(const Scene& scene, const std::filesystem::path& dir) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) return fileError(dir.string(), "cannot create folder (" + ec.message() + ")");
    std::vector<SegmentRow> rows;
    for (SegmentationMethod m : {SegmentationMethod::Pixel, SegmentationMethod::Neighborhood,
                                 SegmentationMethod::Equalized, SegmentationMethod::Default}) {
        SegmentJob job;
        job.params = {m, kSegDefaultK};
        const std::string name(segmentationMethodName(m));
        job.mask = dir / (name + ".png");
        job.truth = scene.sources.truthDeciduous;
        job.truthTrees = scene.sources.truthTrees;
        if (m == SegmentationMethod::Default) {
            job.overlay = dir / "overlay_full.tif";
            job.trees = dir / "trees.csv";
        }
        auto r = segmentScene(scene, job);
        if (!r) return r.error();
        rows.push_back({m, effectiveK(job.params), std::move(*r)});
        if (m != SegmentationMethod::Default) continue;
        auto overlay = readImageU8(job.overlay, 3);
        if (!overlay) return overlay.error();
        std::filesystem::remove(job.overlay, ec);
        const int factor = std::max(1, (std::max(overlay->width, overlay->height) + 1023) / 1024);
        const Image<std::uint8_t> thumb = downsample(*overlay, factor);
        if (auto st = writeImageAtomic(dir / "overlay.png", thumb.pixels.data(), thumb.width, thumb.height, 3); !st)
            return st.error();
        const int side = std::min({640, overlay->width, overlay->height});
        const Image<std::uint8_t> centre =
            crop(*overlay, (overlay->width - side) / 2, (overlay->height - side) / 2, side, side);
        if (auto st = writeImageAtomic(dir / "overlay_crop.png", centre.pixels.data(), centre.width, centre.height, 3);
            !st)
            return st.error();
    }
    nlohmann::ordered_json j = nlohmann::ordered_json::array();
    for (const SegmentRow& row : rows) {
        const SegmentReport& r = row.report;
        const double mp = double(r.width) * double(r.height) / 1e6;
        nlohmann::ordered_json e;
        e["method"] = std::string(segmentationMethodName(row.method));
        e["k"] = row.k;
        if (r.confusion) {
            e["precision"] = r.confusion->precision();
            e["recall"] = r.confusion->recall();
            e["f1"] = r.confusion->f1();
            e["iou"] = r.confusion->iou();
        }
        if (r.centres) {
            e["centres_precision"] = r.centres->precision();
            e["centres_recall"] = r.centres->recall();
            e["crowns"] = r.centres->detected;
            e["trees_truth"] = r.centres->truth;
        }
        e["pixels"] = std::uint64_t(r.width) * std::uint64_t(r.height);
        e["seconds"] = r.segmentSeconds;
        e["megapixels_per_second"] = r.segmentSeconds > 0.0 ? mp / r.segmentSeconds : 0.0;
        e["total_seconds"] = r.totalSeconds;
        j.push_back(e);
    }
    std::string err;
    if (!writeTextAtomic(dir / "metrics.json", j.dump(2) + "\n", err)) return fileError((dir / "metrics.json").string(), err);
    return rows;
}

std::string htmlEscape(const std::string& s) {
    std::string r;
    for (char c : s) {
        if (c == '<') r += "&lt;";
        else if (c == '>') r += "&gt;";
        else if (c == '&') r += "&amp;";
        else r += c;
    }
    return r;
}

// One still of the demo's page.
struct DemoStill {
    const char* file;
    const char* caption;
    Camera camera;
    ImageryView view;
};

// Generates the scene into `sceneDir` unless a complete one with the same options is there; false when cached.
Result<bool> ensureDemoScene(const SynthOptions& synth, const std::filesystem::path& sceneDir, double& synthSeconds) {
    if (cachedSceneMatches(sceneDir, synth)) return false;
    std::printf("generating the synthetic scene (%.0f m at %.2f m/px, seed %llu) ...\n", synth.sizeM, synth.gsd,
                static_cast<unsigned long long>(synth.seed));
    std::fflush(stdout);
    auto report = generateSyntheticScene(synth, sceneDir, terminalProgress("synth"));
    if (!report) return report.error();
    synthSeconds = report->seconds;
    return true;
}

// The stills of the page: both seasons from above, the swipe, the imagery and geometry levels, low and oblique views,
// the canopy with trunks.
std::vector<DemoStill> demoStills(const Scene& scene, double aspect) {
    const Camera top = overviewCamera(scene, aspect);
    const Camera oblique = obliqueCamera(scene, 30.0, -35.0, 0.3);
    const Camera low = obliqueCamera(scene, 210.0, -12.0, 0.22);
    const Camera near = obliqueCamera(scene, 30.0, -30.0, 0.05);
    return {
        {"leafon_top.png", "Leaf-on (summer), straight down", top, ImageryView::LeafOn},
        {"leafoff_top.png", "Leaf-off (winter), straight down", top, ImageryView::LeafOff},
        {"swipe_oblique.png", "Swipe: leaf-on left, leaf-off right, oblique 3D view (35 deg down)", oblique,
         ImageryView::Swipe},
        {"lod_oblique.png", "Clipmap levels used (level 0 red, 1 green, 2 blue, coarse pyramid yellow...)", oblique,
         ImageryView::Lod},
        {"leafoff_oblique.png", "Leaf-off, oblique 3D view (35 deg down)", oblique, ImageryView::LeafOff},
        {"leafon_low.png", "Leaf-on, low view towards the horizon (12 deg down)", low, ImageryView::LeafOn},
        {"terrain_levels.png", "Terrain geometry clipmap levels (one colour per level: red finest, then green, "
                               "blue, yellow, ...)", oblique, ImageryView::Levels},
        {"terrain_wireframe.png", "Terrain geometry clipmap triangles, low view", low, ImageryView::Wireframe},
        {"canopy_trunks.png", "Deciduous treetops found by comparing the seasons (default method, on the GPU), "
                              "standing as 16 stacked layers over the leaf-off ground, trunks at the crown centres "
                              "(30 deg down, 145 m away)", near, ImageryView::Canopy},
    };
}

// The city still: the scene's buildings through their texture-atlas tree (built into the cache on first use), seen
// obliquely from 30° down over the leaf holding the most triangles. The demo's scene is always synth's, whose OBJ is
// in the scene's frame, so the tree's bounds are scene coordinates. Nothing when the tree has no textured leaf.
struct DemoCity {
    std::optional<DemoStill> still;
    std::string note;
    double seconds = 0.0;
};

Result<DemoCity> renderCityStill(const Scene& scene, const RenderSettings& settings, const std::filesystem::path& out,
                                 int w, int h) {
    using clock = std::chrono::steady_clock;
    const auto tc = clock::now();
    DemoCity city;
    auto tree = prepareCityTree(scene, settings.cacheDir, "");
    if (!tree) return tree.error();
    auto file = city::AtlasTreeFile::open(tree->string());
    if (!file) return file.error();
    const city::AtlasNode* best = nullptr;
    std::size_t nodes = 0;
    for (const auto& t : file->trees)
        for (const auto& n : t.nodes) {
            ++nodes;
            if (n.leaf() && (!best || n.count > best->count)) best = &n;
        }
    if (best && best->count > 0) {
        const glm::dvec3 c = 0.5 * (glm::dvec3(best->boundsMin) + glm::dvec3(best->boundsMax));
        const double r = std::max(20.0, glm::length(glm::dvec3(best->boundsMax) - glm::dvec3(best->boundsMin)));
        Camera cam;
        cam.yawDeg = 30.0;
        cam.pitchDeg = -30.0;
        cam.position = c - 2.4 * r * cam.forward();
        city.still = DemoStill{"city_atlas.png",
                               "Buildings of the scene (synth's facades, unique per building) through the "
                               "multiresolution texture-atlas tree, roofs from the leaf-on imagery clipmap",
                               cam, ImageryView::LeafOn};
        RenderSettings cs = settings;
        city::CitySettings cset;
        cset.mode = city::CityMode::Atlas;
        cs.city = cset;
        cs.cityTree = *tree;
        ImagerySettings im;
        im.view = ImageryView::LeafOn;
        auto ci = renderStills(scene, w, h, {{cam, im, out / city.still->file, {}, {}, {}}}, cs);
        if (!ci) return ci.error();
        char note[160];
        std::snprintf(note, sizeof note, "%zu atlas nodes in %s", nodes, tree->filename().c_str());
        city.note = note;
    }
    city.seconds = std::chrono::duration<double>(clock::now() - tc).count();
    return city;
}

// A short interleaved benchmark of the three level-centre placements along a flyover.
BenchSettings demoBenchSettings(int frames, const std::filesystem::path& cacheDir) {
    BenchSettings bs;
    bs.path = "flyover";
    bs.width = 640;
    bs.height = 360;
    bs.frames = frames;
    bs.warmup = 2;
    bs.clipmap.clipSize = 1024;
    bs.compare = "centers=concentric,offset,footprint";
    bs.cacheDir = cacheDir;
    return bs;
}

// The printed summary's table of the offline segmentation.
std::string segmentationTable(const std::vector<SegmentRow>& segmentation) {
    std::ostringstream table;
    for (const SegmentRow& row : segmentation) {
        const SegmentReport& r = row.report;
        char line[256];
        std::snprintf(line, sizeof line, "    %-13s k %d  precision %.3f  recall %.3f  F1 %.3f  IoU %.3f  centres P %.3f R %.3f  %.0f MP/s\n",
                      std::string(segmentationMethodName(row.method)).c_str(), row.k,
                      r.confusion ? r.confusion->precision() : 0.0, r.confusion ? r.confusion->recall() : 0.0,
                      r.confusion ? r.confusion->f1() : 0.0, r.confusion ? r.confusion->iou() : 0.0,
                      r.centres ? r.centres->precision() : 0.0, r.centres ? r.centres->recall() : 0.0,
                      r.segmentSeconds > 0.0 ? double(r.width) * r.height / 1e6 / r.segmentSeconds : 0.0);
        table << line;
    }
    return table.str();
}

// Everything the page and the printed summary report.
struct DemoRun {
    std::filesystem::path out, sceneDir;
    int width = 0, height = 0;
    bool cached = false;
    double synthSeconds = 0.0, renderSeconds = 0.0, segmentSeconds = 0.0;
    std::vector<DemoStill> stills;
    DemoCity city;
    std::optional<BenchResult> bench;
    BenchSettings benchSettings;
    std::vector<SegmentRow> segmentation;
    gl::ContextInfo device;
};

// The page's benchmark section.
void writeBenchHtml(std::ostringstream& html, const BenchResult& bench, const BenchSettings& bs) {
    html << "<h2>Benchmark</h2>\n<p>Flyover, " << bs.frames << " frames of " << bs.width << "&times;" << bs.height
         << ", clipmap levels of " << bs.clipmap.clipSize << "&sup2;, the three level-centre placements run interleaved on "
         << htmlEscape(bench.device) << " (<a href=\"bench/summary.json\">summary.json</a>, "
         << "<a href=\"bench/frames.csv\">frames.csv</a>). Ratios, not absolute times, are comparable across "
            "machines.</p>\n<table><tr><th>centers</th><th>median frame ms</th><th>ratio</th><th>mean coverage</th>"
            "<th>uploaded &divide; geometric minimum</th></tr>\n";
    for (const BenchModeResult& m : bench.modes) {
        char cells[256];
        std::snprintf(cells, sizeof cells, "<td>%.1f</td><td>%.3f</td><td>%.4f</td><td>%.3f</td>", m.medianFrameMs,
                      m.ratioToFirst, m.coverageMean, m.uploadOverMinimum);
        html << "<tr><td>" << htmlEscape(m.mode) << "</td>" << cells << "</tr>\n";
    }
    html << "</table>\n<figure><img src=\"bench/plot.png\" alt=\"frame time and coverage\"></figure>\n";
}

// The page's offline segmentation section.
void writeSegmentationHtml(std::ostringstream& html, const std::vector<SegmentRow>& segmentation) {
    const SegmentReport& any = segmentation.front().report;
    html << "<h2>Offline segmentation</h2>\n<p>Deciduous treetops found on the CPU by comparing the seasons ("
            "<code>seasonview segment</code>, the rule the canopy layers use on the GPU), each method on the "
         << any.width << "&times;" << any.height
         << " pair, scored per pixel against the generator's truth mask and per crown against its tree list "
            "(a detected crown centre counts when it lies within a true crown's radius). Throughput: the rule "
            "alone, on " << std::max(1u, std::thread::hardware_concurrency())
         << " threads (<a href=\"segment/metrics.json\">metrics.json</a>).</p>\n<table><tr><th>method</th><th>k</th>"
            "<th>precision</th><th>recall</th><th>F1</th><th>IoU</th><th>centres precision</th>"
            "<th>centres recall</th><th>MP/s</th></tr>\n";
    for (const SegmentRow& sr : segmentation) {
        const SegmentReport& r = sr.report;
        char cells[512];
        std::snprintf(cells, sizeof cells,
                      "<td>%d</td><td>%.3f</td><td>%.3f</td><td>%.3f</td><td>%.3f</td><td>%.3f</td><td>%.3f</td>"
                      "<td>%.0f</td>",
                      sr.k, r.confusion ? r.confusion->precision() : 0.0,
                      r.confusion ? r.confusion->recall() : 0.0, r.confusion ? r.confusion->f1() : 0.0,
                      r.confusion ? r.confusion->iou() : 0.0, r.centres ? r.centres->precision() : 0.0,
                      r.centres ? r.centres->recall() : 0.0,
                      r.segmentSeconds > 0.0 ? double(r.width) * r.height / 1e6 / r.segmentSeconds : 0.0);
        html << "<tr><td>" << segmentationMethodName(sr.method) << "</td>" << cells << "</tr>\n";
    }
    html << "</table>\n<figure><img src=\"segment/overlay.png\" alt=\"default method vs truth\"><figcaption>"
            "<code>default</code> against the truth, whole scene: <span style=\"color:#c9a800\">yellow</span> "
            "true positive, <span style=\"color:#d000a0\">magenta</span> false positive, "
            "<span style=\"color:#0090f0\">blue</span> false negative</figcaption></figure>"
            "<figure><img src=\"segment/overlay_crop.png\" alt=\"default method vs truth, centre\"><figcaption>"
            "The same at full resolution, the scene's centre</figcaption></figure>\n";
}

// index.html: the run's facts, the stills, the benchmark and the segmentation.
std::string demoPage(const DemoRun& run, const Scene& scene) {
    std::ostringstream html;
    html << "<!doctype html><html><head><meta charset=\"utf-8\"><title>seasonview demo</title><style>"
            "body{font-family:sans-serif;margin:2em;max-width:1400px}figure{display:inline-block;margin:0 1em 1em 0}"
            "img{max-width:640px;border:1px solid #888}table{border-collapse:collapse}"
            "td,th{border:1px solid #aaa;padding:3px 8px;text-align:left}</style></head><body>\n"
            "<h1>seasonview demo</h1>\n<p>Synthetic two-season scene generated by <code>seasonview synth</code>, "
            "rendered headless through the streamed texture clipmaps (level centres: footprint placement).</p>\n<table>\n";
    auto row = [&](const std::string& k, const std::string& v) {
        html << "<tr><th>" << htmlEscape(k) << "</th><td>" << htmlEscape(v) << "</td></tr>\n";
    };
    char buf[256];
    row("scene", (run.sceneDir / "scene.json").string());
    std::snprintf(buf, sizeof buf, "%dx%d px per season, %.2f m/px, %s", scene.leafon.info.width,
                  scene.leafon.info.height, scene.gsd, scene.frame.crs().name().c_str());
    row("imagery", buf);
    row("device", run.device.platform + ": " + run.device.renderer + " (" + run.device.version + ")");
    std::snprintf(buf, sizeof buf, "%s", run.cached ? "cached" : "");
    if (!run.cached) std::snprintf(buf, sizeof buf, "%.1f s", run.synthSeconds);
    row("scene generation", buf);
    std::snprintf(buf, sizeof buf, "%.2f s for %zu stills of %dx%d (includes texture upload)", run.renderSeconds,
                  run.stills.size(), run.width, run.height);
    row("rendering", buf);
    if (run.city.still) {
        std::snprintf(buf, sizeof buf, "%.1f s (atlas tree, cached after the first run; the still)", run.city.seconds);
        row("city", buf);
    }
    html << "</table>\n";
    std::vector<DemoStill> shown = run.stills;
    if (run.city.still) shown.push_back(*run.city.still);
    for (const DemoStill& s : shown)
        html << "<figure><img src=\"" << s.file << "\" alt=\"" << s.caption << "\"><figcaption>" << s.caption
             << " &mdash; camera <code>" << s.camera.toString() << "</code></figcaption></figure>\n";
    if (run.bench) writeBenchHtml(html, *run.bench, run.benchSettings);
    if (!run.segmentation.empty()) writeSegmentationHtml(html, run.segmentation);
    html << "<h2>Ground truth</h2>\n<figure><img src=\"scene/truth_deciduous.png\"><figcaption>Deciduous crowns"
            "</figcaption></figure><figure><img src=\"scene/truth_conifer.png\"><figcaption>Conifers</figcaption>"
            "</figure>\n</body></html>\n";
    return html.str();
}

// What the command prints when done.
void printDemoSummary(const DemoRun& run, const Scene& scene, double total) {
    const std::filesystem::path& out = run.out;
    std::printf("seasonview demo: %s\n", (out / "index.html").c_str());
    std::printf("  scene     %s (%dx%d px, %s)\n", run.cached ? "cached" : "generated", scene.leafon.info.width,
                scene.leafon.info.height, scene.frame.crs().name().c_str());
    for (const DemoStill& s : run.stills) std::printf("  still     %s\n", (out / s.file).c_str());
    if (run.city.still)
        std::printf("  city      %s (%s, %.1f s)\n", (out / run.city.still->file).c_str(), run.city.note.c_str(),
                    run.city.seconds);
    std::printf("  device    %s: %s\n", run.device.platform.c_str(), run.device.renderer.c_str());
    if (run.bench)
        std::printf("  bench     %s/bench (%s)\n%s", out.c_str(), run.bench->device.c_str(), run.bench->table.c_str());
    if (!run.segmentation.empty())
        std::printf("  segment   %s/segment (offline, against the truth)\n%s", out.c_str(),
                    segmentationTable(run.segmentation).c_str());
    std::printf("  time      %.1f s total (synth %.1f s, render %.1f s, segmentation %.1f s)\n", total,
                run.synthSeconds, run.renderSeconds, run.segmentSeconds);
}

} // namespace


Runner addDemoCommand(CLI::App& app) {
    auto args = std::make_shared<DemoArgs>();
    args->synth.sizeM = 2048.0;
    args->synth.gsd = 0.25;
    CLI::App* cmd = app.add_subcommand("demo", "Generate the synthetic demo scene (cached) and write stills + index.html");
    args->scene.addCacheTo(*cmd);
    args->frame.addTo(*cmd, "Still", {.camera = false, .window = true});
    cmd->add_option("--out", args->out, "Output folder")->capture_default_str()->group(kFrameGroup);
    cmd->add_option("--preset", args->preset, "Synthetic scene preset JSON (defaults are data/presets/demo.json's)");
    cmd->add_option("--size-m", args->synth.sizeM, "Synthetic scene side, metres")->capture_default_str();
    cmd->add_option("--gsd", args->synth.gsd, "Synthetic scene resolution, metres per pixel")->capture_default_str();
    cmd->add_option("--seed", args->synth.seed, "Synthetic scene seed")->capture_default_str();
    cmd->add_option("--bench-frames", args->benchFrames, "Frames of the demo's flyover benchmark (0: skip it)")
        ->capture_default_str();
    cmd->add_flag("--no-city", args->noCity, "Skip the still of the scene's buildings (and building their atlas tree)");
    return [args, cmd]() -> int {
        auto fail = [](const std::string& m) {
            std::fprintf(stderr, "seasonview demo: %s\n", m.c_str());
            return 1;
        };
        if (!args->preset.empty()) {
            auto preset = loadSynthPreset(args->preset);
            if (!preset) return fail(preset.message());
            if (cmd->count("--size-m") == 0) args->synth.sizeM = preset->sizeM;
            if (cmd->count("--gsd") == 0) args->synth.gsd = preset->gsd;
            if (cmd->count("--seed") == 0) args->synth.seed = preset->seed;
            args->synth.blockCity = preset->blockCity;
            args->synth.facadeSize = preset->facadeSize;
        }
        using clock = std::chrono::steady_clock;
        const auto t0 = clock::now();
        auto size = args->frame.frameSize();
        if (!size) return fail(size.message());
        DemoRun run;
        std::tie(run.width, run.height) = *size;
        run.out = args->out;
        run.sceneDir = run.out / "scene";
        std::error_code ec;
        std::filesystem::create_directories(run.out, ec);
        if (ec) return fail(run.out.string() + ": cannot create folder (" + ec.message() + ")");

        auto generated = ensureDemoScene(args->synth, run.sceneDir, run.synthSeconds);
        if (!generated) return fail(generated.message());
        run.cached = !*generated;
        SceneArgs sa;
        sa.manifest = (run.sceneDir / "scene.json").string();
        sa.cache = args->scene.cache;
        auto scene = sa.load();
        if (!scene) return fail(scene.message());
        printSceneNotes(*scene);

        run.stills = demoStills(*scene, double(run.width) / double(run.height));
        std::vector<StillRequest> requests;
        for (const DemoStill& s : run.stills) {
            ImagerySettings im;
            im.view = s.view;
            requests.push_back({s.camera, im, run.out / s.file, {}, {}, {}});
        }
        RenderSettings settings;
        settings.windowed = args->frame.window;
        settings.cacheDir = args->scene.cacheDir();
        {
            // The canopy view's layer for its default parameters, as `prepare` makes it: the stills, the benchmark and
            // `bench --view canopy` on this scene read it instead of deriving it while they fly.
            auto pyramids = preparePyramids(*scene, settings.cacheDir);
            if (!pyramids) return fail(pyramids.message());
            auto h = preparePairStats(*scene, *pyramids, settings.cacheDir);
            if (!h) return fail(h.message());
            const CanopyRenderSettings defaults;
            CanopyOptions co;
            co.params = defaults.params;
            co.layers = defaults.layers;
            auto p = canopyPyramid(*pyramids, co, statsFromHistograms(*h, co.params.method), settings.cacheDir, true);
            if (!p) return fail(p.message());
        }
        const auto tr = clock::now();
        auto info = renderStills(*scene, run.width, run.height, requests, settings);
        if (!info) return fail(info.message());
        run.device = *info;
        run.renderSeconds = std::chrono::duration<double>(clock::now() - tr).count();

        if (!args->noCity && !scene->sources.buildings.empty()) {
            auto city = renderCityStill(*scene, settings, run.out, run.width, run.height);
            if (!city) return fail(city.message());
            run.city = std::move(*city);
        }

        if (args->benchFrames >= 2) {
            run.benchSettings = demoBenchSettings(args->benchFrames, settings.cacheDir);
            std::printf("benchmarking a flyover (%d frames, 3 placements interleaved) ...\n", run.benchSettings.frames);
            std::fflush(stdout);
            auto r = runBench(*scene, run.benchSettings, run.out / "bench");
            if (!r) return fail(r.message());
            run.bench = std::move(*r);
        }

        // The offline segmentation against the generator's truth (a scene without truth has nothing to score).
        if (!scene->sources.truthDeciduous.empty()) {
            std::printf("segmenting the scene offline with each method (CPU, k %d) ...\n", kSegDefaultK);
            std::fflush(stdout);
            const auto ts = clock::now();
            auto rows = segmentDemo(*scene, run.out / "segment");
            if (!rows) return fail(rows.message());
            run.segmentation = std::move(*rows);
            run.segmentSeconds = std::chrono::duration<double>(clock::now() - ts).count();
        }

        std::string err;
        if (!writeTextAtomic(run.out / "index.html", demoPage(run, *scene), err))
            return fail((run.out / "index.html").string() + ": " + err);
        printDemoSummary(run, *scene, std::chrono::duration<double>(clock::now() - t0).count());
        return 0;
    };
}

} // namespace seasonview::app
