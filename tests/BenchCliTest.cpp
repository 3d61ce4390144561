// `seasonview bench` end to end on a tiny scene.
#include "TestUtil.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdlib>
#include <array>
#include <fstream>
#include <tuple>
#include <map>
#include <set>
#include <sstream>
#include <vector>

using namespace seasonview;
using namespace seasonview::test;

TEST(BenchCli, CompareWritesFramesSummaryCompareAndPlot) {
    TempDir dir("bench");
    const CliResult s = runCli({"synth", "--out", (dir / "scene").string(), "--size-m", "256", "--gsd", "0.5"});
    ASSERT_EQ(s.exitCode, 0) << s.err;
    const CliResult r = runCli({"bench", (dir / "scene/scene.json").string(), "--path", "flyover", "--frames", "6",
                                "--warmup", "1", "--size", "160x90", "--clip-size", "256", "--compare",
                                "centers=concentric,offset,footprint", "--cache", (dir / "cache").string(), "--out",
                                (dir / "out").string()});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(r.out.find("centers=footprint"), std::string::npos) << r.out;
    for (const char* f : {"frames.csv", "summary.json", "compare.json", "plot.png"})
        EXPECT_TRUE(std::filesystem::exists(dir / "out" / f)) << f;
    // The modes ran interleaved, frame by frame (run_order: the place among all measured frames as they ran).
    std::ifstream csv(dir / "out/frames.csv");
    std::string header;
    std::getline(csv, header);
    EXPECT_EQ(header.substr(0, 11), "mode,frame,");
    const std::size_t orderColumn = std::size_t(std::count(header.begin(), header.begin() + std::ptrdiff_t(header.find("run_order")), ','));
    ASSERT_NE(header.find("run_order"), std::string::npos);
    const std::vector<std::string> order = {"centers=concentric", "centers=offset", "centers=footprint"};
    int lines = 0;
    std::set<int> runOrders;
    for (std::string line; std::getline(csv, line); ++lines) {
        std::vector<std::string> cells;
        std::stringstream l(line);
        for (std::string c; std::getline(l, c, ',');) cells.push_back(c);
        ASSERT_GT(cells.size(), orderColumn);
        const int mode = int(std::find(order.begin(), order.end(), cells[0]) - order.begin());
        ASSERT_LT(mode, 3) << cells[0];
        const int frame = std::stoi(cells[1]), run = std::stoi(cells[orderColumn]);
        EXPECT_EQ(run, frame * 3 + mode) << line;
        runOrders.insert(run);
    }
    EXPECT_EQ(lines, 3 * 6);
    EXPECT_EQ(runOrders.size(), 18u);
    // The printed table: one row per mode with its ratio to the first.
    for (const auto& m : order) EXPECT_NE(r.out.find(m), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("ratio"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("1.000"), std::string::npos) << r.out;
    std::ifstream sj(dir / "out/summary.json");
    const auto summary = nlohmann::json::parse(sj);
    EXPECT_TRUE(summary["device"].contains("renderer"));
    const auto& m = summary["modes"]["centers=offset"];
    EXPECT_GT(m["frame_ms"]["median"].get<double>(), 0.0);
    EXPECT_TRUE(m["frame_ms"].contains("p95"));
    EXPECT_EQ(m["resident_texture_bytes_start"], m["resident_texture_bytes_end"]);
    EXPECT_GE(m["coverage"]["median"].get<double>(), 0.0);
    std::ifstream cj(dir / "out/compare.json");
    const auto compare = nlohmann::json::parse(cj);
    ASSERT_EQ(compare.size(), 3u);
    EXPECT_DOUBLE_EQ(compare[0]["ratio_to_first"].get<double>(), 1.0);
    // The plot is a real PNG with the curves drawn (not one flat colour).
    auto plot = readImageU8(dir / "out/plot.png", 3);
    ASSERT_TRUE(plot.ok()) << plot.message();
    EXPECT_GE(plot->width, 600);
    EXPECT_GE(plot->height, 300);
    std::set<std::uint32_t> colours;
    for (std::size_t i = 0; i + 2 < plot->pixels.size(); i += 3)
        colours.insert(std::uint32_t(plot->pixels[i]) << 16 | std::uint32_t(plot->pixels[i + 1]) << 8 | plot->pixels[i + 2]);
    EXPECT_GE(colours.size(), 4u) << "background, axes and one colour per mode";
    // Each mode's curves are drawn in the plot area (left of the legend), not only its legend swatch.
    for (const std::array<int, 3> c : {std::array<int, 3>{214, 39, 40}, {31, 119, 180}, {44, 160, 44}}) {
        std::size_t n = 0;
        for (int y = 0; y < plot->height; ++y)
            for (int x = 0; x < plot->width - 300; ++x)
                n += plot->at(x, y, 0) == c[0] && plot->at(x, y, 1) == c[1] && plot->at(x, y, 2) == c[2];
        EXPECT_GT(n, 200u) << c[0] << "," << c[1] << "," << c[2];
    }
}

// The canopy comparison (no canopy vs 16 layers with trunks) in one run: both modes draw, the canopy adds
// triangles and draw calls, its settings are recorded, and the per-frame uploads add up to the mode's total.
// Both comparisons that add the canopy: canopy=off,16 (leaf-on terrain vs the canopy view) and scene=terrain,full
// (the relief alone vs both seasons, 16 layers and trunks); canopy-draw=march,layers and
// segmentation=upload,perframe (canopy in both: the counters add up, re-deriving derives every frame). The canopy's counters (blocks derived, trunk searches) add up too.
TEST(BenchCli, CanopyCompareAddsLayersAndTrunks) {
    TempDir dir("bench-canopy");
    const CliResult s = runCli({"synth", "--out", (dir / "scene").string(), "--size-m", "256", "--gsd", "0.25"});
    ASSERT_EQ(s.exitCode, 0) << s.err;
    for (auto [compare, without, with] : {std::tuple{"canopy=off,16", "canopy=off", "canopy=16"},
                                          std::tuple{"scene=terrain,full", "scene=terrain", "scene=full"},
                                          std::tuple{"canopy-draw=march,layers", "canopy-draw=march", "canopy-draw=layers"},
                                          std::tuple{"segmentation=upload,perframe", "segmentation=upload",
                                                     "segmentation=perframe"}}) {
        // Both modes draw the canopy: what each draws depends on the blocks its own loader has brought so far.
        const bool bothCanopy = std::string(compare).find("=off") == std::string::npos &&
                                std::string(compare).rfind("scene=", 0) != 0;
        const bool perFrame = std::string(compare).rfind("segmentation=", 0) == 0;
        const std::string out = (dir / ("out-" + std::string(without))).string();
        const CliResult r = runCli({"bench", (dir / "scene/scene.json").string(), "--path", "flyover", "--frames", "4",
                                    "--warmup", "1", "--size", "160x90", "--clip-size", "512", "--view", "canopy",
                                    "--compare", compare, "--coverage-every", "0", "--cache",
                                    (dir / "cache").string(), "--stages", "issue", "--out", out});
        ASSERT_EQ(r.exitCode, 0) << r.err;
        {
            // --stages issue: the canopy view's stages of plain frames (no waits), in the order they run.
            std::ifstream st(out + "/stages.csv");
            std::map<std::string, std::vector<std::string>> order; // mode -> its first frame's stages
            std::string line;
            std::getline(st, line);
            for (; std::getline(st, line);) {
                std::vector<std::string> cells;
                std::stringstream l(line);
                for (std::string c; std::getline(l, c, ',');) cells.push_back(c);
                ASSERT_EQ(cells.size(), 5u) << line;
                EXPECT_EQ(std::stod(cells[4]), 0.0) << "issue mode waits for nothing: " << line;
                if (cells[1] == "0") order[cells[0]].push_back(cells[2]);
            }
            if (std::string(with) == "canopy=16") {
                const std::vector<std::string> want{"imagery_clipmap", "elevation_clipmap", "canopy_derive", "trunk_search",
                                                    "canopy_marched", "terrain", "canopy_layers", "trunks", "unmarked"};
                EXPECT_EQ(order[with], want);
                EXPECT_EQ(order[without], (std::vector<std::string>{"imagery_clipmap", "elevation_clipmap", "terrain",
                                                                    "unmarked"}));
            }
        }
        std::ifstream csv(out + "/frames.csv");
        std::string header;
        std::getline(csv, header);
        auto column = [&](const std::string& name) {
            std::stringstream h(header);
            int i = 0;
            for (std::string c; std::getline(h, c, ','); ++i)
                if (c == name) return i;
            return -1;
        };
        const int mode = column("mode"), tri = column("triangles"), draws = column("draw_calls"),
                  up = column("texels_uploaded"), derivedColumn = column("canopy_blocks_derived"),
                  searchColumn = column("trunk_searches"), elevColumn = column("elevation_texels_uploaded");
        ASSERT_GE(elevColumn, 0);
        ASSERT_GE(derivedColumn, 0);
        ASSERT_GE(searchColumn, 0);
        std::map<std::string, std::int64_t> derived, searches;
        std::map<std::string, std::vector<std::int64_t>> derivedPerFrame;
        ASSERT_GE(mode, 0);
        std::map<std::string, std::vector<std::int64_t>> triangles, drawCalls;
        std::map<std::string, std::int64_t> uploaded, elevationUploaded;
        for (std::string line; std::getline(csv, line);) {
            std::vector<std::string> cells;
            std::stringstream l(line);
            for (std::string c; std::getline(l, c, ',');) cells.push_back(c);
            triangles[cells[size_t(mode)]].push_back(std::stoll(cells[size_t(tri)]));
            drawCalls[cells[size_t(mode)]].push_back(std::stoll(cells[size_t(draws)]));
            uploaded[cells[size_t(mode)]] += std::stoll(cells[size_t(up)]);
            elevationUploaded[cells[size_t(mode)]] += std::stoll(cells[size_t(elevColumn)]);
            derived[cells[size_t(mode)]] += std::stoll(cells[size_t(derivedColumn)]);
            derivedPerFrame[cells[size_t(mode)]].push_back(std::stoll(cells[size_t(derivedColumn)]));
            searches[cells[size_t(mode)]] += std::stoll(cells[size_t(searchColumn)]);
        }
        ASSERT_EQ(triangles[without].size(), 4u) << compare;
        ASSERT_EQ(triangles[with].size(), 4u) << compare;
        for (size_t i = 0; i < 4; ++i) {
            if (!bothCanopy) {
                EXPECT_GT(triangles[with][i], triangles[without][i]) << compare << " " << i;
                EXPECT_GT(drawCalls[with][i], drawCalls[without][i]) << compare << " " << i;
            }
        }
        std::ifstream sj(out + "/summary.json");
        const auto summary = nlohmann::json::parse(sj);
        EXPECT_EQ(summary["settings"]["trunks"], "on");
        EXPECT_EQ(summary["settings"]["canopy_layers"], "16");
        EXPECT_EQ(summary["settings"]["ground_under_canopy"], "leafoff");
        EXPECT_EQ(summary["settings"]["compare"], compare);
        EXPECT_EQ(summary["settings"]["centers"], "footprint");
        EXPECT_EQ(summary["settings"]["renderer"], "clipmap");
        EXPECT_EQ(summary["settings"]["terrain_shading"], "auto");
        const bool software = summary["device"]["renderer"].get<std::string>().find("llvmpipe") != std::string::npos;
        EXPECT_EQ(summary["settings"]["terrain_shading_resolved"], software ? "deferred" : "forward");
        EXPECT_EQ(summary["settings"]["seed"], 1);
        for (const char* m : {without, with}) {
            // Counters add up: the per-frame uploads sum to what the clipmaps themselves counted over those frames.
            const auto& totals = summary["modes"][m]["totals"];
            EXPECT_EQ(totals["texels_uploaded"].get<std::int64_t>(), uploaded[m]) << m;
            EXPECT_EQ(totals["clipmap_reported_texels_uploaded"].get<std::int64_t>(), uploaded[m]) << m;
            EXPECT_EQ(totals["elevation_reported_texels_uploaded"].get<std::int64_t>(), elevationUploaded[m]) << m;
            // The relief alone streams no imagery (its elevation clipmap only); every other mode does.
            if (std::string(m) == "scene=terrain") {
                EXPECT_EQ(uploaded[m], 0) << m;
            } else {
                EXPECT_GT(uploaded[m], 0) << m;
            }
            for (const char* fig : {"draw_calls", "triangles", "loader_cache_bytes", "elevation_resident_bytes"})
                if (std::string(fig) != "loader_cache_bytes" || std::string(m) != "scene=terrain") {
                    EXPECT_GT(summary["modes"][m][fig]["max"].get<double>(), 0.0) << m << " " << fig;
                }
            EXPECT_EQ(summary["modes"][m]["totals"]["canopy_blocks_derived"].get<std::int64_t>(), derived[m]) << m;
            EXPECT_EQ(summary["modes"][m]["totals"]["trunk_searches"].get<std::int64_t>(), searches[m]) << m;
        }
        // Modes without a canopy derive nothing; re-deriving every frame derives every resident block every frame (the
        // blocks arriving meanwhile are the loader's affair, so upload-time counts are not pinned down here).
        if (!bothCanopy) {
            EXPECT_EQ(derived[without], 0) << compare;
        }
        if (perFrame) {
            for (size_t i = 0; i < 4; ++i) EXPECT_GT(derivedPerFrame[with][i], 0) << i;
        }
    }
    const CliResult bad = runCli({"bench", (dir / "scene/scene.json").string(), "--compare", "scene=terrain,city",
                                  "--out", (dir / "bad").string()});
    EXPECT_EQ(bad.exitCode, 1);
    EXPECT_NE(bad.err.find("scene 'city' (expected terrain|full)"), std::string::npos) << bad.err;
}

// canopy-levels=all,read: with `read` (the default) the canopy layer derives a block of a level finer than the
// trunks' (level 1 at 0.25 m, kept whole for their crown search) only once a canopy lookup has read it (the record
// comes back from the GPU a frame or two later). High over the scene no lookup reads level 0, so its blocks arriving
// as the windows move wait underived (canopy_blocks_unread) and none is derived on demand; `all` derives them. Low
// over the ground the nearest lookups read level 0 and those blocks are derived (canopy_blocks_on_demand). Once the
// camera has stood still a while both draw the same picture (last_frame_*.png).
TEST(BenchCli, CanopyLevelsReadDeriveOnlyTheBlocksTheViewReads) {
    TempDir dir("bench-canopy-levels");
    const CliResult s = runCli({"synth", "--out", (dir / "scene").string(), "--size-m", "256", "--gsd", "0.25"});
    ASSERT_EQ(s.exitCode, 0) << s.err;
    struct Row {
        std::int64_t derived = 0, unread = 0, onDemand = 0;
    };
    auto run = [&](const std::string& name, const std::string& keys, int frames, std::vector<std::string> extra = {}) {
        const std::filesystem::path path = dir / (name + ".json");
        std::ofstream(path) << keys;
        const std::string out = (dir / ("out-" + name)).string();
        std::vector<std::string> args = {"bench", (dir / "scene/scene.json").string(), "--path", path.string(),
                                         "--frames", std::to_string(frames), "--warmup", "2", "--size", "160x90",
                                         "--clip-size", "256", "--view", "canopy", "--compare",
                                         "canopy-levels=all,read", "--coverage-every", "0", "--cache",
                                         (dir / "cache").string(), "--out", out};
        args.insert(args.end(), extra.begin(), extra.end());
        const CliResult r = runCli(args);
        EXPECT_EQ(r.exitCode, 0) << r.err;
        std::map<std::string, std::vector<Row>> rows;
        std::ifstream csv(out + "/frames.csv");
        std::string header;
        std::getline(csv, header);
        std::vector<std::string> names;
        std::stringstream h(header);
        for (std::string c; std::getline(h, c, ',');) names.push_back(c);
        auto column = [&](const std::string& n) { return size_t(std::find(names.begin(), names.end(), n) - names.begin()); };
        const size_t derived = column("canopy_blocks_derived"), unread = column("canopy_blocks_unread"),
                     onDemand = column("canopy_blocks_on_demand");
        EXPECT_LT(onDemand, names.size());
        for (std::string line; std::getline(csv, line);) {
            std::vector<std::string> cells;
            std::stringstream l(line);
            for (std::string c; std::getline(l, c, ',');) cells.push_back(c);
            if (cells.size() != names.size()) {
                ADD_FAILURE() << line;
                continue;
            }
            rows[cells[0]].push_back({std::stoll(cells[derived]), std::stoll(cells[unread]), std::stoll(cells[onDemand])});
        }
        return rows;
    };
    auto sum = [](const std::vector<Row>& rows, std::int64_t Row::*field) {
        std::int64_t n = 0;
        for (const Row& r : rows) n += r.*field;
        return n;
    };
    // 300 m over the scene, straight down, crossing it: level 0's 64-m window moves ~20 m a frame.
    auto high = run("high", R"([{"time": 0, "x": -80, "y": -80, "z": "+300", "yaw": 45, "pitch": -89},
                                {"time": 1, "x": 80, "y": 80, "z": "+300", "yaw": 45, "pitch": -89}])", 10);
    ASSERT_EQ(high["canopy-levels=all"].size(), 10u);
    ASSERT_EQ(high["canopy-levels=read"].size(), 10u);
    EXPECT_EQ(sum(high["canopy-levels=all"], &Row::unread), 0);
    EXPECT_EQ(sum(high["canopy-levels=all"], &Row::onDemand), 0);
    EXPECT_GT(sum(high["canopy-levels=read"], &Row::unread), 0);
    EXPECT_EQ(sum(high["canopy-levels=read"], &Row::onDemand), 0);
    EXPECT_LT(sum(high["canopy-levels=read"], &Row::derived), sum(high["canopy-levels=all"], &Row::derived));
    // 3 m over the ground looking ahead, moving, then standing still.
    auto low = run("low", R"([{"time": 0, "x": -60, "y": -60, "z": "+3", "yaw": 45, "pitch": -20},
                               {"time": 1, "x": -30, "y": -30, "z": "+3", "yaw": 45, "pitch": -20},
                               {"time": 3, "x": -30, "y": -30, "z": "+3", "yaw": 45, "pitch": -20}])", 24);
    ASSERT_EQ(low["canopy-levels=read"].size(), 24u);
    EXPECT_GT(sum(low["canopy-levels=read"], &Row::onDemand), 0);
    // The same canopy once still: no pixel shows another season or a tree the other lacks (differences of a few
    // levels where one mode's imagery loader, which frames never wait for, is a tile behind the other's on a loaded
    // machine).
    auto samePicture = [&](const std::string& out) {
        auto all = readImageU8(dir / out / "last_frame_canopy-levels_all.png", 3);
        auto read = readImageU8(dir / out / "last_frame_canopy-levels_read.png", 3);
        ASSERT_TRUE(all.ok()) << all.message();
        ASSERT_TRUE(read.ok()) << read.message();
        ASSERT_EQ(all->pixels.size(), read->pixels.size());
        int strong = 0;
        for (std::size_t i = 0; i + 2 < all->pixels.size(); i += 3) {
            int d = 0;
            for (int c = 0; c < 3; ++c) d = std::max(d, std::abs(int(all->pixels[i + c]) - int(read->pixels[i + c])));
            strong += d > 24 ? 1 : 0;
        }
        EXPECT_LE(strong, int(all->pixels.size() / 3 / 1000)) << out << ": " << strong << " pixels differ by more than 24";
        std::set<std::uint32_t> colours;
        for (std::size_t i = 0; i + 2 < read->pixels.size(); i += 3)
            colours.insert(std::uint32_t(read->pixels[i]) << 16 | std::uint32_t(read->pixels[i + 1]) << 8 | read->pixels[i + 2]);
        EXPECT_GT(colours.size(), 100u) << out << ": a drawn view";
    };
    samePicture("out-low");
    // The ground alone (no layers, so no trunks and no level kept whole): only the ground's own lookups, recorded on
    // the GPU, bring the level-0 blocks under the nearest pixels in.
    const std::string lowKeys = R"([{"time": 0, "x": -60, "y": -60, "z": "+3", "yaw": 45, "pitch": -20},
                                    {"time": 1, "x": -30, "y": -30, "z": "+3", "yaw": 45, "pitch": -20},
                                    {"time": 3, "x": -30, "y": -30, "z": "+3", "yaw": 45, "pitch": -20}])";
    auto ground = run("ground", lowKeys, 24, {"--canopy-layers", "off"});
    ASSERT_EQ(ground["canopy-levels=read"].size(), 24u);
    EXPECT_GT(sum(ground["canopy-levels=read"], &Row::onDemand), 0);
    samePicture("out-ground");
}

