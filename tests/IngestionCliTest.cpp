// Real data in, end to end through the CLI: a synthetic scene re-delivered as national data comes (Lambert-93 JPEG
// tiles with collars, a Web Mercator COG at another resolution) renders and segments like the original; the mask is a
// GeoTIFF GIS tools read (CRS, geotransform, nodata); no-data is never drawn black; and the real Saclay pair as
// delivered (../shared/data/seasons/saclay_w_delivered) against the registered original.
#include "Scene.h"
#include "SyntheticScene.h"
#include "TestUtil.h"

#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <ogr_spatialref.h>

#include <cmath>
#include <fstream>

using namespace seasonview;
using namespace seasonview::test;

namespace {

namespace fs = std::filesystem;

nlohmann::json readJson(const fs::path& p) {
    std::ifstream f(p);
    return nlohmann::json::parse(f, nullptr, false);
}

/// A GeoTIFF mask as GDAL reads it.
struct GdalMask {
    std::vector<std::uint8_t> values;
    int width = 0, height = 0;
    std::array<double, 6> geotransform{};
    std::string wkt;
    std::optional<double> nodata;
};
GdalMask readMask(const fs::path& p) {
    GDALAllRegister();
    GdalMask m;
    GDALDataset* d = GDALDataset::FromHandle(GDALOpen(p.c_str(), GA_ReadOnly));
    EXPECT_TRUE(d) << p;
    if (!d) return m;
    m.width = d->GetRasterXSize();
    m.height = d->GetRasterYSize();
    d->GetGeoTransform(m.geotransform.data());
    if (const OGRSpatialReference* srs = d->GetSpatialRef()) {
        char* w = nullptr;
        srs->exportToWkt(&w);
        m.wkt = w ? w : "";
        CPLFree(w);
    }
    int has = 0;
    const double nd = d->GetRasterBand(1)->GetNoDataValue(&has);
    if (has) m.nodata = nd;
    m.values.resize(size_t(m.width) * size_t(m.height));
    EXPECT_EQ(d->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, m.width, m.height, m.values.data(), m.width, m.height,
                                           GDT_Byte, 0, 0, nullptr),
              CE_None);
    GDALClose(GDALDataset::ToHandle(d));
    return m;
}

/// Share of the pixels both masks cover (neither 255) where they agree.
double agreement(const GdalMask& a, const GdalMask& b, std::int64_t* both = nullptr) {
    std::int64_t n = 0, same = 0;
    for (size_t i = 0; i < std::min(a.values.size(), b.values.size()); ++i) {
        if (a.values[i] == 255 || b.values[i] == 255) continue;
        ++n;
        same += a.values[i] == b.values[i];
    }
    if (both) *both = n;
    return n ? double(same) / double(n) : 0.0;
}

bool sameCrs(const std::string& wkt, const char* user) {
    OGRSpatialReference a, b;
    a.importFromWkt(wkt.c_str());
    b.SetFromUserInput(user);
    return a.IsSame(&b) != 0;
}

