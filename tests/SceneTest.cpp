#include "Heightfield.h"
#include "ReferenceMesh.h"
#include "Scene.h"
#include "TestUtil.h"
#include "WebSource.h"

#include <gdal.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>

using namespace seasonview;
using namespace seasonview::test;

namespace {

void writeText(const std::filesystem::path& p, const std::string& text) { std::ofstream(p) << text; }

void writeDem(const std::filesystem::path& p, int w, int h, const Georef& g, float fill, int nanEvery = 0) {
    std::vector<float> v(size_t(w) * size_t(h));
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const size_t i = size_t(y) * size_t(w) + size_t(x);
            v[i] = std::isnan(fill) ? fill : fill + float(x) + 2.0f * float(y);
            if (nanEvery && i % size_t(nanEvery) == 0) v[i] = std::numeric_limits<float>::quiet_NaN();
        }
    ASSERT_TRUE(writeGeoTiff(p, v.data(), SampleType::F32, w, h, 1, g).ok());
}

struct Pair {
    TempDir dir{"scene"};
    Pair() {
        writeTestImage(dir / "on.tif", 64, 48, testGeoref(0.5), false, 1);
        writeTestImage(dir / "off.tif", 64, 48, testGeoref(0.5), false, 2);
    }
    SceneSources sources() const {
        SceneSources s;
        s.leafon = dir / "on.tif";
        s.leafoff = dir / "off.tif";
        return s;
    }
};

} // namespace

TEST(ManifestTest, ParsesAndResolvesRelativePaths) {
    Pair p;
    std::filesystem::create_directories(p.dir / "sub");
    writeText(p.dir / "sub/scene.json", R"({"name": "x", "leafon": "../on.tif", "leafoff": "../off.tif",
        "truth": {"deciduous": "t.png"}, "parameters": {"tree_height_m": 21.5}, "colour": 1})");
    auto s = parseManifest(p.dir / "sub/scene.json");
    ASSERT_TRUE(s.ok()) << s.message();
    ASSERT_EQ(s->leafon.items.size(), 1u);
    EXPECT_EQ(s->leafon.items.front(), p.dir / "sub/../on.tif");
    EXPECT_EQ(s->truthDeciduous, p.dir / "sub/t.png");
    EXPECT_DOUBLE_EQ(s->treeHeightM, 21.5);
    ASSERT_EQ(s->warnings.size(), 1u);
    EXPECT_NE(s->warnings[0].find("unknown key 'colour'"), std::string::npos);
    auto scene = loadScene(*s, p.dir / "cache");
    ASSERT_TRUE(scene.ok()) << scene.message();
}

TEST(ManifestTest, ErrorsNameTheManifestAndTheKey) {
    TempDir dir("manifest-bad");
    struct Case {
        const char* text;
        const char* needle;
    } cases[] = {
        {"{\"leafon\": \"a.tif\",\n \"leafoff\": }", "malformed JSON manifest (line 2"},
        {"[1, 2]", "must be a JSON object"},
        {"{\"leafoff\": \"b.tif\"}", "missing required key 'leafon'"},
        {"{\"leafon\": 3, \"leafoff\": \"b.tif\"}", "'leafon' must be a non-empty string"},
        {"{\"leafon\": \"a.tif\", \"leafoff\": \"b.tif\", \"truth\": 5}", "'truth' must be an object"},
        {"{\"leafon\": \"a.tif\", \"leafoff\": \"b.tif\", \"parameters\": {\"tree_height_m\": -2}}",
         "'parameters.tree_height_m' must be a positive number"},
        {"", "malformed JSON manifest"},
    };
    int i = 0;
    for (const Case& c : cases) {
        const auto path = dir / ("m" + std::to_string(i++) + ".json");
        writeText(path, c.text);
        auto r = parseManifest(path);
        ASSERT_FALSE(r.ok()) << c.text;
        EXPECT_EQ(r.message().rfind(path.string() + ": ", 0), 0u) << r.message();
        EXPECT_NE(r.message().find(c.needle), std::string::npos) << r.message();
        EXPECT_EQ(r.message().find('\n'), std::string::npos);
    }
    auto missing = parseManifest(dir / "none.json");
    ASSERT_FALSE(missing.ok());
    EXPECT_NE(missing.message().find("none.json: file not found"), std::string::npos);
}