// canopy-pyramid=off,on: `on` builds the canopy layer for the view's parameters (once, into the cache) and reads it
// instead of deriving its blocks; `off` derives them; without the key a prepared layer is read where the cache has
// one. The layer holds the derived bytes (CanopyClipmapGLTest), so once still both draw the same picture.
TEST(BenchCli, CanopyPyramidReadsThePreparedLayer) {
    TempDir dir("bench-canopy-pyramid");
    const CliResult s = runCli({"synth", "--out", (dir / "scene").string(), "--size-m", "256", "--gsd", "0.25"});
    ASSERT_EQ(s.exitCode, 0) << s.err;
    std::ofstream(dir / "still.json") << R"([{"time": 0, "x": -60, "y": -60, "z": "+30", "yaw": 45, "pitch": -30},
                                            {"time": 1, "x": -60, "y": -60, "z": "+30", "yaw": 45, "pitch": -30}])";
    auto bench = [&](const std::string& out, std::vector<std::string> extra) {
        std::vector<std::string> args = {"bench", (dir / "scene/scene.json").string(), "--path",
                                         (dir / "still.json").string(), "--frames", "12", "--warmup", "2", "--size",
                                         "160x90", "--clip-size", "256", "--view", "canopy", "--coverage-every", "0",
                                         "--cache", (dir / "cache").string(), "--out", (dir / out).string()};
        args.insert(args.end(), extra.begin(), extra.end());
        return runCli(args);
    };
    // The one mode's canopy_source, or the named mode's.
    auto source = [&](const std::string& out, const std::string& mode = "") {
        std::ifstream in(dir / out / "summary.json");
        const nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
        if (!j.is_object() || !j.contains("modes")) return std::string("(no summary)");
        const nlohmann::json& m = mode.empty() ? j["modes"].begin().value() : j["modes"][mode];
        return m.value("canopy_source", std::string());
    };
    // Nothing prepared yet: derived.
    const CliResult before = bench("before", {});
    ASSERT_EQ(before.exitCode, 0) << before.err;
    const CliResult r = bench("compare", {"--compare", "canopy-pyramid=off,on"});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(r.out.find("prepared the canopy layer (default, k 5, 16 layers)"), std::string::npos) << r.out;
    EXPECT_EQ(source("compare", "canopy-pyramid=off"), "cpu");
    EXPECT_EQ(source("compare", "canopy-pyramid=on"), "precomputed");
    auto off = readImageU8(dir / "compare/last_frame_canopy-pyramid_off.png", 3);
    auto on = readImageU8(dir / "compare/last_frame_canopy-pyramid_on.png", 3);
    ASSERT_TRUE(off.ok()) << off.message();
    ASSERT_TRUE(on.ok()) << on.message();
    EXPECT_EQ(off->pixels, on->pixels);
    // Now prepared: read without asking, and not built again.
    const CliResult after = bench("after", {});
    ASSERT_EQ(after.exitCode, 0) << after.err;
    EXPECT_EQ(after.out.find("prepared the canopy layer"), std::string::npos) << after.out;
    EXPECT_EQ(source("before"), "cpu");
    EXPECT_EQ(source("after"), "precomputed");
    const CliResult bad = bench("bad", {"--compare", "canopy-pyramid=off,maybe"});
    EXPECT_EQ(bad.exitCode, 1);
    EXPECT_NE(bad.err.find("canopy-pyramid 'maybe' (expected off|on)"), std::string::npos) << bad.err;
}