/// A synthetic scene south of Paris (UTM 31N), 1024×1024 px at 0.5 m, and its seasons re-delivered: the leaf-on in
/// Lambert-93 as 2×2 JPEG-in-TIFF YCbCr tiles with internal masks and nodata collars, the leaf-off in Web Mercator at
/// 0.75 m (about 0.5 m on the ground) as one RGBA file with an alpha band.
struct Delivered {
    TempDir dir{"ingest-cli"};
    fs::path scene;
    std::string extent; // the original grid's extent, for --extent
    Delivered() {
        SynthOptions o;
        o.sizeM = 512;
        o.gsd = 0.5;
        o.seed = 5;
        o.city = false;
        o.centreLonLat = glm::dvec2(2.18, 48.70);
        auto r = generateSyntheticScene(o, dir / "scene");
        EXPECT_TRUE(r.ok()) << r.message();
        scene = dir / "scene";
        auto info = readRasterInfo(scene / "leafon.tif");
        const Georef& g = *info->georef;
        extent = std::to_string(g.origin.x) + "," + std::to_string(g.origin.y - 512.0) + "," +
                 std::to_string(g.origin.x + 512.0) + "," + std::to_string(g.origin.y);
        gdalWarp(scene / "leafon.tif", dir / "on_l93.tif", {"-t_srs", "EPSG:2154", "-tr", "0.5", "0.5", "-r", "bilinear",
                                                             "-dstnodata", "0"});
        fs::create_directories(dir / "on_tiles");
        CPLSetConfigOption("GDAL_TIFF_INTERNAL_MASK", "YES"); // masks inside the tiles, as national deliveries have
        auto l93 = readRasterInfo(dir / "on_l93.tif");
        const int hw = l93->width / 2, hh = l93->height / 2;
        for (int ty = 0; ty < 2; ++ty)
            for (int tx = 0; tx < 2; ++tx)
                gdalTranslate(dir / "on_l93.tif", dir / "on_tiles" / ("on_" + std::to_string(tx) + "_" + std::to_string(ty) + ".tif"),
                              {"-srcwin", std::to_string(tx * hw), std::to_string(ty * hh),
                               std::to_string(tx ? l93->width - hw : hw), std::to_string(ty ? l93->height - hh : hh),
                               "-co", "TILED=YES", "-co", "COMPRESS=JPEG", "-co", "PHOTOMETRIC=YCBCR", "-co",
                               "JPEG_QUALITY=92", "-mask", "auto", "-a_nodata", "none"});
        gdalWarp(scene / "leafoff.tif", dir / "off_3857.tif",
                 {"-t_srs", "EPSG:3857", "-tr", "0.75", "0.75", "-r", "bilinear", "-dstalpha", "-co", "TILED=YES",
                  "-co", "COMPRESS=DEFLATE"});
    }
    std::vector<std::string> delivered(const std::string& command) const {
        return {command, "--leafon", (dir / "on_tiles").string(), "--leafoff", (dir / "off_3857.tif").string(),
                "--cache", (dir / "cache").string()};
    }
};

} // namespace

TEST(IngestionCliTest, SameSceneDeliveredTwoWaysSegmentsAlike) {
    Delivered d;
    const TempDir& dir = d.dir;
    // The original pair, and the delivered one segmented on the original's grid (UTM 31N, 0.5 m, its extent).
    CliResult a = runCli({"segment", (d.scene / "scene.json").string(), "--cache", (dir / "cache").string(), "--out",
                          (dir / "original.tif").string(), "--metrics", (dir / "original.json").string()});
    ASSERT_EQ(a.exitCode, 0) << a.err;
    auto args = d.delivered("segment");
    args.insert(args.end(), {"--grid-crs", "EPSG:32631", "--grid-res", "0.5", "--extent", d.extent, "--truth",
                             (d.scene / "truth_deciduous.png").string(), "--out", (dir / "delivered.tif").string(),
                             "--metrics", (dir / "delivered.json").string(), "--overlay",
                             (dir / "overlay.tif").string(), "--trees", (dir / "trees.geojson").string()});
    CliResult b = runCli(args);
    ASSERT_EQ(b.exitCode, 0) << b.err;
    const GdalMask original = readMask(dir / "original.tif"), delivered = readMask(dir / "delivered.tif");
    ASSERT_EQ(original.width, 1024);
    ASSERT_EQ(delivered.width, 1024);
    ASSERT_EQ(delivered.height, 1024);
    std::int64_t both = 0;
    const double agree = agreement(original, delivered, &both);
    std::printf("delivered vs original: %.4f of %lld pixels agree\n", agree, (long long)both);
    EXPECT_GT(both, 1024 * 1024 * 9 / 10) << "the collars are the only pixels left out";
    EXPECT_GE(agree, 0.95);
    const nlohmann::json mo = readJson(dir / "original.json"), md = readJson(dir / "delivered.json");
    EXPECT_NEAR(md["f1"].get<double>(), mo["f1"].get<double>(), 0.05);
    EXPECT_GT(md["nodata_pixels"].get<int>(), 0);
    EXPECT_EQ(md["warped"], true);

    // The mask as GIS tools read it: on the grid asked for, with its CRS and nodata; values 0, 1, 255.
    EXPECT_TRUE(sameCrs(delivered.wkt, "EPSG:32631")) << delivered.wkt;
    const std::array<double, 6> gt = original.geotransform;
    EXPECT_EQ(delivered.geotransform, gt);
    ASSERT_TRUE(delivered.nodata);
    EXPECT_EQ(*delivered.nodata, 255.0);
    for (std::uint8_t v : delivered.values) ASSERT_TRUE(v == 0 || v == 1 || v == 255) << int(v);
    const GdalMask overlay = readMask(dir / "overlay.tif");
    EXPECT_TRUE(sameCrs(overlay.wkt, "EPSG:32631"));
    EXPECT_EQ(overlay.geotransform, gt);
    const nlohmann::json trees = readJson(dir / "trees.geojson");
    ASSERT_TRUE(trees.is_object());
    ASSERT_GT(trees["features"].size(), 10u);
    const auto& p = trees["features"][0]["geometry"]["coordinates"];
    EXPECT_NEAR(p[0].get<double>(), 2.18, 0.01); // WGS 84 longitude, latitude
    EXPECT_NEAR(p[1].get<double>(), 48.70, 0.01);
}

