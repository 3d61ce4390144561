// The seasonview binary on bad input: one line naming the file and the problem, exit code 1, no output file.
#include "TestUtil.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <limits>

using namespace seasonview;
using namespace seasonview::test;

namespace {

struct CliFixture : ::testing::Test {
    TempDir dir{"cli"};
    void SetUp() override {
        writeTestImage(dir / "on.tif", 48, 32, testGeoref(1.0), false, 1);
        writeTestImage(dir / "off.tif", 48, 32, testGeoref(1.0), false, 2);
    }
    std::vector<std::string> render(std::vector<std::string> sceneArgs, const std::string& out = "out.png") {
        std::vector<std::string> a = {"render"};
        a.insert(a.end(), sceneArgs.begin(), sceneArgs.end());
        a.insert(a.end(), {"--size", "64x48", "--cache", (dir / "cache").string(), "--out", (dir / out).string()});
        return a;
    }
    std::vector<std::string> pair() const { return {"--leafon", (dir / "on.tif").string(), "--leafoff", (dir / "off.tif").string()}; }
    // Bad input: exit 1, exactly one stderr line containing `needle`, and no output file.
    void expectOneLineError(const std::vector<std::string>& args, const std::string& needle,
                            const std::string& out = "out.png") {
        const CliResult r = runCli(args);
        EXPECT_EQ(r.exitCode, 1) << r.err;
        EXPECT_NE(r.err.find(needle), std::string::npos) << "stderr: " << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << "stderr: " << r.err;
        EXPECT_FALSE(std::filesystem::exists(dir / out));
        for (auto& e : std::filesystem::directory_iterator(dir.path()))
            EXPECT_EQ(e.path().filename().string().find(".partial"), std::string::npos) << e.path();
    }
};

} // namespace

TEST_F(CliFixture, RenderWritesAnImage) {
    const CliResult r = runCli(render(pair()));
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(r.out.find("wrote"), std::string::npos);
    auto img = readRasterInfo(dir / "out.png");
    ASSERT_TRUE(img.ok()) << img.message();
    EXPECT_EQ(img->width, 64);
    EXPECT_EQ(img->height, 48);
    // TIFF output too, same pixels.
    const CliResult t = runCli(render(pair(), "out.tif"));
    ASSERT_EQ(t.exitCode, 0) << t.err;
    auto a = readImageU8(dir / "out.png");
    auto b = readImageU8(dir / "out.tif");
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_EQ(a->pixels, b->pixels);
}

TEST_F(CliFixture, HelpForEverySubcommand) {
    for (const char* sub : {"synth", "render", "demo"}) {
        const CliResult r = runCli({sub, "--help"});
        EXPECT_EQ(r.exitCode, 0) << sub;
        EXPECT_NE(r.out.find("--out"), std::string::npos) << sub;
    }
    EXPECT_NE(runCli({"render", "--help"}).out.find("leafon|leafoff"), std::string::npos);
}

TEST_F(CliFixture, MissingFile) {
    expectOneLineError(render({"--leafon", (dir / "gone.tif").string(), "--leafoff", (dir / "off.tif").string()}),
                       "gone.tif: file not found");
}

TEST_F(CliFixture, TruncatedTiff) {
    writeTestImage(dir / "big.tif", 600, 400, testGeoref(1.0), false, 3);
    writeTestImage(dir / "big2.tif", 600, 400, testGeoref(1.0), false, 4);
    std::filesystem::resize_file(dir / "big.tif", std::filesystem::file_size(dir / "big.tif") / 3);
    expectOneLineError(render({"--leafon", (dir / "big.tif").string(), "--leafoff", (dir / "big2.tif").string()}),
                       "big.tif:");
}

TEST_F(CliFixture, HeaderOnlyTiff) {
    writeTestImage(dir / "h.tif", 600, 400, testGeoref(1.0), false, 3);
    std::filesystem::resize_file(dir / "h.tif", 100);
    expectOneLineError(render({"--leafon", (dir / "h.tif").string(), "--leafoff", (dir / "off.tif").string()}),
                       "h.tif:");
}

TEST_F(CliFixture, NotAnImage) {
    std::ofstream(dir / "notes.tif") << "leaf-on imagery will follow\n";
    expectOneLineError(render({"--leafon", (dir / "notes.tif").string(), "--leafoff", (dir / "off.tif").string()}),
                       "notes.tif: not a readable image");
}

