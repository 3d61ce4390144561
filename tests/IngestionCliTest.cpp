// Real data in, end to end through the CLI: a synthetic scene re-delivered as national data comes (Lambert-93 JPEG
// tiles with collars, a Web Mercator RGBA GeoTIFF at another pixel size) renders and segments like the original; the
// mask is a GeoTIFF GIS tools read (CRS, geotransform, nodata); no-data is never drawn black; a leaf-off twice as
// coarse on the default working grid; PNGs with world files and --crs; a COG; a manifest of tile lists and grid keys;
// truth masks on other grids; and the real Saclay pair as delivered (../shared/data/seasons/saclay_w_delivered)
// against the registered original.
#include "Scene.h"
#include "SyntheticScene.h"
#include "TestUtil.h"

#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <ogr_spatialref.h>

#include <algorithm>
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

/// Two masks whose grids share a CRS and pixel size and line up (a whole-pixel offset, read from their
/// geotransforms): over the pixels both cover (neither 255), the share where they agree and the IoU of their canopy
/// (value 1).
struct Alike {
    double agreement = 0.0, canopyIou = 0.0;
    std::int64_t both = 0;
};
Alike compareAligned(const GdalMask& a, const GdalMask& b) {
    Alike r;
    const double px = a.geotransform[1];
    EXPECT_NEAR(b.geotransform[1], px, 1e-9);
    EXPECT_NEAR(b.geotransform[5], a.geotransform[5], 1e-9);
    const double fx = (a.geotransform[0] - b.geotransform[0]) / px, fy = (b.geotransform[3] - a.geotransform[3]) / px;
    EXPECT_NEAR(fx, std::round(fx), 1e-6) << "the grids' pixels line up";
    EXPECT_NEAR(fy, std::round(fy), 1e-6) << "the grids' pixels line up";
    const int dx = int(std::lround(fx)), dy = int(std::lround(fy));
    std::int64_t same = 0, inter = 0, uni = 0;
    for (int y = 0; y < a.height; ++y)
        for (int x = 0; x < a.width; ++x) {
            const int bx = x + dx, by = y + dy;
            if (bx < 0 || by < 0 || bx >= b.width || by >= b.height)
                continue;
            const std::uint8_t va = a.values[size_t(y) * size_t(a.width) + size_t(x)];
            const std::uint8_t vb = b.values[size_t(by) * size_t(b.width) + size_t(bx)];
            if (va == 255 || vb == 255)
                continue;
            ++r.both;
            same += va == vb;
            inter += va == 1 && vb == 1;
            uni += va == 1 || vb == 1;
        }
    r.agreement = r.both ? double(same) / double(r.both) : 0.0;
    r.canopyIou = uni ? double(inter) / double(uni) : 0.0;
    return r;
}

std::int64_t canopyPixels(const GdalMask& m) {
    return std::count(m.values.begin(), m.values.end(), std::uint8_t(1));
}

/// A synthetic scene `sizeM` metres wide south of Paris (UTM 31N) at 0.5 m, seed 5, without a city.
SynthOptions parisScene(double sizeM) {
    SynthOptions o;
    o.sizeM = sizeM;
    o.gsd = 0.5;
    o.seed = 5;
    o.city = false;
    o.centreLonLat = glm::dvec2(2.18, 48.70);
    return o;
}