// Seasons as lists of tiles and every grid key, as README's scene format writes them: parsed as written (paths
// relative to the manifest, in order), and loaded as they say: the leaf-on's tiles take "crs" (they carry none), the
// grid is "grid_crs" at "grid_res" over "extent", both seasons are warped onto it with "resampling", and "stretch"
// percentile gives even 8-bit data a stretch.
TEST(ManifestTest, TileListsAndGridKeysAsWritten) {
    TempDir dir("manifest-tiles");
    writeTiledTestPair(dir.path());
    ASSERT_FALSE(HasFailure());
    writeText(dir / "scene.json", R"({"leafon": ["tiles/on_w.tif", "tiles/on_e.tif"],
        "leafoff": ["tiles/off_n.tif", "tiles/off_s.tif"], "crs": "EPSG:32632", "grid_crs": "EPSG:25832",
        "grid_res": 0.25, "extent": [405004, 5757964, 405060, 5757996], "stretch": "percentile",
        "resampling": "bilinear"})");
    auto s = parseManifest(dir / "scene.json");
    ASSERT_TRUE(s.ok()) << s.message();
    EXPECT_TRUE(s->warnings.empty()) << s->warnings.front();
    ASSERT_EQ(s->leafon.items.size(), 2u);
    EXPECT_EQ(s->leafon.items[0].string(), (dir / "tiles/on_w.tif").string());
    EXPECT_EQ(s->leafon.items[1].string(), (dir / "tiles/on_e.tif").string());
    ASSERT_EQ(s->leafoff.items.size(), 2u);
    EXPECT_EQ(s->leafoff.items[0].string(), (dir / "tiles/off_n.tif").string());
    EXPECT_EQ(s->leafoff.items[1].string(), (dir / "tiles/off_s.tif").string());
    EXPECT_EQ(s->crs, "EPSG:32632");
    EXPECT_EQ(s->grid.crs, "EPSG:25832");
    ASSERT_TRUE(s->grid.resolution);
    EXPECT_EQ(*s->grid.resolution, 0.25);
    ASSERT_TRUE(s->grid.extent);
    EXPECT_EQ(*s->grid.extent, (std::array<double, 4>{405004, 5757964, 405060, 5757996}));
    EXPECT_EQ(s->stretch, "percentile");
    EXPECT_EQ(s->resampling, "bilinear");

    auto scene = loadScene(*s, dir / "cache");
    ASSERT_TRUE(scene.ok()) << scene.message();
    EXPECT_EQ(scene->leafon.source.tiles.size(), 2u);
    EXPECT_EQ(scene->leafon.source.crs.epsg(), 32632) << "the tiles without a CRS take \"crs\"";
    EXPECT_EQ(scene->leafoff.source.tiles.size(), 2u);
    EXPECT_EQ(scene->grid.georef.crs.epsg(), 25832);
    EXPECT_EQ(scene->grid.georef.pixelSize, glm::dvec2(0.25));
    EXPECT_EQ(scene->grid.georef.origin, glm::dvec2(405004, 5757996));
    EXPECT_EQ(scene->grid.width, 224);  // 56 m at 0.25 m
    EXPECT_EQ(scene->grid.height, 128); // 32 m
    EXPECT_EQ(scene->resampling, Resampling::Bilinear);
    EXPECT_TRUE(scene->warped());
    EXPECT_FALSE(scene->leafon.stretch.identity) << "\"stretch\": \"percentile\" stretches 8-bit data too";
    EXPECT_FALSE(scene->leafoff.stretch.identity);

    // Each key does something: without "stretch" 8-bit data is taken as it is; without "crs" the leaf-on's tiles
    // are refused, the message suggesting --crs.
    SceneSources autoStretch = *s;
    autoStretch.stretch = "auto";
    auto a = loadScene(autoStretch, dir / "cache");
    ASSERT_TRUE(a.ok()) << a.message();
    EXPECT_TRUE(a->leafon.stretch.identity);
    writeText(dir / "nocrs.json", R"({"leafon": ["tiles/on_w.tif", "tiles/on_e.tif"],
        "leafoff": ["tiles/off_n.tif", "tiles/off_s.tif"], "grid_crs": "EPSG:25832"})");
    auto bare = parseManifest(dir / "nocrs.json");
    ASSERT_TRUE(bare.ok()) << bare.message();
    auto refused = loadScene(*bare, dir / "cache");
    ASSERT_FALSE(refused.ok());
    EXPECT_NE(refused.message().find("on_"), std::string::npos) << refused.message();
    EXPECT_NE(refused.message().find("has no CRS (give one with --crs"), std::string::npos) << refused.message();
}

