// `seasonview view` without a person: a script pans and zooms the map, switches the season, drags the swipe bar and
// toggles the canopy layers; timed screenshots are compared with golden images and with each other; the flight is
// recorded and replayed by `bench` through the same camera poses. Runs under xvfb-run when there is no display
// (skipped only when neither exists).
#include "TestUtil.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

using namespace seasonview;
using namespace seasonview::test;

namespace {

std::vector<std::vector<std::string>> readCsv(const std::filesystem::path& p) {
    std::ifstream f(p);
    std::vector<std::vector<std::string>> rows;
    std::string line;
    while (std::getline(f, line)) {
        std::vector<std::string> cells;
        std::stringstream ss(line);
        std::string c;
        while (std::getline(ss, c, ',')) cells.push_back(c);
        rows.push_back(cells);
    }
    return rows;
}

// Mean absolute difference over the columns [x0, x1) of two same-size RGB images.
double meanDiff(const Image<std::uint8_t>& a, const Image<std::uint8_t>& b, int x0, int x1) {
    double sum = 0.0;
    long n = 0;
    for (int y = 0; y < a.height; ++y)
        for (int x = x0; x < x1; ++x)
            for (int c = 0; c < 3; ++c, ++n) sum += std::abs(int(a.at(x, y, c)) - int(b.at(x, y, c)));
    return n ? sum / double(n) : 0.0;
}

} // namespace