TEST_F(CliFixture, SeasonsThatDoNotOverlap) {
    writeTestImage(dir / "far.tif", 48, 32, testGeoref(1.0, 406000, 5758000), false, 2);
    expectOneLineError(render({"--leafon", (dir / "on.tif").string(), "--leafoff", (dir / "far.tif").string()}),
                       "far.tif: does not overlap the leaf-on");
}

TEST_F(CliFixture, DemFullOfNan) {
    std::vector<float> nan(16 * 16, std::numeric_limits<float>::quiet_NaN());
    ASSERT_TRUE(writeGeoTiff(dir / "nan.tif", nan.data(), SampleType::F32, 16, 16, 1, testGeoref(4.0, 404990, 5758010)).ok());
    auto args = pair();
    args.insert(args.end(), {"--dem", (dir / "nan.tif").string()});
    expectOneLineError(render(args), "nan.tif: DEM has no valid heights");
}

TEST_F(CliFixture, DemWithNodataValue) {
    std::vector<std::int16_t> v(16 * 16, -32768);
    ASSERT_TRUE(writeGeoTiff(dir / "void.tif", v.data(), SampleType::I16, 16, 16, 1, testGeoref(4.0, 404990, 5758010)).ok());
    auto args = pair();
    args.insert(args.end(), {"--dem", (dir / "void.tif").string()});
    expectOneLineError(render(args), "void.tif: DEM has no valid heights");
}

TEST_F(CliFixture, NoCrsAtAll) {
    std::vector<std::uint8_t> px(48 * 32 * 3, 100);
    GdalRasterSpec spec;
    spec.geotransform = geotransformOf(testGeoref(1.0));
    writeGdalRaster(dir / "nocrs.tif", px.data(), SampleType::U8, 48, 32, 3, spec);
    expectOneLineError(render({"--leafon", (dir / "nocrs.tif").string(), "--leafoff", (dir / "off.tif").string()}),
                       "nocrs.tif: has no CRS (give one with --crs EPSG:CODE)");
}

TEST_F(CliFixture, MalformedManifest) {
    std::ofstream(dir / "scene.json") << "{\"leafon\": \"on.tif\", \"leafoff\": \"off.tif\"";
    expectOneLineError(render({(dir / "scene.json").string()}), "scene.json: malformed JSON manifest");
    std::ofstream(dir / "scene2.json") << "{\"leafon\": \"on.tif\"}";
    expectOneLineError(render({(dir / "scene2.json").string()}), "scene2.json: missing required key 'leafoff'");
}

TEST_F(CliFixture, ManifestRendersLikeFlags) {
    std::ofstream(dir / "scene.json") << "{\"leafon\": \"on.tif\", \"leafoff\": \"off.tif\"}";
    const CliResult a = runCli(render({(dir / "scene.json").string()}, "a.png"));
    ASSERT_EQ(a.exitCode, 0) << a.err;
    const CliResult b = runCli(render(pair(), "b.png"));
    ASSERT_EQ(b.exitCode, 0) << b.err;
    auto ia = readImageU8(dir / "a.png");
    auto ib = readImageU8(dir / "b.png");
    ASSERT_TRUE(ia.ok() && ib.ok());
    EXPECT_EQ(ia->pixels, ib->pixels);
}

TEST_F(CliFixture, CameraStringThatDoesNotParse) {
    auto args = render(pair());
    args.insert(args.end(), {"--camera", "1,2,three,0,-90"});
    expectOneLineError(args, "camera '1,2,three,0,-90': Z 'three' is not a number");
    auto args2 = render(pair());
    args2.insert(args2.end(), {"--camera", "1,2,3"});
    expectOneLineError(args2, "expected X,Y,Z,YAW,PITCH[,FOV]");
}

TEST_F(CliFixture, CameraAboveTerrain) {
    auto args = render(pair());
    args.insert(args.end(), {"--camera", "0,0,+30,0,-90"});
    const CliResult r = runCli(args);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(r.out.find("camera 0,0,30,0,-90,60"), std::string::npos) << r.out;
}