TEST(IngestionCliTest, RenderAndPrepareTakeTheDeliveryAsItIs) {
    Delivered d;
    const TempDir& dir = d.dir;
    auto prepare = d.delivered("prepare");
    CliResult p = runCli(prepare);
    ASSERT_EQ(p.exitCode, 0) << p.err;
    EXPECT_NE(p.out.find("leafon: built"), std::string::npos) << p.out;
    EXPECT_NE(p.out.find("is warped onto the working grid"), std::string::npos) << p.out;
    CliResult again = runCli(prepare);
    ASSERT_EQ(again.exitCode, 0) << again.err;
    EXPECT_NE(again.out.find("leafon: up to date"), std::string::npos) << again.out;
    // Straight down over the whole working grid (the Lambert-93 leaf-on's CRS): the seasons, the no-data corners
    // grey, never black.
    for (const char* view : {"leafon", "leafoff", "swipe"}) {
        SCOPED_TRACE(view);
        auto args = d.delivered("render");
        args.insert(args.end(), {"--view", view, "--size", "256x256", "--out", (dir / "still.png").string()});
        CliResult r = runCli(args);
        ASSERT_EQ(r.exitCode, 0) << r.err;
        auto img = readImageU8(dir / "still.png", 3);
        ASSERT_TRUE(img.ok());
        int black = 0;
        for (size_t i = 0; i < img->pixels.size(); i += 3)
            black += img->pixels[i] < 6 && img->pixels[i + 1] < 6 && img->pixels[i + 2] < 6;
        EXPECT_EQ(black, 0) << "no-data drawn black";
    }
}