TEST(ViewCliTest, ScriptedSessionScreenshotsAndRecordedPath) {
    TempDir dir("view-cli");
    const CliResult synth = runCli({"synth", "--size-m", "256", "--gsd", "0.5", "--seed", "11", "--out", (dir / "scene").string()});
    ASSERT_EQ(synth.exitCode, 0) << synth.err;
    const std::string scene = (dir / "scene/scene.json").string();
    // Window 320x240; the overview camera looks straight down, so the viewer starts in map mode.
    const nlohmann::json script = nlohmann::json::parse(R"([
        {"t": 0.2, "drag": [[200, 150], [140, 110]], "duration": 0.3},
        {"t": 0.8, "wheel": 3, "at": [160, 120]},
        {"t": 1.6, "key": "2"},
        {"t": 1.9, "key": "4"},
        {"t": 2.0, "drag": [[160, 100], [80, 100]], "duration": 0.2},
        {"t": 2.4, "key": "5"},
        {"t": 2.55, "set": "canopy_draw", "value": "layers"},
        {"t": 2.8, "key": "C"},
        {"t": 3.1, "key": "F"},
        {"t": 3.2, "hold": "W", "duration": 0.4},
        {"t": 1.55, "key": "K"},
        {"t": 3.65, "key": "J"}
    ])");
    {
        std::ofstream f(dir / "script.json");
        f << script.dump(1);
    }
    auto png = [&](const char* name) { return (dir / name).string(); };
    const auto r = runCliWithDisplay({"view", scene, "--size", "320x240", "--cache", (dir / "cache").string(),
                                      "--script", (dir / "script.json").string(), "--record", png("rec.json"),
                                      "--bookmarks", png("bookmarks.json"),
                                      "--screenshot-at", std::string("1.5:") + png("leafon.png"),
                                      "--screenshot-at", std::string("1.8:") + png("leafoff.png"),
                                      "--screenshot-at", std::string("2.3:") + png("swipe.png"),
                                      "--screenshot-at", std::string("2.5:") + png("canopy_march.png"),
                                      "--screenshot-at", std::string("2.7:") + png("canopy.png"),
                                      "--screenshot-at", std::string("3.0:") + png("canopy_off.png"),
                                      "--quit-at", "3.75"});
    if (!r) GTEST_SKIP() << "no DISPLAY and no xvfb-run: the viewer needs a window";
    ASSERT_EQ(r->exitCode, 0) << r->err;

    std::map<std::string, Image<std::uint8_t>> shots;
    for (const char* name : {"leafon", "leafoff", "swipe", "canopy", "canopy_off"}) {
        auto img = readImageU8(dir / (std::string(name) + ".png"), 3);
        ASSERT_TRUE(img.ok()) << name << ": " << img.message();
        ASSERT_EQ(img->width, 320);
        ASSERT_EQ(img->height, 240);
        // llvmpipe is deterministic; the tolerance covers a different Mesa build's rounding.
        const ImageDiff d = compareWithGolden(std::string("view_") + name, img->pixels, 320, 240, 255, 3.0);
        EXPECT_LE(d.meanDelta, 3.0) << name;
        shots[name] = std::move(*img);
    }
    // The season switch changed the picture; the swipe shows leaf-on left of the bar dragged to x = 80 and leaf-off
    // right of it, with the 2-pixel white bar itself at columns 79 and 80.
    EXPECT_GT(meanDiff(shots["leafon"], shots["leafoff"], 0, 320), 10.0);
    EXPECT_LT(meanDiff(shots["swipe"], shots["leafon"], 0, 78), 1.0);
    EXPECT_LT(meanDiff(shots["swipe"], shots["leafoff"], 82, 320), 1.0);
    int white = 0;
    for (int y = 0; y < 240; ++y)
        white += shots["swipe"].at(79, y, 0) == 255 && shots["swipe"].at(80, y, 1) == 255 ? 1 : 0;
    EXPECT_GT(white, 200) << "the swipe bar follows the drag to x = 80";
    // The canopy layers (C toggles them off) change the canopy view.
    EXPECT_GT(meanDiff(shots["canopy"], shots["canopy_off"], 0, 320), 1.0);
    EXPECT_GT(meanDiff(shots["canopy"], shots["leafon"], 0, 320), 1.0);
    // The layers marched (the default, before the `set` at 2.55 s) and rasterised (the golden's) show the same
    // canopy but for crown edges.
    auto march = readImageU8(dir / "canopy_march.png", 3);
    ASSERT_TRUE(march.ok()) << march.message();
    const double modes = meanDiff(*march, shots["canopy"], 0, 320);
    EXPECT_GT(modes, 0.0) << "the set event switched the draw mode";
    EXPECT_LT(modes, 3.0);
    EXPECT_GT(meanDiff(*march, shots["canopy_off"], 0, 320), 2.0 * modes);

    // The recorded flight (a keyframe every 8 frames of 1/30 s from t = 0) replays in `bench` through the same poses:
    // with one frame per keyframe the path hits each keyframe exactly.
    std::ifstream rf(dir / "rec.json");
    ASSERT_TRUE(rf.good());
    const auto keys = nlohmann::json::parse(rf);
    ASSERT_EQ(keys.size(), 15u); // t = 0, 8/30, ..., 112/30 (3.73 s) before quitting at 3.75 s
    EXPECT_NEAR(keys[1].at("time").get<double>(), 8.0 / 30.0, 1e-12);
    // The fly phase (F, then W held) moved the camera along its view, straight down from the map view.
    const auto& lastKey = keys[keys.size() - 1];
    EXPECT_LT(keys[keys.size() - 2].at("z").get<double>(), keys[keys.size() - 5].at("z").get<double>() - 1.0);
    // K saved the camera of the leaf-on screenshot as a bookmark; J at 3.65 s jumped back to it at once (no easing),
    // so the last keyframe (3.73 s) is that camera again.
    std::ifstream bf(dir / "bookmarks.json");
    ASSERT_TRUE(bf.good());
    const auto marks = nlohmann::json::parse(bf);
    ASSERT_EQ(marks.size(), 1u);
    double mark[6] = {0, 0, 0, 0, 0, 0};
    ASSERT_EQ(std::sscanf(marks[0].get<std::string>().c_str(), "%lf,%lf,%lf,%lf,%lf,%lf", &mark[0], &mark[1], &mark[2],
                          &mark[3], &mark[4], &mark[5]),
              6);
    EXPECT_NEAR(lastKey.at("x").get<double>(), mark[0], 1e-6);
    EXPECT_NEAR(lastKey.at("y").get<double>(), mark[1], 1e-6);
    EXPECT_NEAR(lastKey.at("z").get<double>(), mark[2], 1e-6);
    EXPECT_NEAR(keys[6].at("z").get<double>(), mark[2], 0.02) << "the map camera after the zoom (1.6 s), still easing in";

    const CliResult b = runCli({"bench", scene, "--cache", (dir / "cache").string(), "--path", png("rec.json"), "--frames",
                                std::to_string(keys.size()), "--warmup", "0", "--size", "80x60", "--coverage-every", "0",
                                "--out", png("bench")});
    ASSERT_EQ(b.exitCode, 0) << b.err;
    const auto rows = readCsv(dir / "bench/frames.csv");
    ASSERT_EQ(rows.size(), keys.size() + 1);
    for (size_t i = 0; i < keys.size(); ++i) {
        const auto& row = rows[i + 1]; // mode,frame,x,y,z,yaw,pitch,...
        EXPECT_NEAR(std::stod(row[2]), keys[i].at("x").get<double>(), 2e-3) << "frame " << i;
        EXPECT_NEAR(std::stod(row[3]), keys[i].at("y").get<double>(), 2e-3) << "frame " << i;
        EXPECT_NEAR(std::stod(row[4]), keys[i].at("z").get<double>(), 2e-3) << "frame " << i;
        const double dyaw = std::remainder(std::stod(row[5]) - keys[i].at("yaw").get<double>(), 360.0);
        EXPECT_NEAR(dyaw, 0.0, 2e-3) << "frame " << i;
        EXPECT_NEAR(std::stod(row[6]), keys[i].at("pitch").get<double>(), 2e-3) << "frame " << i;
    }
}