// Counters add up where both clipmaps stream: a 4 km scene with a 4 m DEM (1024² samples) under a 63-vertex
// geometry clipmap and 256² imagery levels, on the `fast` path. Every frame's uploads in frames.csv sum to what the
// imagery and elevation clipmaps themselves counted, and both uploaded in several frames. Frames never wait for the
// loaders: 30 frames (not fewer) leave their threads time to deliver on a loaded machine.
TEST(BenchCli, CountersAddUpWhileBothClipmapsStream) {
    TempDir dir("bench-stream");
    const CliResult s = runCli({"synth", "--out", (dir / "scene").string(), "--size-m", "4096", "--gsd", "4",
                                "--dem-spacing", "4"});
    ASSERT_EQ(s.exitCode, 0) << s.err;
    const CliResult r = runCli({"bench", (dir / "scene/scene.json").string(), "--path", "fast", "--frames", "30",
                                "--warmup", "1", "--size", "160x90", "--coverage-every", "0", "--clip-size", "256",
                                "--grid-size", "63", "--cache", (dir / "cache").string(), "--out",
                                (dir / "out").string()});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    std::ifstream csv(dir / "out/frames.csv");
    std::string header;
    std::getline(csv, header);
    std::vector<std::string> names;
    {
        std::stringstream h(header);
        for (std::string c; std::getline(h, c, ',');) names.push_back(c);
    }
    auto column = [&](const std::string& name) {
        return int(std::find(names.begin(), names.end(), name) - names.begin());
    };
    const int up = column("texels_uploaded"), elev = column("elevation_texels_uploaded"),
              elevResident = column("elevation_resident_bytes");
    ASSERT_LT(elev, int(names.size()));
    ASSERT_LT(elevResident, int(names.size()));
    std::int64_t imagery = 0, elevation = 0;
    int imageryFrames = 0, elevationFrames = 0, rows = 0;
    for (std::string line; std::getline(csv, line); ++rows) {
        std::vector<std::string> cells;
        std::stringstream l(line);
        for (std::string c; std::getline(l, c, ',');) cells.push_back(c);
        ASSERT_EQ(cells.size(), names.size()) << line;
        const std::int64_t a = std::stoll(cells[size_t(up)]), b = std::stoll(cells[size_t(elev)]);
        imagery += a;
        elevation += b;
        imageryFrames += a > 0;
        elevationFrames += b > 0;
        EXPECT_GT(std::stoll(cells[size_t(elevResident)]), 0) << "row " << rows;
    }
    EXPECT_EQ(rows, 30);
    std::ifstream sj(dir / "out/summary.json");
    const auto summary = nlohmann::json::parse(sj);
    ASSERT_EQ(summary["modes"].size(), 1u);
    const auto& totals = summary["modes"].begin().value()["totals"];
    EXPECT_EQ(totals["texels_uploaded"].get<std::int64_t>(), imagery);
    EXPECT_EQ(totals["clipmap_reported_texels_uploaded"].get<std::int64_t>(), imagery);
    EXPECT_EQ(totals["elevation_texels_uploaded"].get<std::int64_t>(), elevation);
    EXPECT_EQ(totals["elevation_reported_texels_uploaded"].get<std::int64_t>(), elevation);
    EXPECT_GT(imagery, 0);
    EXPECT_GT(elevation, 0) << "the elevation clipmap streamed";
    EXPECT_GE(imageryFrames, 2);
    EXPECT_GE(elevationFrames, 3);
}

TEST(BenchCli, BadPathAndCompareAreOneLineErrors) {
    TempDir dir("bench-bad");
    ASSERT_TRUE(writeTestPair(dir.path(), 64, 48, 1.0).ok());
    for (auto extra : std::vector<std::vector<std::string>>{{"--path", "spiral"}, {"--compare", "canopy"},
                                                            {"--compare", "centers=offset,diagonal"},
                                                            {"--compare", "aniso=1,99"}}) {
        std::vector<std::string> args = {"bench", "--leafon", (dir / "on.tif").string(), "--leafoff",
                                         (dir / "off.tif").string(), "--cache", (dir / "cache").string(), "--out",
                                         (dir / "out").string()};
        args.insert(args.end(), extra.begin(), extra.end());
        const CliResult r = runCli(args);
        EXPECT_EQ(r.exitCode, 1) << extra[1];
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    }
}
