// `seasonview demo` end to end on a small scene: the page and every image it shows exist, the canopy and city
// stills among them, the bench it ran left its files, and the offline segmentation scored every method against the truth.
#include "TestUtil.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

using namespace seasonview;
using namespace seasonview::test;

TEST(DemoCliTest, IndexHtmlAndEveryImageItShowsExist) {
    TempDir dir("demo-cli");
    const CliResult r = runCli({"demo", "--out", (dir / "out").string(), "--size-m", "512", "--gsd", "0.5", "--size",
                                "320x180", "--bench-frames", "2", "--cache", (dir / "cache").string()});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    std::ifstream f(dir / "out/index.html");
    ASSERT_TRUE(f.good());
    std::stringstream ss;
    ss << f.rdbuf();
    const std::string html = ss.str();
    const std::regex img("<img src=\"([^\"]+)\"");
    int images = 0;
    bool canopy = false, city = false;
    for (auto it = std::sregex_iterator(html.begin(), html.end(), img); it != std::sregex_iterator(); ++it) {
        const std::string src = (*it)[1];
        EXPECT_TRUE(std::filesystem::is_regular_file(dir / "out" / src)) << src;
        EXPECT_GT(std::filesystem::file_size(dir / "out" / src), 1000u) << src;
        canopy = canopy || src == "canopy_trunks.png";
        city = city || src == "city_atlas.png";
        ++images;
    }
    EXPECT_GE(images, 10);
    EXPECT_TRUE(canopy);
    EXPECT_TRUE(city) << "512 m at seed 1 has a village: its buildings get a still through their atlas tree";
    for (const char* file : {"bench/summary.json", "bench/frames.csv", "bench/plot.png"})
        EXPECT_TRUE(std::filesystem::is_regular_file(dir / "out" / file)) << file;

    // The offline segmentation: every method scored against the truth, in the page and in metrics.json; the
    // full-size overlay not left behind.
    EXPECT_NE(html.find("Offline segmentation"), std::string::npos);
    std::ifstream mf(dir / "out/segment/metrics.json");
    ASSERT_TRUE(mf.good());
    const auto metrics = nlohmann::json::parse(mf);
    ASSERT_EQ(metrics.size(), 4u);
    std::vector<std::string> methods;
    for (const auto& m : metrics) {
        methods.push_back(m.at("method").get<std::string>());
        for (const char* key : {"precision", "recall", "f1", "iou", "centres_precision", "centres_recall"}) {
            EXPECT_GE(m.at(key).get<double>(), 0.0) << key;
            EXPECT_LE(m.at(key).get<double>(), 1.0) << key;
        }
        EXPECT_GT(m.at("megapixels_per_second").get<double>(), 0.0);
        EXPECT_TRUE(std::filesystem::is_regular_file(dir / "out/segment" / (methods.back() + ".png")));
        EXPECT_NE(html.find("<td>" + methods.back() + "</td>"), std::string::npos) << methods.back();
    }
    EXPECT_EQ(methods, (std::vector<std::string>{"pixel", "neighborhood", "equalized", "default"}));
    // The default method finds the synthetic crowns (on this small scene too).
    EXPECT_GT(metrics[3].at("f1").get<double>(), 0.5);
    for (const char* file : {"segment/overlay.png", "segment/overlay_crop.png", "segment/trees.csv"})
        EXPECT_TRUE(std::filesystem::is_regular_file(dir / "out" / file)) << file;
    EXPECT_FALSE(std::filesystem::exists(dir / "out/segment/overlay_full.tif"));

    // The printed summary: the page, the scene generated, every still, the bench table, the segmentation's scores.
    EXPECT_NE(r.out.find("seasonview demo: " + (dir / "out/index.html").string()), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("scene     generated"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("prepared leafon pyramid"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("built the atlas tree"), std::string::npos) << r.out;
    for (auto it = std::sregex_iterator(html.begin(), html.end(), img); it != std::sregex_iterator(); ++it)
        if (std::string((*it)[1]).find('/') == std::string::npos) {
            EXPECT_NE(r.out.find((dir / "out" / std::string((*it)[1])).string()), std::string::npos) << (*it)[1];
        }
    for (const char* m : {"centers=concentric", "centers=offset", "centers=footprint", "ratio"})
        EXPECT_NE(r.out.find(m), std::string::npos) << m;
    for (const auto& m : methods) EXPECT_NE(r.out.find("    " + m + " "), std::string::npos) << m;

    // Run again: the scene, its pyramids and the city's tree come from the caches (nothing regenerated or prepared)
    // and the stills are the same images.
    const auto sceneTime = std::filesystem::last_write_time(dir / "out/scene/leafon.tif");
    std::map<std::string, std::string> before;
    for (const auto& e : std::filesystem::directory_iterator(dir / "out"))
        if (e.path().extension() == ".png") before[e.path().filename().string()] = readBytes(e.path());
    const CliResult again = runCli({"demo", "--out", (dir / "out").string(), "--size-m", "512", "--gsd", "0.5",
                                    "--size", "320x180", "--bench-frames", "2", "--cache", (dir / "cache").string()});
    ASSERT_EQ(again.exitCode, 0) << again.err;
    EXPECT_NE(again.out.find("scene     cached"), std::string::npos) << again.out;
    EXPECT_EQ(again.out.find("prepared "), std::string::npos) << again.out;
    EXPECT_EQ(again.out.find("built the atlas tree"), std::string::npos) << again.out;
    EXPECT_EQ(std::filesystem::last_write_time(dir / "out/scene/leafon.tif"), sceneTime);
    EXPECT_GE(before.size(), 10u);
    for (const auto& [name, bytes] : before) EXPECT_EQ(readBytes(dir / "out" / name), bytes) << name;
}