/// A 128 m synthetic scene south of Paris (UTM 31N, 256² px at 0.5 m, no city) in dir/scene, and its deciduous truth
/// written again as a GeoTIFF on the scene's grid (dir/truth.tif), which segmentations on other grids can read.
struct SmallScene {
    fs::path scene, truth;
    Georef grid;
    explicit SmallScene(const TempDir& dir) { make(dir); }
    void make(const TempDir& dir) { // ASSERT_* cannot stand in a constructor
        scene = dir / "scene";
        auto r = generateSyntheticScene(parisScene(128), scene);
        ASSERT_TRUE(r.ok()) << r.message();
        auto info = readRasterInfo(scene / "leafon.tif");
        ASSERT_TRUE(info.ok() && info->georef) << info.message();
        grid = *info->georef;
        auto t = readImageU8(scene / "truth_deciduous.png", 1);
        ASSERT_TRUE(t.ok()) << t.message();
        GdalRasterSpec s;
        s.geotransform = geotransformOf(grid);
        s.crs = grid.crs.identifier();
        truth = dir / "truth.tif";
        writeGdalRaster(truth, t->pixels.data(), SampleType::U8, t->width, t->height, 1, s);
    }
    /// `segment` of the scene's leaf-on and `leafoff` (default: the scene's) with `extra` flags, cache in dir/cache.
    CliResult segment(const TempDir& dir, const fs::path& leafoff, const std::vector<std::string>& extra) const {
        const fs::path off = leafoff.empty() ? scene / "leafoff.tif" : leafoff;
        std::vector<std::string> a = {"segment", "--leafon", (scene / "leafon.tif").string(), "--leafoff",
                                      off.string(), "--cache", (dir / "cache").string()};
        a.insert(a.end(), extra.begin(), extra.end());
        return runCli(a);
    }
};