TEST(IngestionCliTest, NoDataShowsTheOtherSeasonThenGrey) {
    // A leaf-off whose east half is a nodata collar (value 0): in the leaf-off view the leaf-on shows there; a
    // leaf-on with a hole shows the no-data grey where neither season has data.
    TempDir dir("ingest-nodata");
    SynthOptions o;
    o.sizeM = 128;
    o.gsd = 0.5;
    o.seed = 2;
    o.city = false;
    ASSERT_TRUE(generateSyntheticScene(o, dir / "scene").ok());
    auto on = readImageU8(dir / "scene/leafon.tif", 3), off = readImageU8(dir / "scene/leafoff.tif", 3);
    const Georef g = *readRasterInfo(dir / "scene/leafon.tif")->georef;
    for (int y = 0; y < 256; ++y)
        for (int x = 128; x < 256; ++x)
            for (int c = 0; c < 3; ++c) off->at(x, y, c) = 0;
    for (int y = 0; y < 64; ++y)
        for (int x = 192; x < 256; ++x)
            for (int c = 0; c < 3; ++c) on->at(x, y, c) = 0;
    GdalRasterSpec s;
    s.geotransform = geotransformOf(g);
    s.crs = "EPSG:32632";
    s.nodata = 0.0;
    writeGdalRaster(dir / "off.tif", off->pixels.data(), SampleType::U8, 256, 256, 3, s);
    writeGdalRaster(dir / "on.tif", on->pixels.data(), SampleType::U8, 256, 256, 3, s);
    // Straight down, one screen pixel per image pixel.
    const double height = 64.0 / std::tan(30.0 * 3.14159265358979 / 180.0);
    const std::string camera = "0,0," + std::to_string(height) + ",0,-90,60";
    CliResult r = runCli({"render", "--leafon", (dir / "on.tif").string(), "--leafoff", (dir / "off.tif").string(),
                          "--cache", (dir / "cache").string(), "--view", "leafoff", "--camera", camera, "--size",
                          "256x256", "--out", (dir / "off.png").string()});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    auto img = readImageU8(dir / "off.png", 3);
    ASSERT_TRUE(img.ok());
    auto near = [&](int x, int y, const Image<std::uint8_t>& ref, int rx, int ry) {
        int e = 0;
        for (int c = 0; c < 3; ++c) e = std::max(e, std::abs(int(img->at(x, y, c)) - int(ref.at(rx, ry, c))));
        return e;
    };
    // West: leaf-off as it is; east below the hole: the leaf-on; the hole itself: the no-data grey (0.56, 0.55, 0.52).
    EXPECT_LE(near(40, 150, *off, 40, 150), 12);
    EXPECT_LE(near(160, 150, *on, 160, 150), 12);
    EXPECT_NEAR(img->at(224, 30, 0), 143, 3);
    EXPECT_NEAR(img->at(224, 30, 1), 140, 3);
    EXPECT_NEAR(img->at(224, 30, 2), 133, 3);
    // The segmentation leaves the east half out and scores only the west.
    CliResult seg = runCli({"segment", "--leafon", (dir / "on.tif").string(), "--leafoff", (dir / "off.tif").string(),
                            "--cache", (dir / "cache").string(), "--truth", (dir / "scene/truth_deciduous.png").string(),
                            "--out", (dir / "mask.tif").string(), "--metrics", (dir / "m.json").string()});
    ASSERT_EQ(seg.exitCode, 0) << seg.err;
    const nlohmann::json m = readJson(dir / "m.json");
    EXPECT_EQ(m["nodata_pixels"].get<int>(), 128 * 256);
    EXPECT_EQ(m["scored_pixels"].get<int>(), 128 * 256);
    const GdalMask mask = readMask(dir / "mask.tif");
    for (int y = 0; y < 256; ++y) {
        ASSERT_EQ(mask.values[size_t(y) * 256 + 200], 255);
        ASSERT_LE(mask.values[size_t(y) * 256 + 50], 1);
    }
}

