// `seasonview prepare` through the binary: builds both pyramids, the pair statistics and the canopy layer, then reports
// them up to date, rebuilds on --force, and fails with one line naming the file on bad input.
#include "TestUtil.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>

using namespace seasonview;
using namespace seasonview::test;

namespace {

struct PrepareCli : ::testing::Test {
    TempDir dir{"prepare-cli"};
    void SetUp() override {
        writeTestImage(dir / "on.tif", 300, 200, testGeoref(1.0), false, 1);
        writeTestImage(dir / "off.tif", 300, 200, testGeoref(1.0), true, 2); // 16-bit: stretch applied
    }
    std::vector<std::string> prepare(const std::string& leafon, const std::string& cache = "cache") const {
        return {"prepare", "--leafon", (dir / leafon).string(), "--leafoff", (dir / "off.tif").string(), "--cache",
                (dir / cache).string()};
    }
    static int count(const std::string& text, const std::string& word) {
        int n = 0;
        for (size_t at = text.find(word); at != std::string::npos; at = text.find(word, at + 1)) ++n;
        return n;
    }
};

} // namespace

TEST_F(PrepareCli, BuildsThenUpToDateThenForced) {
    const CliResult first = runCli(prepare("on.tif"));
    ASSERT_EQ(first.exitCode, 0) << first.err;
    EXPECT_EQ(count(first.out, "built"), 4) << first.out;
    EXPECT_NE(first.out.find("canopy layer: built"), std::string::npos) << first.out;
    EXPECT_NE(first.out.find("default, k 5, 16 layers"), std::string::npos) << first.out;
    EXPECT_NE(first.out.find("leafon: built"), std::string::npos) << first.out;
    EXPECT_NE(first.out.find("leafoff: built"), std::string::npos) << first.out;
    EXPECT_NE(first.out.find("pair statistics: built"), std::string::npos) << first.out;
    EXPECT_NE(first.out.find("drop threshold"), std::string::npos) << first.out;
    EXPECT_NE(first.out.find("not prepared yet"), std::string::npos) << first.out;
    EXPECT_NE(first.out.find("10 levels"), std::string::npos) << first.out; // 300x200 ... 1x1

    const CliResult second = runCli(prepare("on.tif"));
    ASSERT_EQ(second.exitCode, 0) << second.err;
    EXPECT_EQ(count(second.out, "up to date"), 4) << second.out;
    EXPECT_NE(second.out.find("canopy layer: up to date"), std::string::npos) << second.out;
    EXPECT_NE(second.out.find("pair statistics: up to date"), std::string::npos) << second.out;
    EXPECT_EQ(count(second.out, "built"), 0) << second.out;

    std::vector<std::string> force = prepare("on.tif");
    force.push_back("--force");
    const CliResult third = runCli(force);
    ASSERT_EQ(third.exitCode, 0) << third.err;
    EXPECT_EQ(count(third.out, "built"), 4) << third.out;
    EXPECT_EQ(count(third.out, "forced"), 4) << third.out;
}

// The canopy layer is prepared for the parameters given (another k: another layer, built beside the first), or not
// at all with --canopy-layers off; a parameter out of range is one line naming its flag, before anything is built.
TEST_F(PrepareCli, CanopyLayerFollowsItsParameters) {
    ASSERT_EQ(runCli(prepare("on.tif")).exitCode, 0);
    std::vector<std::string> k7 = prepare("on.tif");
    k7.insert(k7.end(), {"--k", "7"});
    const CliResult other = runCli(k7);
    ASSERT_EQ(other.exitCode, 0) << other.err;
    EXPECT_NE(other.out.find("canopy layer: built"), std::string::npos) << other.out;
    EXPECT_NE(other.out.find("default, k 7, 16 layers"), std::string::npos) << other.out;
    EXPECT_NE(runCli(prepare("on.tif")).out.find("canopy layer: up to date"), std::string::npos); // k 5 kept

    std::vector<std::string> off = prepare("on.tif", "cache-off");
    off.insert(off.end(), {"--canopy-layers", "off"});
    const CliResult none = runCli(off);
    ASSERT_EQ(none.exitCode, 0) << none.err;
    EXPECT_EQ(none.out.find("canopy layer"), std::string::npos) << none.out;

    std::vector<std::string> even = prepare("on.tif", "cache-even");
    even.insert(even.end(), {"--k", "4"});
    const CliResult bad = runCli(even);
    EXPECT_EQ(bad.exitCode, 1);
    EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << bad.err;
    EXPECT_NE(bad.err.find("--k"), std::string::npos) << bad.err;
    EXPECT_EQ(bad.out, "");
    EXPECT_FALSE(std::filesystem::exists(dir / "cache-even"));
}

TEST_F(PrepareCli, MissingSourceIsOneLineNamingIt) {
    const CliResult r = runCli(prepare("gone.tif"));
    EXPECT_EQ(r.exitCode, 1);
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find("seasonview prepare: "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find((dir / "gone.tif").string() + ": file not found"), std::string::npos) << r.err;
    EXPECT_EQ(r.out, "");
}

TEST_F(PrepareCli, UnwritableCacheIsOneLineNamingIt) {
    std::ofstream(dir / "plainfile") << "not a folder";
    const CliResult r = runCli(prepare("on.tif", "plainfile/cache"));
    EXPECT_EQ(r.exitCode, 1);
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find((dir / "plainfile" / "cache").string()), std::string::npos) << r.err;
}

TEST_F(PrepareCli, HelpListsForce) {
    const CliResult r = runCli({"prepare", "--help"});
    EXPECT_EQ(r.exitCode, 0);
    EXPECT_NE(r.out.find("--force"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("--cache"), std::string::npos) << r.out;
}