/// A synthetic scene south of Paris (UTM 31N), 1024×1024 px at 0.5 m, and its seasons re-delivered: the leaf-on in
/// Lambert-93 as 2×2 JPEG-in-TIFF YCbCr tiles with internal masks and nodata collars, the leaf-off in Web Mercator at
/// 0.75 m (about 0.5 m on the ground) as one RGBA file with an alpha band.
struct Delivered {
    TempDir dir{"ingest-cli"};
    fs::path scene;
    std::string extent; // the original grid's extent, for --extent
    Delivered() {
        auto r = generateSyntheticScene(parisScene(512), dir / "scene");
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

TEST(IngestionCliTest, LeafOffTwiceAsCoarseSegmentsAlikeOnTheDefaultGrid) {
    // The leaf-off delivered with half the leaf-on's ground resolution, segmented with no grid flags at all, against
    // the original pair (both 0.5 m, one grid). Two deliveries, each averaged down as coarser products are made: in
    // Web Mercator at 1.5 m, which at 48.70° N is 1.5 × cos(48.70°) = 0.99 m on the ground, with an alpha band
    // around its footprint; and in the leaf-on's own CRS at 1 m.
    TempDir dir("ingest-coarse");
    const SmallScene s(dir);
    ASSERT_FALSE(HasFailure());
    const CliResult a = s.segment(dir, {},
                                  {"--truth", s.truth.string(), "--out", (dir / "original.tif").string(), "--metrics",
                                   (dir / "original.json").string()});
    ASSERT_EQ(a.exitCode, 0) << a.err;
    const GdalMask original = readMask(dir / "original.tif");
    ASSERT_EQ(original.width, 256);
    ASSERT_EQ(original.height, 256);
    ASSERT_GT(canopyPixels(original), 256 * 256 / 100) << "the scene has deciduous crowns to compare";
    const double f1 = readJson(dir / "original.json")["f1"].get<double>();
    gdalWarp(s.scene / "leafoff.tif", dir / "off_3857.tif",
             {"-t_srs", "EPSG:3857", "-tr", "1.5", "1.5", "-r", "average", "-dstalpha"});
    gdalTranslate(s.scene / "leafoff.tif", dir / "off_1m.tif", {"-outsize", "128", "128", "-r", "average"});
    for (const char* name : {"off_3857", "off_1m"}) {
        const std::string off = name;
        SCOPED_TRACE(off);
        const CliResult b = s.segment(dir, dir / (off + ".tif"),
                                      {"--truth", s.truth.string(), "--out", (dir / (off + "_mask.tif")).string(),
                                       "--metrics", (dir / (off + ".json")).string()});
        ASSERT_EQ(b.exitCode, 0) << b.err;
        const GdalMask d = readMask(dir / (off + "_mask.tif"));
        const nlohmann::json m = readJson(dir / (off + ".json"));
        EXPECT_EQ(m["warped"], true);
        // The default working grid: the leaf-on's CRS (it is projected), the finest season's pixel (the leaf-on's
        // 0.5 m) on that season's lattice, the union of both seasons (so it holds the original grid).
        EXPECT_TRUE(sameCrs(d.wkt, "EPSG:32631")) << d.wkt;
        EXPECT_EQ(d.geotransform[1], 0.5);
        EXPECT_EQ(d.geotransform[5], -0.5);
        EXPECT_LE(d.geotransform[0], original.geotransform[0]);
        EXPECT_GE(d.geotransform[3], original.geotransform[3]);
        EXPECT_GE(d.width, 256);
        EXPECT_GE(d.height, 256);
        if (off == "off_1m") { // the same extent: the original grid itself
            EXPECT_EQ(d.geotransform, original.geotransform);
            EXPECT_EQ(d.width, 256);
            EXPECT_EQ(d.height, 256);
        }
        const Alike c = compareAligned(original, d);
        std::printf("%s vs original: %.4f of %lld pixels agree, canopy IoU %.3f, F1 %.3f (original %.3f)\n",
                    off.c_str(), c.agreement, (long long)c.both, c.canopyIou, m["f1"].get<double>(), f1);
        // Only the leaf-off's outermost pixels (a pixel of 1 m, partly covered, at the edge of its footprint) are
        // left out.
        EXPECT_GT(c.both, 256 * 256 * 9 / 10);
        // Thresholds. A leaf-off pixel spans 2×2 working pixels: along each crown's edge a band about one leaf-off
        // pixel wide (2 working pixels) mixes twigs and meadow in the leaf-off, and there the decision may change;
        // elsewhere the pair is what it was. The synthetic deciduous crowns have radii of 2.5-7 m (5-14 px), so
        // that band holds at most about half a crown's pixels (less on the larger ones), and the crowns cover a
        // small part of the scene: at most a few percent of all pixels can change (agreement ≥ 0.92) and the
        // canopies still overlap mostly (IoU ≥ 0.6). A leaf-off placed a crown's radius (a few metres) off, or read
        // at the wrong scale, would move every crown: their IoU would fall well below 0.5, as would the F1.
        EXPECT_GE(c.agreement, 0.92);
        EXPECT_GE(c.canopyIou, 0.6);
        EXPECT_GT(m["f1"].get<double>(), f1 - 0.1);
    }
}

TEST(IngestionCliTest, PngWithAWorldFileTakesItsCrsFromTheFlag) {
    // PNGs placed by world files (on.pgw, off.wld: six lines, the last two the centre of the top-left pixel), which
    // carry no CRS: refused without --crs (one line, naming the file and suggesting the flag), read with it exactly
    // as the same pixels in GeoTIFFs that carry the CRS, the mask on the grid the world files give.
    TempDir dir("ingest-worldfile");
    const int w = 128, h = 96;
    const TreePair p = makeTreePair(w, h, 3);
    const Georef g = testGeoref(0.5, 405000.0, 5758000.0);
    const std::string world = "0.5\n0\n0\n-0.5\n405000.25\n5757999.75\n";
    ASSERT_TRUE(writeImageAtomic(dir / "on.png", p.on.pixels.data(), w, h, 3).ok());
    ASSERT_TRUE(writeImageAtomic(dir / "off.png", p.off.pixels.data(), w, h, 3).ok());
    std::ofstream(dir / "on.pgw") << world;
    std::ofstream(dir / "off.wld") << world;
    ASSERT_TRUE(writeGeoTiff(dir / "on.tif", p.on.pixels.data(), SampleType::U8, w, h, 3, g).ok());
    ASSERT_TRUE(writeGeoTiff(dir / "off.tif", p.off.pixels.data(), SampleType::U8, w, h, 3, g).ok());
    auto segment = [&](const std::string& ext, const std::string& out, std::vector<std::string> extra) {
        std::vector<std::string> a = {"segment", "--leafon", (dir / ("on" + ext)).string(), "--leafoff",
                                      (dir / ("off" + ext)).string(), "--cache", (dir / "cache").string()};
        a.insert(a.end(), {"--out", (dir / out).string()});
        a.insert(a.end(), extra.begin(), extra.end());
        return runCli(a);
    };
    const CliResult bare = segment(".png", "bare.tif", {});
    EXPECT_EQ(bare.exitCode, 1);
    EXPECT_NE(bare.err.find((dir / "on.png").string() + ": has no CRS (give one with --crs EPSG:CODE)"),
              std::string::npos)
        << bare.err;
    EXPECT_EQ(std::count(bare.err.begin(), bare.err.end(), '\n'), 1) << bare.err;
    EXPECT_FALSE(fs::exists(dir / "bare.tif"));

    const CliResult png = segment(".png", "png.tif", {"--crs", "EPSG:32632", "--metrics", (dir / "png.json").string()});
    ASSERT_EQ(png.exitCode, 0) << png.err;
    const CliResult tif = segment(".tif", "tif.tif", {});
    ASSERT_EQ(tif.exitCode, 0) << tif.err;
    const GdalMask a = readMask(dir / "png.tif"), b = readMask(dir / "tif.tif");
    EXPECT_TRUE(sameCrs(a.wkt, "EPSG:32632")) << a.wkt;
    const std::array<double, 6> fromWorldFile{405000.0, 0.5, 0.0, 5758000.0, 0.0, -0.5};
    for (size_t i = 0; i < 6; ++i)
        EXPECT_NEAR(a.geotransform[i], fromWorldFile[i], 1e-9) << i;
    EXPECT_EQ(a.width, w);
    EXPECT_EQ(a.height, h);
    EXPECT_GT(canopyPixels(a), 0) << "the crowns are found";
    EXPECT_TRUE(a.values == b.values) << "the same pixels on the same grid give the same mask";
    EXPECT_EQ(readJson(dir / "png.json")["warped"], false) << "PNGs that are the working grid are read as they are";
}

TEST(IngestionCliTest, CogSeasonReadsAsTheGeoTiffItWasMadeFrom) {
    // The leaf-on as a Cloud Optimized GeoTIFF (GDAL's COG driver: 64² deflate tiles, overviews, the COG layout):
    // segment and render read it as the GeoTIFF it was made from (lossless: the same mask and the same still, so its
    // full-resolution image is read, not an overview).
    TempDir dir("ingest-cog");
    const SmallScene s(dir);
    ASSERT_FALSE(HasFailure());
    gdalTranslate(s.scene / "leafon.tif", dir / "on_cog.tif",
                  {"-of", "COG", "-co", "COMPRESS=DEFLATE", "-co", "BLOCKSIZE=64"});
    {
        GDALAllRegister();
        GDALDataset* d = GDALDataset::FromHandle(GDALOpen((dir / "on_cog.tif").c_str(), GA_ReadOnly));
        ASSERT_TRUE(d);
        const char* layout = d->GetMetadataItem("LAYOUT", "IMAGE_STRUCTURE");
        EXPECT_STREQ(layout ? layout : "", "COG");
        EXPECT_GE(d->GetRasterBand(1)->GetOverviewCount(), 1);
        GDALClose(GDALDataset::ToHandle(d));
    }
    auto info = readRasterInfo(dir / "on_cog.tif");
    ASSERT_TRUE(info.ok() && info->georef) << info.message();
    EXPECT_TRUE(info->tiled);
    EXPECT_EQ(info->georef->crs, s.grid.crs);
    EXPECT_EQ(info->georef->origin, s.grid.origin);
    EXPECT_EQ(info->georef->pixelSize, s.grid.pixelSize);

    for (const char* name : {"tif", "cog"}) {
        const fs::path on = std::string(name) == "cog" ? dir / "on_cog.tif" : s.scene / "leafon.tif";
        const std::vector<std::string> pair = {"--leafon",  on.string(),
                                               "--leafoff", (s.scene / "leafoff.tif").string(),
                                               "--cache",   (dir / "cache").string()};
        std::vector<std::string> seg = {"segment"}, render = {"render"};
        seg.insert(seg.end(), pair.begin(), pair.end());
        render.insert(render.end(), pair.begin(), pair.end());
        seg.insert(seg.end(), {"--out", (dir / (std::string(name) + ".tif")).string(), "--metrics",
                               (dir / (std::string(name) + ".json")).string()});
        render.insert(render.end(), {"--view", "leafon", "--size", "128x128", "--clip-size", "256", "--out",
                                     (dir / (std::string(name) + ".png")).string()});
        const CliResult r = runCli(seg);
        ASSERT_EQ(r.exitCode, 0) << name << ": " << r.err;
        EXPECT_EQ(readJson(dir / (std::string(name) + ".json"))["warped"], false) << name << ": read as it is";
        const CliResult still = runCli(render);
        ASSERT_EQ(still.exitCode, 0) << name << ": " << still.err;
    }
    const GdalMask tif = readMask(dir / "tif.tif"), cog = readMask(dir / "cog.tif");
    EXPECT_GT(canopyPixels(tif), 0);
    EXPECT_TRUE(cog.values == tif.values) << "the COG's pixels are the GeoTIFF's";
    EXPECT_EQ(cog.geotransform, tif.geotransform);
    auto a = readImageU8(dir / "tif.png", 3), b = readImageU8(dir / "cog.png", 3);
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_TRUE(a->pixels == b->pixels) << "the same pyramid, the same still";
}

TEST(IngestionCliTest, ManifestWithTileListsAndGridKeysSegmentsAsTheFlagsSay) {
    // README's scene format end to end: seasons as lists of tiles (the leaf-on's without a CRS), "crs", "grid_crs",
    // "grid_res", "extent", "stretch" and "resampling": the mask is on the grid they give, and the same as with the
    // flags that say the same.
    TempDir dir("ingest-manifest");
    writeTiledTestPair(dir.path());
    ASSERT_FALSE(HasFailure());
    std::ofstream(dir / "scene.json") << R"({"leafon": ["tiles/on_w.tif", "tiles/on_e.tif"],
 "leafoff": ["tiles/off_n.tif", "tiles/off_s.tif"], "crs": "EPSG:32632", "grid_crs": "EPSG:25832", "grid_res": 0.25,
 "extent": [405004, 5757964, 405060, 5757996], "stretch": "percentile", "resampling": "bilinear"})";
    const CliResult m = runCli({"segment", (dir / "scene.json").string(), "--cache", (dir / "cache").string(), "--out",
                                (dir / "manifest.tif").string(), "--metrics", (dir / "manifest.json").string()});
    ASSERT_EQ(m.exitCode, 0) << m.err;
    std::vector<std::string> flags = {"segment", "--leafon", (dir / "tiles/on_w.tif").string(),
                                      (dir / "tiles/on_e.tif").string(), "--leafoff",
                                      (dir / "tiles/off_n.tif").string(), (dir / "tiles/off_s.tif").string()};
    flags.insert(flags.end(), {"--crs", "EPSG:32632", "--grid-crs", "EPSG:25832", "--grid-res", "0.25", "--extent",
                               "405004,5757964,405060,5757996", "--stretch", "percentile", "--resampling", "bilinear"});
    flags.insert(flags.end(), {"--cache", (dir / "cache").string(), "--out", (dir / "flags.tif").string()});
    const CliResult f = runCli(flags);
    ASSERT_EQ(f.exitCode, 0) << f.err;
    const GdalMask a = readMask(dir / "manifest.tif"), b = readMask(dir / "flags.tif");
    EXPECT_TRUE(sameCrs(a.wkt, "EPSG:25832")) << a.wkt;
    const std::array<double, 6> fromKeys{405004.0, 0.25, 0.0, 5757996.0, 0.0, -0.25};
    EXPECT_EQ(a.geotransform, fromKeys);
    EXPECT_EQ(a.width, 224); // 56 m at 0.25 m
    EXPECT_EQ(a.height, 128);
    EXPECT_GT(canopyPixels(a), 0) << "the pair's crowns are found";
    EXPECT_TRUE(a.values == b.values) << "the manifest's keys act as the flags";
    const nlohmann::json metrics = readJson(dir / "manifest.json");
    EXPECT_EQ(metrics["grid_crs"], "EPSG:25832");
    EXPECT_EQ(metrics["warped"], true);
    EXPECT_EQ(metrics["leafon"], (dir / "tiles/on_w.tif").string() + " (and 1 more)") << "the list, in its order";
}