TEST(SceneTest, FlatSceneFrameAndExtent) {
    Pair p;
    auto scene = loadScene(p.sources(), p.dir / "cache");
    ASSERT_TRUE(scene.ok()) << scene.message();
    EXPECT_FALSE(scene->elevation);
    EXPECT_NEAR(scene->localMin.x, -16, 1e-9);
    EXPECT_NEAR(scene->localMax.x, 16, 1e-9);
    EXPECT_NEAR(scene->localMin.y, -12, 1e-9);
    EXPECT_NEAR(scene->gsd, 0.5, 1e-12);
    EXPECT_DOUBLE_EQ(scene->terrainHeight(3, 4), 0.0);
    const glm::dvec2 px = scene->localToImagePixel({-16, 12}); // north-west corner
    EXPECT_NEAR(px.x, 0, 1e-9);
    EXPECT_NEAR(px.y, 0, 1e-9);
}

TEST(SceneTest, SameGridIsReadAsItIs) {
    Pair p;
    auto scene = loadScene(p.sources(), p.dir / "cache");
    ASSERT_TRUE(scene.ok()) << scene.message();
    EXPECT_FALSE(scene->warped());
    EXPECT_TRUE(scene->leafon.direct && scene->leafoff.direct);
    EXPECT_EQ(scene->grid.width, 64);
    EXPECT_EQ(scene->grid.height, 48);
    EXPECT_EQ(scene->grid.georef.origin, glm::dvec2(405000, 5758000));
    EXPECT_EQ(scene->grid.georef.crs, Crs::utm(32, true));
}

TEST(SceneTest, SeasonsOnOtherGridsGetOneWorkingGrid) {
    Pair p;
    SceneSources s = p.sources();
    // Smaller and shifted by a fraction of a pixel: the union, on the leaf-on's lattice; the leaf-off warped.
    writeTestImage(p.dir / "small.tif", 60, 50, testGeoref(0.5, 405000.15, 5758000.4));
    s.leafoff = p.dir / "small.tif";
    auto a = loadScene(s, p.dir / "cache");
    ASSERT_TRUE(a.ok()) << a.message();
    EXPECT_EQ(a->grid.georef.origin, glm::dvec2(405000, 5758000.5)); // snapped outwards to the leaf-on's pixels
    EXPECT_EQ(a->grid.width, 64);
    EXPECT_EQ(a->grid.height, 51);
    EXPECT_FALSE(a->leafon.direct); // the leaf-on is no longer the whole grid: read through the warper too
    EXPECT_FALSE(a->leafoff.direct);
    // A finer leaf-off (0.25 m) sets the pixel size; the grid is on its lattice.
    writeTestImage(p.dir / "fine.tif", 100, 80, testGeoref(0.25, 405002.0, 5757998.0));
    s.leafoff = p.dir / "fine.tif";
    auto b = loadScene(s, p.dir / "cache");
    ASSERT_TRUE(b.ok()) << b.message();
    EXPECT_EQ(b->grid.georef.pixelSize, glm::dvec2(0.25));
    EXPECT_EQ(b->grid.width, 128);
    EXPECT_EQ(b->grid.height, 96);
    EXPECT_NEAR(b->gsd, 0.25, 1e-12);
    // Grid options: CRS, resolution and extent.
    s.grid.crs = "EPSG:25832"; // ETRS89 / UTM 32N: the same numbers as WGS 84's zone, another datum
    s.grid.resolution = 1.0;
    s.grid.extent = std::array<double, 4>{405004.0, 5757984.0, 405020.0, 5757996.0};
    auto c = loadScene(s, p.dir / "cache");
    ASSERT_TRUE(c.ok()) << c.message();
    EXPECT_EQ(c->grid.georef.crs.epsg(), 25832);
    EXPECT_EQ(c->grid.width, 16);
    EXPECT_EQ(c->grid.height, 12);
    EXPECT_TRUE(c->warped());
    s.grid.extent = std::array<double, 4>{500000.0, 5000000.0, 500010.0, 5000010.0};
    auto d = loadScene(s, p.dir / "cache");
    ASSERT_FALSE(d.ok());
    EXPECT_NE(d.message().find("--extent"), std::string::npos) << d.message();
}