TEST_F(CliFixture, BadSizeViewAndOutput) {
    auto a = render(pair());
    a[std::find(a.begin(), a.end(), "64x48") - a.begin()] = "64by48";
    expectOneLineError(a, "size '64by48'");
    auto b = render(pair());
    b.insert(b.end(), {"--view", "autumn"});
    expectOneLineError(b, "--view 'autumn'");
    expectOneLineError(render(pair(), "out.jpgx"), "output must be a .png or .tif", "out.jpgx");
    auto c = render(pair());
    c.insert(c.end(), {"--grid-size", "100"});
    expectOneLineError(c, "--grid-size 100: expected 2^k - 1");
    auto d = render(pair());
    d.insert(d.end(), {"--view", "levels", "--renderer", "reference"});
    expectOneLineError(d, "--view levels needs --renderer clipmap");
}

// The terrain inspection views and --accuracy write what they promise.
TEST_F(CliFixture, TerrainViewsAndAccuracy) {
    for (const char* view : {"wireframe", "levels", "relief"}) {
        auto a = render(pair(), std::string(view) + ".png");
        a.insert(a.end(), {"--view", view, "--camera", "0,-20,+20,0,-35"});
        const CliResult r = runCli(a);
        ASSERT_EQ(r.exitCode, 0) << view << ": " << r.err;
        EXPECT_TRUE(std::filesystem::exists(dir / (std::string(view) + ".png"))) << view;
    }
    auto a = render(pair(), "acc.png");
    a.insert(a.end(), {"--camera", "0,-20,+20,0,-35", "--accuracy", (dir / "acc.json").string()});
    const CliResult r = runCli(a);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    std::ifstream f(dir / "acc.json");
    const auto j = nlohmann::json::parse(f);
    EXPECT_GE(j["psnr_db"].get<double>(), 35.0); // flat pair: geometry identical, imagery nearly so
    EXPECT_LT(j["mean_depth_error_px"].get<double>(), 0.1);
    EXPECT_GT(j["triangles"].get<int>(), 0);
}

TEST_F(CliFixture, SynthRejectsBadDem) {
    std::ofstream(dir / "dem.tif") << "not a dem";
    const CliResult r = runCli({"synth", "--out", (dir / "s").string(), "--size-m", "64", "--gsd", "1", "--dem",
                                (dir / "dem.tif").string()});
    EXPECT_EQ(r.exitCode, 1);
    EXPECT_NE(r.err.find("dem.tif"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "s" / "scene.json"));
}

TEST_F(CliFixture, SynthRejectsScenesAboveTheLimit) {
    const CliResult r = runCli({"synth", "--out", (dir / "s").string(), "--size-m", "140000", "--gsd", "1"});
    EXPECT_EQ(r.exitCode, 1);
    EXPECT_NE(r.err.find("max 131072"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "s" / "scene.json"));
}

TEST_F(CliFixture, UnknownOptionIsExitOne) {
    const CliResult r = runCli({"render", "--frobnicate"});
    EXPECT_EQ(r.exitCode, 1);
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
}

TEST_F(CliFixture, RealSentinelPair) {
    auto data = realDataDir();
    if (!data) GTEST_SKIP() << "real data not found (set SEASONVIEW_DATA or provide ../shared/data)";
    const CliResult r = runCli({"render", "--leafon", (*data / "seasons/saclay_w/leafon_2017-08-29.tif").string(),
                                "--leafoff", (*data / "seasons/saclay_w/leafoff_2016-03-15.tif").string(), "--size",
                                "344x320", "--view", "leafoff", "--cache", (dir / "cache").string(), "--out",
                                (dir / "saclay.png").string()});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_TRUE(std::filesystem::exists(dir / "saclay.png"));
}

TEST_F(CliFixture, SizeBeyondTheGlLimitIsRefusedWithTheLimit) {
    // 65536 is over every GL implementation's largest framebuffer (llvmpipe 16384, NVIDIA 32768).
    auto args = pair();
    args.insert(args.begin(), "render");
    args.insert(args.end(), {"--size", "65536x16", "--cache", (dir / "cache").string(), "--out", (dir / "out.png").string()});
    expectOneLineError(args, "--size 65536x16: larger than");
    const CliResult r = runCli(args);
    EXPECT_NE(r.err.find("pixels a side: GL_MAX_RENDERBUFFER_SIZE"), std::string::npos) << r.err;
}
