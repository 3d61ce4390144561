// `seasonview demo` end to end on a small scene: the page and every image it shows exist, the canopy still among
// them, and the bench it ran left its files.
#include "TestUtil.h"

#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <sstream>

using namespace seasonview;
using namespace seasonview::test;

TEST(DemoCliTest, IndexHtmlAndEveryImageItShowsExist) {
    TempDir dir("demo-cli");
    const CliResult r = runCli({"demo", "--out", (dir / "out").string(), "--size-m", "256", "--gsd", "0.5", "--size",
                                "320x180", "--bench-frames", "2", "--cache", (dir / "cache").string()});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    std::ifstream f(dir / "out/index.html");
    ASSERT_TRUE(f.good());
    std::stringstream ss;
    ss << f.rdbuf();
    const std::string html = ss.str();
    const std::regex img("<img src=\"([^\"]+)\"");
    int images = 0;
    bool canopy = false;
    for (auto it = std::sregex_iterator(html.begin(), html.end(), img); it != std::sregex_iterator(); ++it) {
        const std::string src = (*it)[1];
        EXPECT_TRUE(std::filesystem::is_regular_file(dir / "out" / src)) << src;
        EXPECT_GT(std::filesystem::file_size(dir / "out" / src), 1000u) << src;
        canopy = canopy || src == "canopy_trunks.png";
        ++images;
    }
    EXPECT_GE(images, 10);
    EXPECT_TRUE(canopy);
    for (const char* file : {"bench/summary.json", "bench/frames.csv", "bench/plot.png"})
        EXPECT_TRUE(std::filesystem::is_regular_file(dir / "out" / file)) << file;
}