// --extent in degrees (the default when the numbers read as longitudes and latitudes), in a CRS named by
// --extent-crs ("grid": the grid's), or the footprint of an input (--extent-of); the web keys of a manifest.
TEST(SceneTest, ExtentInDegreesInItsOwnCrsOrAnInputsFootprint) {
    Pair p;
    SceneSources s = p.sources();
    s.grid.resolution = 1.0;
    const glm::dvec2 lo(405004.0, 5757984.0), hi(405020.0, 5757996.0); // UTM 32N, inside both seasons
    s.grid.extent = std::array<double, 4>{lo.x, lo.y, hi.x, hi.y};     // projected numbers: the grid's CRS
    auto a = loadScene(s, p.dir / "cache");
    ASSERT_TRUE(a.ok()) << a.message();
    EXPECT_EQ(a->grid.width, 16);
    EXPECT_EQ(a->grid.height, 12);
    s.grid.extentCrs = "grid";
    auto b = loadScene(s, p.dir / "cache");
    ASSERT_TRUE(b.ok()) << b.message();
    EXPECT_EQ(b->grid.width, 16);
    // The same box in degrees: its outline in UTM is the box, give or take the curvature of a 16 m square.
    std::vector<glm::dvec2> corners = {lo, hi};
    convert(Crs::utm(32, true), Crs::geographic(), corners);
    s.grid.extent = std::array<double, 4>{corners[0].x, corners[0].y, corners[1].x, corners[1].y};
    s.grid.extentCrs.clear();
    auto c = loadScene(s, p.dir / "cache");
    ASSERT_TRUE(c.ok()) << c.message();
    EXPECT_EQ(c->grid.georef.crs.epsg(), 32632);
    EXPECT_GE(c->grid.width, 16);
    EXPECT_LE(c->grid.width, 18); // the grid's meridian convergence (~0.8°) turns the box
    EXPECT_GE(c->grid.height, 12);
    EXPECT_LE(c->grid.height, 14);
    s.grid.extentCrs = "EPSG:4326";
    auto d = loadScene(s, p.dir / "cache");
    ASSERT_TRUE(d.ok()) << d.message();
    EXPECT_EQ(d->grid.width, c->grid.width);
    // Named as an input's footprint: the leaf-off's (the whole 32 x 24 m).
    s.grid.extent.reset();
    s.grid.extentCrs.clear();
    s.grid.extentOf = "leafoff";
    auto e = loadScene(s, p.dir / "cache");
    ASSERT_TRUE(e.ok()) << e.message();
    EXPECT_EQ(e->grid.width, 32);
    EXPECT_EQ(e->grid.height, 24);
    // Errors name the flag.
    s.grid.extentOf = "dem";
    auto f = loadScene(s, p.dir / "cache");
    ASSERT_FALSE(f.ok());
    EXPECT_NE(f.message().find("--extent-of dem: no DEM given"), std::string::npos) << f.message();
    s.grid.extentOf.clear();
    s.grid.extent = std::array<double, 4>{lo.x, lo.y, hi.x, hi.y};
    s.grid.extentCrs = "EPSG:0";
    auto g = loadScene(s, p.dir / "cache");
    ASSERT_FALSE(g.ok());
    EXPECT_EQ(g.message().rfind("--extent-crs: ", 0), 0u) << g.message();

    writeText(p.dir / "web.json", R"({"leafon": "on.tif", "leafoff": "off.tif", "extent": [8.1, 52.0, 8.2, 52.1],
        "extent_crs": "EPSG:4326", "offline": true, "web_cache_mb": 64})");
    auto m = parseManifest(p.dir / "web.json");
    ASSERT_TRUE(m.ok()) << m.message();
    EXPECT_TRUE(m->warnings.empty()) << m->warnings.front();
    EXPECT_EQ(m->grid.extentCrs, "EPSG:4326");
    EXPECT_TRUE(m->offline);
    EXPECT_EQ(m->webCacheMb, 64);
    writeText(p.dir / "of.json", R"({"leafon": "on.tif", "leafoff": "off.tif", "extent_of": "leafon",
        "web_cache_mb": 0})");
    auto bad = parseManifest(p.dir / "of.json");
    ASSERT_FALSE(bad.ok());
    EXPECT_NE(bad.message().find("'web_cache_mb' must be a positive number"), std::string::npos) << bad.message();
}

