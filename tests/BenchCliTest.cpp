// `seasonview bench` end to end on a tiny scene.
#include "TestUtil.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>

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
    std::ifstream csv(dir / "out/frames.csv");
    int lines = 0;
    for (std::string line; std::getline(csv, line);) ++lines;
    EXPECT_EQ(lines, 1 + 3 * 6);
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
