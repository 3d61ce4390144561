// Damaged cache files are rebuilt from their source, never drawn or scored: a pyramid tile flipped or cut short in
// the cache, then `render`, `segment` and `bench` run again give what a clean cache gives.
#include "TestUtil.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <tiffio.h>

#include <fstream>

using namespace seasonview;
using namespace seasonview::test;

namespace {

namespace fs = std::filesystem;

/// The level files of every pyramid in the cache whose manifest names `source` (part of its path).
std::vector<fs::path> cachedLevels(const fs::path& cache, const std::string& source, const std::string& level) {
    std::vector<fs::path> out;
    for (const auto& e : fs::directory_iterator(cache / "pyramids")) {
        std::ifstream f(e.path() / "pyramid.json");
        const auto j = nlohmann::json::parse(f, nullptr, false);
        if (j.is_object() && j.value("source_path", std::string()).find(source) != std::string::npos)
            out.push_back(e.path() / level);
    }
    return out;
}

/// Flips bytes in the middle of the file's first tile (its Zstandard checksum no longer matches).
void damageFirstTile(const fs::path& p) {
    TIFF* t = TIFFOpen(p.c_str(), "r");
    ASSERT_TRUE(t) << p;
    const std::uint64_t at = TIFFGetStrileOffset(t, 0) + TIFFGetStrileByteCount(t, 0) / 2;
    TIFFClose(t);
    std::fstream f(p, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(std::streamoff(at));
    f.write("\xde\xad\xbe\xef", 4);
}

struct Damaged : ::testing::Test {
    TempDir dir{"integrity-cli"};
    void SetUp() override {
        writeTestImage(dir / "on.tif", 600, 400, testGeoref(0.5), false, 1);
        // The leaf-off shifted by 2 m: both seasons are warped, read from their pyramids' level 0 by `segment`.
        writeTestImage(dir / "off.tif", 600, 400, testGeoref(0.5, 405002.0), false, 2);
    }
    std::vector<std::string> scene(const std::string& command) const {
        return {command, "--leafon", (dir / "on.tif").string(), "--leafoff", (dir / "off.tif").string(), "--cache",
                (dir / "cache").string()};
    }
    std::vector<std::string> with(std::vector<std::string> a, const std::vector<std::string>& b) const {
        a.insert(a.end(), b.begin(), b.end());
        return a;
    }
};

} // namespace

TEST_F(Damaged, RenderRebuildsTheDamagedPyramidAndDrawsWhatACleanCacheDraws) {
    const auto still = [&](const std::string& out) {
        // Clip levels of 256²: levels 0 and 1 (604 and 302 wide) stream through the block loader, level 2 is the
        // resident base; the still needs level 0.
        return with(scene("render"), {"--view", "leafon", "--size", "640x480", "--clip-size", "256", "--out",
                                      (dir / out).string()});
    };
    CliResult clean = runCli(still("clean.png"));
    ASSERT_EQ(clean.exitCode, 0) << clean.err;
    for (const char* level : {"level_00.tif", "level_01.tif", "level_02.tif"}) {
        SCOPED_TRACE(level);
        const auto files = cachedLevels(dir / "cache", "on.tif", level);
        ASSERT_EQ(files.size(), 1u);
        damageFirstTile(files[0]);
        CliResult again = runCli(still("again.png"));
        ASSERT_EQ(again.exitCode, 0) << again.err;
        EXPECT_NE(again.out.find("damaged in the cache; its pyramid is rebuilt from the source"), std::string::npos)
            << again.out;
        EXPECT_EQ(readBytes(dir / "again.png"), readBytes(dir / "clean.png"));
    }
}

TEST_F(Damaged, RenderRebuildsAnElevationLevelWithOneFlippedByte) {
    // A DEM of noise: its levels' Zstandard frames are mostly raw literals, so one flipped byte decodes without an
    // error through libtiff and only the tile's content checksum (ZstdTileCheck) sees it. Levels 0 and 1 stream
    // through the block loader at this clip size; the coarser ones are resident, read whole.
    const std::vector<float> dem = noiseHeights(size_t(300) * 200, 5, 40.0f, 4.0f);
    GdalRasterSpec spec;
    spec.geotransform = geotransformOf(testGeoref(1.0));
    spec.crs = "EPSG:32632";
    writeGdalRaster(dir / "dem.tif", dem.data(), SampleType::F32, 300, 200, 1, spec);
    const auto still = [&](const std::string& out) {
        return with(scene("render"), {"--dem", (dir / "dem.tif").string(), "--view", "relief", "--size", "320x240",
                                      "--clip-size", "256", "--out", (dir / out).string()});
    };
    CliResult clean = runCli(still("clean.png"));
    ASSERT_EQ(clean.exitCode, 0) << clean.err;
    for (const char* level : {"level_00.tif", "level_03.tif"}) {
        SCOPED_TRACE(level);
        const auto files = cachedLevels(dir / "cache", "dem.tif", level);
        ASSERT_EQ(files.size(), 1u);
        TIFF* t = TIFFOpen(files[0].c_str(), "r");
        ASSERT_TRUE(t);
        const std::uint64_t at = TIFFGetStrileOffset(t, 0) + TIFFGetStrileByteCount(t, 0) / 2;
        TIFFClose(t);
        flipByte(files[0], at, 0x01);
        CliResult again = runCli(still("again.png"));
        ASSERT_EQ(again.exitCode, 0) << again.err;
        EXPECT_NE(again.out.find("checksum"), std::string::npos) << again.out;
        EXPECT_NE(again.out.find("damaged in the cache; its pyramid is rebuilt from the source"), std::string::npos)
            << again.out;
        EXPECT_TRUE(readBytes(dir / "again.png") == readBytes(dir / "clean.png")) << "the still differs from the clean one";
    }
}

TEST_F(Damaged, SegmentAndBenchRebuildTheDamagedPyramid) {
    const auto seg = [&](const std::string& out) {
        return with(scene("segment"), {"--out", (dir / out).string()});
    };
    CliResult clean = runCli(seg("clean.tif"));
    ASSERT_EQ(clean.exitCode, 0) << clean.err;
    const auto files = cachedLevels(dir / "cache", "off.tif", "level_00.tif");
    ASSERT_EQ(files.size(), 1u);
    damageFirstTile(files[0]);
    CliResult again = runCli(seg("again.tif"));
    ASSERT_EQ(again.exitCode, 0) << again.err;
    EXPECT_NE(again.out.find("damaged in the cache"), std::string::npos) << again.out;
    auto a = readImageU8(dir / "clean.tif", 1), b = readImageU8(dir / "again.tif", 1);
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_EQ(a->pixels, b->pixels);

    damageFirstTile(cachedLevels(dir / "cache", "on.tif", "level_00.tif").at(0));
    CliResult bench = runCli(with(scene("bench"), {"--path", "orbit", "--frames", "3", "--size", "64x48",
                                                   "--coverage-every", "0", "--out", (dir / "bench").string()}));
    ASSERT_EQ(bench.exitCode, 0) << bench.err;
    EXPECT_NE(bench.out.find("damaged in the cache"), std::string::npos) << bench.out;
}

namespace {

/// One error line naming `file`, exit 1, and neither the output nor a cache entry left behind.
void expectRefused(const CliResult& r, const std::string& file, const fs::path& out, const fs::path& cache) {
    EXPECT_EQ(r.exitCode, 1) << r.out << r.err;
    EXPECT_NE(r.err.find(file + ":"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(out)) << out;
    if (fs::exists(cache / "pyramids"))
        for (const auto& e : fs::directory_iterator(cache / "pyramids")) {
            std::ifstream f(e.path() / "pyramid.json");
            const auto j = nlohmann::json::parse(f, nullptr, false);
            EXPECT_FALSE(j.is_object() && j.value("source_path", std::string()).find(file) != std::string::npos)
                << "a pyramid of the damaged " << file << " was kept: " << e.path();
        }
}

/// `render`, `segment` and `prepare` on a leaf-on cut to `bytes`: all refused, then the whole file works.
void refuseTruncatedLeafOn(const fs::path& leafon, const fs::path& leafoff, const std::vector<std::uintmax_t>& cuts) {
    TempDir dir("integrity-truncated");
    const fs::path cut = dir / "TRUNCATED.tif";
    for (const std::uintmax_t bytes : cuts) {
        SCOPED_TRACE("cut at " + std::to_string(bytes) + " bytes");
        fs::copy_file(leafon, cut, fs::copy_options::overwrite_existing);
        fs::permissions(cut, fs::perms::owner_read | fs::perms::owner_write);
        fs::resize_file(cut, bytes);
        const auto pair = [&](const std::string& cmd) {
            return std::vector<std::string>{cmd, "--leafon", cut.string(), "--leafoff", leafoff.string(), "--cache",
                                            (dir / "cache").string()};
        };
        auto render = pair("render");
        render.insert(render.end(), {"--size", "320x320", "--out", (dir / "x.png").string()});
        expectRefused(runCli(render), "TRUNCATED.tif", dir / "x.png", dir / "cache");
        auto segment = pair("segment");
        segment.insert(segment.end(), {"--out", (dir / "mask.png").string()});
        expectRefused(runCli(segment), "TRUNCATED.tif", dir / "mask.png", dir / "cache");
        expectRefused(runCli(pair("prepare")), "TRUNCATED.tif", dir / "cache/none", dir / "cache");
    }
    // The same commands on the whole file succeed: nothing of the damaged runs was kept and reused.
    fs::copy_file(leafon, cut, fs::copy_options::overwrite_existing);
    CliResult ok = runCli({"segment", "--leafon", cut.string(), "--leafoff", leafoff.string(), "--cache",
                           (dir / "cache").string(), "--out", (dir / "mask.png").string()});
    EXPECT_EQ(ok.exitCode, 0) << ok.err;
    EXPECT_TRUE(fs::exists(dir / "mask.png"));
}

} // namespace

TEST(IntegrityCliTest, TruncatedLeafOnIsRefusedByRenderSegmentAndPrepare) {
    TempDir dir("integrity-truncated-synth");
    // A 16-bit pair like the Sentinel-2 one: deflate tiles, so a cut lands inside the image data.
    writeTestImage(dir / "on.tif", 900, 700, testGeoref(1.0), true, 1);
    writeTestImage(dir / "off.tif", 900, 700, testGeoref(1.0), true, 2);
    const auto size = fs::file_size(dir / "on.tif");
    refuseTruncatedLeafOn(dir / "on.tif", dir / "off.tif", {5000, size / 2, size - 100});
}

TEST(IntegrityCliTest, RealTruncatedLeafOnIsRefusedByRenderSegmentAndPrepare) {
    const auto data = realDataDir();
    const fs::path s = data ? *data / "seasons/saclay_w" : fs::path();
    if (!data || !fs::exists(s / "leafon_2017-08-29.tif"))
        GTEST_SKIP() << "real data not found (../shared/data/seasons/saclay_w)";
    // The cuts an interrupted copy leaves: the first 5,000 and 1,000,000 bytes.
    refuseTruncatedLeafOn(s / "leafon_2017-08-29.tif", s / "leafoff_2016-03-15.tif", {5000, 1000000});
}

TEST(IntegrityCliTest, FacadeTextureCutShortStopsTheAtlasBuild) {
    TempDir dir("integrity-facade");
    CliResult synth = runCli({"synth", "--size-m", "256", "--gsd", "0.5", "--block-city", "2", "--facade-size", "64",
                              "--out", (dir / "s").string()});
    ASSERT_EQ(synth.exitCode, 0) << synth.err;
    const fs::path facade = dir / "s/city/facades/b0.jpg";
    ASSERT_TRUE(fs::exists(facade));
    // Half a JPEG decodes as grey after a warning: it must not be packed into an atlas as if it were the photo.
    fs::resize_file(facade, fs::file_size(facade) / 2);
    CliResult r = runCli({"atlas", "build", (dir / "s/city/city.obj").string(), "--obj-local", "--atlas-size", "64",
                          "--out", (dir / "city.atlas").string()});
    EXPECT_EQ(r.exitCode, 1) << r.out << r.err;
    EXPECT_NE(r.err.find("b0.jpg: cannot read texture"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(dir / "city.atlas"));
}