TEST(SceneTest, SeasonsThatDoNotOverlapAreAnError) {
    Pair p;
    writeTestImage(p.dir / "far.tif", 64, 48, testGeoref(0.5, 405100, 5758000));
    SceneSources s = p.sources();
    s.leafoff = p.dir / "far.tif";
    auto b = loadScene(s, p.dir / "cache");
    ASSERT_FALSE(b.ok());
    EXPECT_EQ(b.message().rfind((p.dir / "far.tif").string() + ": does not overlap the leaf-on", 0), 0u) << b.message();
    EXPECT_EQ(b.message().find('\n'), std::string::npos);
}

TEST(SceneTest, DemWithHolesIsFilledAndSaidSo) {
    Pair p;
    writeDem(p.dir / "dem.tif", 20, 16, testGeoref(2.0, 404996, 5758004), 100.0f, 7);
    SceneSources s = p.sources();
    s.elevation = p.dir / "dem.tif";
    auto scene = loadScene(s, p.dir / "cache");
    ASSERT_TRUE(scene.ok()) << scene.message();
    ASSERT_TRUE(scene->elevation);
    EXPECT_GT(scene->elevation->filledSamples, 0);
    ASSERT_EQ(scene->notes.size(), 1u);
    EXPECT_NE(scene->notes[0].find("filled"), std::string::npos);
    for (float v : scene->elevation->heights.pixels) EXPECT_FALSE(std::isnan(v));
    // Heights rise by 1 m per sample east, 2 m per sample south: bilinear sampling follows.
    const double h0 = scene->terrainHeight(0, 0), hEast = scene->terrainHeight(4, 0), hNorth = scene->terrainHeight(0, 4);
    EXPECT_NEAR(hEast - h0, 2.0, 0.6);
    EXPECT_NEAR(hNorth - h0, -4.0, 1.2);
}

TEST(SceneTest, AllNanDemIsAnError) {
    Pair p;
    writeDem(p.dir / "nan.tif", 8, 8, testGeoref(4.0, 404990, 5758010), std::numeric_limits<float>::quiet_NaN());
    SceneSources s = p.sources();
    s.elevation = p.dir / "nan.tif";
    auto scene = loadScene(s, p.dir / "cache");
    ASSERT_FALSE(scene.ok());
    EXPECT_NE(scene.message().find("nan.tif: DEM has no valid heights (all 64 samples"), std::string::npos)
        << scene.message();
}

TEST(SceneTest, DemOutsideTheImageryIsAnError) {
    Pair p;
    writeDem(p.dir / "far.tif", 8, 8, testGeoref(4.0, 500000, 5000000), 1.0f);
    SceneSources s = p.sources();
    s.elevation = p.dir / "far.tif";
    auto scene = loadScene(s, p.dir / "cache");
    ASSERT_FALSE(scene.ok());
    EXPECT_NE(scene.message().find("does not cover the imagery"), std::string::npos) << scene.message();
}