// The options view shares with render (CliOptions.h) mean the same in both: a viewer screenshot with the blend view,
// a blend weight, relief shading and isotropic filtering is the still `render` makes with the same options and camera,
// and differs from the still with render's defaults for those options.
TEST(ViewCliTest, SharedOptionsMeanWhatTheyMeanInRender) {
    TempDir dir("view-cli-shared");
    const CliResult synth = runCli({"synth", "--size-m", "256", "--gsd", "0.5", "--seed", "11", "--no-city", "--out",
                                    (dir / "scene").string()});
    ASSERT_EQ(synth.exitCode, 0) << synth.err;
    const std::string scene = (dir / "scene/scene.json").string(), cache = (dir / "cache").string();
    const std::vector<std::string> shared = {"--camera", "10,-120,+60,20,-35", "--view", "blend", "--blend", "0.2",
                                             "--shade", "0.8", "--aniso", "1", "--clip-size", "1024"};
    std::vector<std::string> view = {"view", scene, "--size", "320x240", "--cache", cache, "--no-panel",
                                     "--screenshot-at", "0:" + (dir / "view.png").string(), "--quit-at", "0.05"};
    view.insert(view.end(), shared.begin(), shared.end());
    const auto v = runCliWithDisplay(view);
    if (!v) GTEST_SKIP() << "no DISPLAY and no xvfb-run: the viewer needs a window";
    ASSERT_EQ(v->exitCode, 0) << v->err;
    auto render = [&](const std::string& out, const std::vector<std::string>& options) {
        std::vector<std::string> a = {"render", scene, "--size", "320x240", "--cache", cache, "--out", (dir / out).string()};
        a.insert(a.end(), options.begin(), options.end());
        const CliResult r = runCli(a);
        EXPECT_EQ(r.exitCode, 0) << r.err;
        auto img = readImageU8(dir / out, 3);
        EXPECT_TRUE(img.ok()) << img.message();
        return img.ok() ? *img : Image<std::uint8_t>{};
    };
    const Image<std::uint8_t> same = render("same.png", shared);
    const Image<std::uint8_t> defaults =
        render("defaults.png", {"--camera", "10,-120,+60,20,-35", "--view", "blend", "--clip-size", "1024"});
    auto shot = readImageU8(dir / "view.png", 3);
    ASSERT_TRUE(shot.ok()) << shot.message();
    ASSERT_EQ(same.width, 320);
    ASSERT_EQ(defaults.width, 320);
    // The same renderer with every texel resident: the same pixels (byte for byte on llvmpipe).
    EXPECT_LT(meanDiff(*shot, same, 0, 320), 0.05);
    EXPECT_GT(meanDiff(same, defaults, 0, 320), 2.0) << "--blend and --shade change the still";
    EXPECT_GT(meanDiff(*shot, defaults, 0, 320), 2.0) << "the viewer takes --blend and --shade";
}

TEST(ViewCliTest, BadArgumentsFailWithOneLine) {
    TempDir dir("view-cli-bad");
    {
        std::ofstream f(dir / "bad.json");
        f << R"([{"t": 1, "key": "NoSuchKey"}])";
    }
    auto pair = writeTestPair(dir.path(), 64, 64, 1.0);
    ASSERT_TRUE(pair.ok());
    const std::string on = (dir / "on.tif").string(), off = (dir / "off.tif").string();
    const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
        {{"--script", (dir / "missing.json").string()}, "missing.json: file not found"},
        {{"--script", (dir / "bad.json").string()}, "unknown key 'NoSuchKey'"},
        {{"--screenshot-at", "x:a.png"}, "--screenshot-at 'x:a.png'"},
        {{"--screenshot-at", "1:a.jpg2"}, "a.jpg2"},
        {{"--mode", "walk"}, "--mode 'walk'"},
        {{"--view", "sideways"}, "--view 'sideways'"},
        // The options shared with render and bench (CliOptions.h) are checked as render checks them.
        {{"--grid-size", "100"}, "--grid-size 100: expected 2^k - 1"},
        {{"--clip-size", "100"}, "--clip-size 100"},
        {{"--terrain", "off"}, "--terrain off draws only the city"},
        {{"--ground-elsewhere", "autumn"}, "--ground-elsewhere 'autumn'"},
        {{"--window-screenshot-at", "x:a.png"}, "--window-screenshot-at 'x:a.png'"},
    };
    for (const auto& [extra, message] : cases) {
        std::vector<std::string> args = {"view", "--leafon", on, "--leafoff", off, "--cache", (dir / "cache").string()};
        args.insert(args.end(), extra.begin(), extra.end());
        // These fail before any window opens: no display needed.
        const CliResult r = runCli(args);
        EXPECT_EQ(r.exitCode, 1) << extra[0];
        EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    }
}