TEST(IngestionCliTest, RealSaclayPairAsDeliveredSegmentsLikeTheOriginal) {
    const auto data = realDataDir();
    if (!data || !fs::exists(*data / "seasons/saclay_w_delivered"))
        GTEST_SKIP() << "real data not found (../shared/data/seasons/saclay_w_delivered)";
    TempDir dir("ingest-saclay");
    const fs::path s = *data / "seasons";
    // Both pairs segmented on one grid: UTM 31N at 10 m over the area both cover. The delivered seasons are 8-bit
    // top-of-atmosphere reflectance scaled into a byte (0-3000 -> 1-255): --stretch percentile gives them the stretch
    // the 16-bit originals get.
    const std::vector<std::string> grid = {"--grid-crs", "EPSG:32631", "--grid-res", "10", "--extent",
                                           "436000,5390500,441800,5398500", "--stretch", "percentile", "--cache",
                                           (dir / "cache").string()};
    auto original = std::vector<std::string>{"segment", "--leafon", (s / "saclay_w/leafon_2017-08-29.tif").string(),
                                             "--leafoff", (s / "saclay_w/leafoff_2016-03-15.tif").string(), "--out",
                                             (dir / "original.tif").string()};
    auto delivered = std::vector<std::string>{
        "segment", "--leafon", (s / "saclay_w_delivered/leafon_3857_cog.tif").string(), "--leafoff",
        (s / "saclay_w_delivered/leafoff_L93_tiles").string(), "--out", (dir / "delivered.tif").string()};
    original.insert(original.end(), grid.begin(), grid.end());
    delivered.insert(delivered.end(), grid.begin(), grid.end());
    CliResult a = runCli(original), b = runCli(delivered);
    ASSERT_EQ(a.exitCode, 0) << a.err;
    ASSERT_EQ(b.exitCode, 0) << b.err;
    std::int64_t both = 0;
    const double agree = agreement(readMask(dir / "original.tif"), readMask(dir / "delivered.tif"), &both);
    std::printf("Saclay delivered vs original: %.4f of %lld pixels agree\n", agree, (long long)both);
    EXPECT_GT(both, 350000);
    EXPECT_GE(agree, 0.95);
    // And with no flags at all, the delivered pair renders (its own grid: the leaf-on's Web Mercator).
    CliResult r = runCli({"render", "--leafon", (s / "saclay_w_delivered/leafon_3857_cog.tif").string(), "--leafoff",
                          (s / "saclay_w_delivered/leafoff_L93_tiles").string(), "--view", "swipe", "--size",
                          "320x320", "--cache", (dir / "cache").string(), "--out", (dir / "swipe.png").string()});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_TRUE(fs::exists(dir / "swipe.png"));
}

TEST(IngestionCliTest, BadDeliveriesAreOneLineAndNoOutput) {
    TempDir dir("ingest-cli-bad");
    std::vector<std::uint8_t> rgb(64 * 64 * 3, 120), rg(64 * 64 * 2, 120);
    GdalRasterSpec s;
    s.geotransform = geotransformOf(testGeoref(1.0));
    s.crs = "EPSG:32632";
    fs::create_directories(dir / "tiles");
    fs::create_directories(dir / "empty");
    writeGdalRaster(dir / "tiles/a.tif", rgb.data(), SampleType::U8, 64, 64, 3, s);
    writeGdalRaster(dir / "tiles/b.tif", rg.data(), SampleType::U8, 64, 64, 2, s);
    writeGdalRaster(dir / "on.tif", rgb.data(), SampleType::U8, 64, 64, 3, s);
    std::ofstream(dir / "empty/notes.txt") << "nothing";
    struct Case {
        std::string leafoff, needle;
    } cases[] = {{(dir / "tiles").string(), (dir / "tiles/b.tif").string() + ": 2 bands but "},
                 {(dir / "empty").string(), (dir / "empty").string() + ": no rasters in this folder"},
                 {(dir / "none_*.tif").string(), "none_*.tif: matches no file"}};
    for (const Case& c : cases) {
        for (const char* command : {"segment", "render"}) {
            SCOPED_TRACE(std::string(command) + " " + c.leafoff);
            const CliResult r = runCli({command, "--leafon", (dir / "on.tif").string(), "--leafoff", c.leafoff,
                                        "--cache", (dir / "cache").string(), "--out", (dir / "out.tif").string()});
            EXPECT_EQ(r.exitCode, 1);
            EXPECT_NE(r.err.find(c.needle), std::string::npos) << r.err;
            EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
            EXPECT_FALSE(fs::exists(dir / "out.tif"));
        }
    }
}