TEST(HeightfieldTest, FillHolesPushPull) {
    Image<float> img;
    img.width = 5;
    img.height = 1;
    img.channels = 1;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    img.pixels = {10, nan, nan, nan, 20};
    EXPECT_EQ(fillHoles(img), 3);
    for (float v : img.pixels) {
        EXPECT_GE(v, 10.0f);
        EXPECT_LE(v, 20.0f);
    }
    img.pixels = {nan, nan, nan, nan, nan};
    EXPECT_EQ(fillHoles(img), -1);
}

TEST(ReferenceMeshTest, FlatGridCoversTheImage) {
    Pair p;
    auto scene = loadScene(p.sources(), p.dir / "cache");
    ASSERT_TRUE(scene.ok());
    const ReferenceMesh m = buildReferenceMesh(*scene, 8);
    EXPECT_EQ(m.columns, 9);
    EXPECT_EQ(m.vertices.size(), 81u);
    EXPECT_EQ(m.indices.size(), 8u * 8u * 6u);
    EXPECT_FLOAT_EQ(m.vertices.front().u, 0.0f);
    EXPECT_FLOAT_EQ(m.vertices.back().v, 1.0f);
    EXPECT_FLOAT_EQ(m.vertices.front().x, -16.0f);
    EXPECT_FLOAT_EQ(m.vertices.front().y, 12.0f);
}

TEST(ReferenceMeshTest, DemMeshUsesEverySampleAndSpansTheImagery) {
    Pair p;
    writeDem(p.dir / "dem.tif", 50, 50, testGeoref(1.0, 404990, 5758010), 50.0f);
    SceneSources s = p.sources();
    s.elevation = p.dir / "dem.tif";
    auto scene = loadScene(s, p.dir / "cache");
    ASSERT_TRUE(scene.ok()) << scene.message();
    const ReferenceMesh m = buildReferenceMesh(*scene);
    EXPECT_EQ(m.stride, 1);
    // Imagery spans 32 m x 24 m = 32 x 24 DEM samples, plus a margin of one sample each side.
    EXPECT_GE(m.columns, 33);
    EXPECT_LE(m.columns, 37);
    float umin = 1e9f, umax = -1e9f;
    for (const auto& v : m.vertices) {
        umin = std::min(umin, v.u);
        umax = std::max(umax, v.u);
    }
    EXPECT_LT(umin, 0.0f);
    EXPECT_GT(umax, 1.0f);
    const ReferenceMesh dec = buildReferenceMesh(*scene, 64, 400);
    EXPECT_GE(dec.stride, 2);
    EXPECT_LE(std::int64_t(dec.vertices.size()), 400);
}

TEST(ReferenceMeshTest, TileLayout) {
    const TileLayout one = computeTileLayout(1000, 700, 16384);
    EXPECT_EQ(one.layers(), 1);
    EXPECT_EQ(one.border, 0);
    EXPECT_EQ(one.tileWidth, 1000);
    const TileLayout many = computeTileLayout(1000, 700, 256);
    EXPECT_EQ(many.border, 1);
    EXPECT_EQ(many.step, 254);
    EXPECT_EQ(many.tilesX, 4); // 4 * 254 >= 1000
    EXPECT_EQ(many.tilesY, 3); // 3 * 254 >= 700
    EXPECT_LT((many.tilesX - 1) * many.step, 1000);
}