TEST(IngestionCliTest, TruthOnAnotherGridIsReadOntoTheWorkingGrid) {
    // `segment --truth` with a georeferenced truth on another grid than the seasons': read onto the working grid
    // (nearest neighbour) and scored where it reaches. The scene's truth (a PNG on the grid) and the same truth at
    // 0.25 m (each pixel split in four on the grid's lattice), in Web Mercator at 0.75 m (0.5 m on the ground at
    // 48.70° N) and 4 m (8 pixels) east of where it belongs.
    TempDir dir("ingest-truth");
    const SmallScene s(dir);
    ASSERT_FALSE(HasFailure());
    auto truth = readImageU8(s.scene / "truth_deciduous.png", 1);
    ASSERT_TRUE(truth.ok()) << truth.message();
    ASSERT_EQ(truth->width, 256);
    gdalTranslate(s.truth, dir / "truth_fine.tif", {"-outsize", "512", "512", "-r", "nearest"});
    gdalWarp(s.truth, dir / "truth_3857.tif", {"-t_srs", "EPSG:3857", "-tr", "0.75", "0.75", "-r", "near"});
    {
        Georef east = s.grid;
        east.origin.x += 4.0;
        GdalRasterSpec spec;
        spec.geotransform = geotransformOf(east);
        spec.crs = s.grid.crs.identifier();
        writeGdalRaster(dir / "truth_east.tif", truth->pixels.data(), SampleType::U8, 256, 256, 1, spec);
    }
    auto scored = [&](const std::string& name, const fs::path& t) {
        const CliResult r = s.segment(dir, {},
                                      {"--truth", t.string(), "--out", (dir / (name + ".tif")).string(), "--metrics",
                                       (dir / (name + ".json")).string()});
        EXPECT_EQ(r.exitCode, 0) << name << ": " << r.err;
        return readJson(dir / (name + ".json"));
    };
    const nlohmann::json png = scored("png", s.scene / "truth_deciduous.png"),
                         fine = scored("fine", dir / "truth_fine.tif"), merc = scored("merc", dir / "truth_3857.tif"),
                         east = scored("east", dir / "truth_east.tif");
    ASSERT_FALSE(HasFailure());
    const std::int64_t all = 256 * 256;
    EXPECT_EQ(png["scored_pixels"].get<std::int64_t>(), all);
    EXPECT_GT(png["tp"].get<std::int64_t>(), 0);
    // At 0.25 m on the lattice: the very truth, the very scores.
    for (const char* k : {"tp", "fp", "fn", "tn"})
        EXPECT_EQ(fine[k], png[k]) << k;
    // In Web Mercator: two nearest-neighbour resamplings at the same ground pixel move a crown's edge by at most a
    // pixel here and there (crowns of 5-14 px radius), so the F1 moves by a few hundredths at most; the truth's
    // footprint covers the grid but for its outermost pixels.
    EXPECT_GE(merc["scored_pixels"].get<std::int64_t>(), all * 95 / 100);
    EXPECT_NEAR(merc["f1"].get<double>(), png["f1"].get<double>(), 0.05);
    // 8 pixels east: the grid's 8 western columns have no truth and are not scored; every other pixel is scored
    // against the truth pixel 8 to its west. The mask does not depend on the truth: the scores follow exactly.
    const GdalMask mask = readMask(dir / "png.tif");
    ASSERT_EQ(mask.values.size(), size_t(all));
    std::int64_t tp = 0, fp = 0, fn = 0, tn = 0;
    for (int y = 0; y < 256; ++y)
        for (int x = 8; x < 256; ++x) {
            const bool m = mask.values[size_t(y) * 256 + size_t(x)] == 1, t = truth->at(x - 8, y) != 0;
            tp += m && t;
            fp += m && !t;
            fn += !m && t;
            tn += !m && !t;
        }
    EXPECT_EQ(east["scored_pixels"].get<std::int64_t>(), 248 * 256);
    EXPECT_EQ(east["tp"].get<std::int64_t>(), tp);
    EXPECT_EQ(east["fp"].get<std::int64_t>(), fp);
    EXPECT_EQ(east["fn"].get<std::int64_t>(), fn);
    EXPECT_EQ(east["tn"].get<std::int64_t>(), tn);
}