// The triangulated surface is the reference mesh's: exact at samples, planar on each side of the NE-SW diagonal,
// where it differs from the bilinear one.
TEST(HeightfieldTest, TriangulatedSurfaceSplitsCellsAlongTheReferenceDiagonal) {
    Heightfield f;
    f.heights.width = f.heights.height = 2;
    f.heights.channels = 1;
    f.heights.pixels = {0.0f, 10.0f, 20.0f, 0.0f}; // h00 (NW), h10 (NE), h01 (SW), h11 (SE)
    f.georef = testGeoref(1.0);
    auto at = [&](double fx, double fy) { return f.georef.pixelToCrs({0.5 + fx, 0.5 + fy}); };
    EXPECT_DOUBLE_EQ(f.sampleCrsTriangulated(at(0, 0)), 0.0);
    EXPECT_DOUBLE_EQ(f.sampleCrsTriangulated(at(1, 0)), 10.0);
    EXPECT_DOUBLE_EQ(f.sampleCrsTriangulated(at(0, 1)), 20.0);
    EXPECT_DOUBLE_EQ(f.sampleCrsTriangulated(at(1, 1)), 0.0);
    EXPECT_DOUBLE_EQ(f.sampleCrsTriangulated(at(0.5, 0.5)), 15.0); // on the NE-SW diagonal: mean of NE and SW
    EXPECT_DOUBLE_EQ(f.sampleCrs(at(0.5, 0.5)), 7.5);               // bilinear: mean of all four
    EXPECT_DOUBLE_EQ(f.sampleCrsTriangulated(at(0.25, 0.25)), 7.5); // NW triangle: 0 + 0.25*10 + 0.25*20
    EXPECT_DOUBLE_EQ(f.sampleCrsTriangulated(at(0.75, 0.75)), 7.5); // SE triangle: 0 + 0.25*20 + 0.25*10
}

// A service description's identity is what it describes: the run's options (offline, the cache and its bound,
// connections, timeout, User-Agent) leave it, and so the pyramid made from it, unchanged; another window changes it.
TEST(SceneTest, ServiceDescriptionIdentityIgnoresTheRunsOptions) {
    TempDir dir("service-identity");
    const std::string head = "<GDAL_WMS>\n  <Service name=\"TMS\"><ServerUrl>http://h/${z}/${x}/${y}.png</ServerUrl>"
                             "</Service>\n  <DataWindow><TileLevel>17</TileLevel><TileX>10</TileX></DataWindow>\n";
    writeText(dir / "a.xml", head + "  <OfflineMode>false</OfflineMode><Cache><Path>/c</Path></Cache>\n</GDAL_WMS>\n");
    writeText(dir / "b.xml", head + "  <OfflineMode>true</OfflineMode><Cache><Path>/d</Path><MaxSize>1048576</MaxSize>"
                                    "</Cache><MaxConnections>2</MaxConnections><Timeout>5</Timeout><UserAgent>x"
                                    "</UserAgent>\n</GDAL_WMS>\n");
    std::string other = head;
    other.replace(other.find("<TileX>10"), 9, "<TileX>11");
    writeText(dir / "c.xml", other + "</GDAL_WMS>\n");
    auto a = fileIdentity(dir / "a.xml"), b = fileIdentity(dir / "b.xml"), c = fileIdentity(dir / "c.xml");
    ASSERT_TRUE(a.ok() && b.ok() && c.ok());
    EXPECT_EQ(*a, *b);
    EXPECT_NE(*a, *c);
    EXPECT_EQ(a->rfind("service|", 0), 0u) << *a;
    writeText(dir / "plain.xml", "<VRTDataset/>");
    auto plain = fileIdentity(dir / "plain.xml");
    ASSERT_TRUE(plain.ok());
    EXPECT_NE(plain->rfind("service|", 0), 0u) << "other XML files keep path|size|mtime";
}

// The tile cache's bound: the least recently fetched tiles go first, until what is left fits.
TEST(SceneTest, TileCacheTrimRemovesTheOldestTilesBeyondTheBound) {
    TempDir dir("tile-trim");
    const auto now = std::filesystem::file_time_type::clock::now();
    for (int i = 0; i < 5; ++i) {
        const auto f = dir / ("a" + std::to_string(i % 2)) / ("t" + std::to_string(i) + ".png");
        std::filesystem::create_directories(f.parent_path());
        writeText(f, std::string(1000, 'x'));
        std::filesystem::last_write_time(f, now - std::chrono::hours(10 - i)); // t0 oldest
    }
    EXPECT_EQ(web::trimTileCache(dir.path(), 5000), 0);
    EXPECT_EQ(web::trimTileCache(dir.path(), 2500), 3000);
    EXPECT_FALSE(std::filesystem::exists(dir / "a0/t0.png"));
    EXPECT_FALSE(std::filesystem::exists(dir / "a1/t1.png"));
    EXPECT_FALSE(std::filesystem::exists(dir / "a0/t2.png"));
    EXPECT_TRUE(std::filesystem::exists(dir / "a1/t3.png"));
    EXPECT_TRUE(std::filesystem::exists(dir / "a0/t4.png"));
    EXPECT_EQ(web::trimTileCache(dir / "none", 0), 0);
}

// Heights in the colour of 8-bit RGB tiles: Mapbox Terrain-RGB and Terrarium decode exactly, alpha 0 is no data
// (filled); a DEM of other samples is refused for them.
TEST(SceneTest, HeightsEncodedInColourDecodeExactly) {
    TempDir dir("dem-rgb");
    const int w = 32, h = 24;
    const Georef g = testGeoref(1.0);
    const auto write = [&](const std::filesystem::path& p, bool terrarium) {
        GDALAllRegister();
        GDALDatasetH ds = GDALCreate(GDALGetDriverByName("GTiff"), p.c_str(), w, h, 4, GDT_Byte, nullptr);
        ASSERT_TRUE(ds);
        double gt[6] = {g.origin.x, g.pixelSize.x, 0, g.origin.y, 0, -g.pixelSize.y};
        GDALSetGeoTransform(ds, gt);
        GDALSetProjection(ds, g.crs.wkt().c_str());
        std::vector<std::uint8_t> px(size_t(w) * h * 4);
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                const double height = 100.0 + 3.5 * x - 2.5 * y; // exact in both encodings
                std::uint8_t* p4 = &px[(size_t(y) * w + x) * 4];
                if (terrarium) {
                    const double v = height + 32768.0;
                    p4[0] = std::uint8_t(std::floor(v / 256.0));
                    p4[1] = std::uint8_t(int(std::floor(v)) % 256);
                    p4[2] = std::uint8_t(std::floor((v - std::floor(v)) * 256.0));
                } else {
                    const long long v = std::llround((height + 10000.0) * 10.0);
                    p4[0] = std::uint8_t(v >> 16), p4[1] = std::uint8_t((v >> 8) & 255), p4[2] = std::uint8_t(v & 255);
                }
                p4[3] = (x == 5 && y == 5) ? 0 : 255;
            }
        ASSERT_EQ(GDALDatasetRasterIO(ds, GF_Write, 0, 0, w, h, px.data(), w, h, GDT_Byte, 4, nullptr, 4, w * 4, 1),
                  CE_None);
        GDALSetRasterColorInterpretation(GDALGetRasterBand(ds, 4), GCI_AlphaBand);
        GDALClose(ds);
    };
    write(dir / "mapbox.tif", false);
    write(dir / "terrarium.tif", true);
    ASSERT_FALSE(HasFailure());
    WorkingGrid area{g, w, h};
    for (const auto& [file, enc] : {std::pair{"mapbox.tif", HeightEncoding::Mapbox}, {"terrarium.tif", HeightEncoding::Terrarium}}) {
        auto m = openMosaic(SourceList{dir / file}, "DEM");
        ASSERT_TRUE(m.ok()) << m.message();
        auto hf = loadHeightfield(*m, area, enc);
        ASSERT_TRUE(hf.ok()) << hf.message();
        EXPECT_EQ(hf->filledSamples, 1) << file;
        const glm::dvec2 at = hf->georef.crsToPixel(g.pixelToCrs({10.5, 7.5}));
        const float v = hf->heights.pixels[size_t(at.y) * hf->heights.width + size_t(at.x)];
        EXPECT_FLOAT_EQ(v, float(100.0 + 3.5 * 10 - 2.5 * 7)) << file;
    }
    EXPECT_FALSE(parseHeightEncoding("terrain").ok());
    EXPECT_EQ(*parseHeightEncoding("mapbox"), HeightEncoding::Mapbox);
}
