// `seasonview synth`: determinism, ground truth consistent with the pixels, season differences, real DEM.
#include "Raster.h"
#include "Scene.h"
#include "SyntheticScene.h"
#include "TestUtil.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <sstream>

using namespace seasonview;
using namespace seasonview::test;

namespace {

const char* const kFiles[] = {"leafon.tif", "leafoff.tif",  "dem.tif",  "truth_deciduous.png",
                              "truth_conifer.png", "trees.csv", "scene.json"};


SynthOptions smallScene(std::uint64_t seed, int threads = 0) {
    SynthOptions o;
    o.sizeM = 128.0; // 256 x 256 pixels: small, but a real layout (margins, roads, trees of both kinds)
    o.gsd = 0.5;
    o.seed = seed;
    o.threads = threads;
    return o;
}

void generate(const SynthOptions& o, const std::filesystem::path& dir, int pixels = 256) {
    auto r = generateSyntheticScene(o, dir);
    ASSERT_TRUE(r.ok()) << r.message();
    EXPECT_EQ(r->width, pixels);
    EXPECT_EQ(r->height, pixels);
}

// A geographic DEM (64² samples, ~2 km) around (lon, lat): smooth hills and a slope.
void writeDem(const std::filesystem::path& path, double lon, double lat) {
    const int n = 64;
    const double step = 0.0003;
    std::vector<float> z(size_t(n) * n);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
            z[size_t(j) * n + size_t(i)] =
                300.0f + 80.0f * std::sin(float(i) * 0.2f) * std::cos(float(j) * 0.15f) + 2.0f * float(i);
    const Georef g{Crs::geographic(), glm::dvec2(lon - 0.5 * n * step, lat + 0.5 * n * step), glm::dvec2(step)};
    ASSERT_TRUE(writeGeoTiff(path, z.data(), SampleType::F32, n, n, 1, g).ok());
}

void expectSameFiles(const std::filesystem::path& a, const std::filesystem::path& b, const std::string& what) {
    for (const char* f : kFiles) {
        const std::string x = readBytes(a / f);
        EXPECT_FALSE(x.empty()) << f;
        EXPECT_TRUE(x == readBytes(b / f)) << f << ": " << what;
    }
}

struct TreeRow {
    long id = 0;
    bool conifer = false;
    double x = 0, y = 0, easting = 0, northing = 0, radius = 0, height = 0;
};

std::vector<TreeRow> readTrees(const std::filesystem::path& csv) {
    std::ifstream f(csv);
    std::string line;
    std::getline(f, line);
    EXPECT_EQ(line, "id,type,x,y,easting,northing,radius_m,height_m");
    std::vector<TreeRow> rows;
    while (std::getline(f, line)) {
        std::replace(line.begin(), line.end(), ',', ' ');
        std::istringstream s(line);
        TreeRow t;
        std::string type;
        s >> t.id >> type >> t.x >> t.y >> t.easting >> t.northing >> t.radius >> t.height;
        EXPECT_TRUE(type == "deciduous" || type == "conifer") << type;
        t.conifer = type == "conifer";
        rows.push_back(t);
    }
    return rows;
}

// One scene shared by the read-only checks (generation is the slow part).
class SynthSceneTest : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        s_dir = new TempDir("synth");
        generate(smallScene(3), s_dir->path());
    }
    static void TearDownTestSuite() {
        delete s_dir;
        s_dir = nullptr;
    }
    static const std::filesystem::path& dir() { return s_dir->path(); }
    static inline TempDir* s_dir = nullptr;
};

} // namespace

TEST(SyntheticSceneTest, SameSeedGivesIdenticalFiles) {
    TempDir a("synth-a"), b("synth-b");
    generate(smallScene(5), a.path());
    generate(smallScene(5), b.path());
    for (const char* f : kFiles) {
        const std::string x = readBytes(a / f), y = readBytes(b / f);
        EXPECT_FALSE(x.empty()) << f;
        EXPECT_TRUE(x == y) << f << " differs between two runs with the same seed";
    }
}

TEST(SyntheticSceneTest, ThreadCountDoesNotChangeTheOutput) {
    TempDir a("synth-t1"), b("synth-t2"), c("synth-t3");
    generate(smallScene(6, 1), a.path());
    generate(smallScene(6, 2), b.path());
    generate(smallScene(6, 3), c.path());
    for (const char* f : kFiles) {
        EXPECT_TRUE(readBytes(a / f) == readBytes(b / f)) << f << ": 1 vs 2 threads";
        EXPECT_TRUE(readBytes(a / f) == readBytes(c / f)) << f << ": 1 vs 3 threads";
    }
}

TEST(SyntheticSceneTest, BandHeightDoesNotChangeTheOutput) {
    // 384² pixels. One band; bands of 100 rows (they split the 256-pixel tiles, the 32-row object slabs and the
    // shadow sweep, which runs bottom up here, against the writing order); bands of 256 rows on tile boundaries.
    SynthOptions o = smallScene(9);
    o.sizeM = 192.0;
    TempDir whole("synth-band-whole"), b100("synth-band-100"), b256("synth-band-256");
    generate(o, whole.path(), 384);
    o.bandRows = 100;
    generate(o, b100.path(), 384);
    o.bandRows = 256;
    o.threads = 1;
    generate(o, b256.path(), 384);
    expectSameFiles(whole.path(), b100.path(), "one band vs bands of 100 rows");
    expectSameFiles(whole.path(), b256.path(), "one band vs bands of 256 rows on one thread");
}

TEST(SyntheticSceneTest, BandHeightDoesNotChangeTheOutputSouthOfTheEquator) {
    // In the southern hemisphere the sun is in the north: the shadow sweep runs top down, with the bands.
    TempDir d("synth-south"), a("synth-south-a"), b("synth-south-b");
    writeDem(d / "dem.tif", 18.4, -33.9);
    SynthOptions o = smallScene(4);
    o.sizeM = 160.0;
    o.dem = d / "dem.tif";
    auto r = generateSyntheticScene(o, a.path());
    ASSERT_TRUE(r.ok()) << r.message();
    EXPECT_EQ(r->crs, Crs::utm(34, false).name());
    o.bandRows = 48;
    o.threads = 3;
    generate(o, b.path(), 320);
    expectSameFiles(a.path(), b.path(), "one band vs bands of 48 rows");
}

TEST(SyntheticSceneTest, LargeScenesGetGeoTiffTruthMasks) {
    // The switch to GeoTIFF masks happens at 32768 pixels; a low threshold tests it on a small scene.
    TempDir png("synth-mask-png"), tif("synth-mask-tif");
    SynthOptions o = smallScene(3);
    generate(o, png.path());
    std::ofstream(tif / "truth_conifer.png") << "stale mask of an earlier run";
    o.pngMasksUpTo = 128;
    o.bandRows = 96;
    generate(o, tif.path());
    const auto j = nlohmann::json::parse(readBytes(tif / "scene.json"));
    EXPECT_EQ(j["truth"]["deciduous"], "truth_deciduous.tif");
    EXPECT_EQ(j["truth"]["conifer"], "truth_conifer.tif");
    EXPECT_FALSE(std::filesystem::exists(tif / "truth_conifer.png"));
    auto src = parseManifest(tif / "scene.json");
    ASSERT_TRUE(src.ok()) << src.message();
    EXPECT_TRUE(readBytes(png / "leafon.tif") == readBytes(tif / "leafon.tif"));
    auto imagery = readRasterInfo(tif / "leafon.tif");
    ASSERT_TRUE(imagery.ok() && imagery->georef);
    for (const char* kind : {"deciduous", "conifer"}) {
        const std::string name = std::string("truth_") + kind;
        auto info = readRasterInfo(tif / (name + ".tif"));
        ASSERT_TRUE(info.ok()) << info.message();
        EXPECT_EQ(info->channels, 1);
        EXPECT_EQ(info->type, SampleType::U8);
        EXPECT_TRUE(info->tiled);
        ASSERT_TRUE(info->georef);
        EXPECT_EQ(info->georef->crs.epsg(), imagery->georef->crs.epsg());
        EXPECT_DOUBLE_EQ(info->georef->origin.x, imagery->georef->origin.x);
        EXPECT_DOUBLE_EQ(info->georef->origin.y, imagery->georef->origin.y);
        EXPECT_DOUBLE_EQ(info->georef->pixelSize.x, imagery->georef->pixelSize.x);
        auto a = readImageU8(png / (name + ".png"), 1);
        auto b = readImageU8(tif / (name + ".tif"), 1);
        ASSERT_TRUE(a.ok() && b.ok());
        EXPECT_TRUE(a->pixels == b->pixels) << kind;
    }
}

TEST(SyntheticSceneTest, DifferentSeedGivesDifferentScene) {
    TempDir a("synth-s1"), b("synth-s2");
    generate(smallScene(7), a.path());
    generate(smallScene(8), b.path());
    EXPECT_FALSE(readBytes(a / "leafon.tif") == readBytes(b / "leafon.tif"));
    EXPECT_FALSE(readBytes(a / "trees.csv") == readBytes(b / "trees.csv"));
}

TEST(SyntheticSceneTest, RejectsBadOptions) {
    TempDir d("synth-bad");
    SynthOptions o = smallScene(1);
    o.gsd = 0.0;
    EXPECT_FALSE(generateSyntheticScene(o, d.path()).ok());
    o = smallScene(1);
    o.sizeM = 4.0; // 8 pixels: too small
    EXPECT_FALSE(generateSyntheticScene(o, d.path()).ok());
    o = smallScene(1);
    o.bandRows = -1;
    EXPECT_FALSE(generateSyntheticScene(o, d.path()).ok());
    o = smallScene(1);
    o.dem = d / "missing.tif";
    auto r = generateSyntheticScene(o, d.path());
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.message().find("missing.tif"), std::string::npos) << r.message();
    EXPECT_FALSE(std::filesystem::exists(d / "scene.json"));
}

TEST_F(SynthSceneTest, ManifestHasTheDocumentedShape) {
    const auto j = nlohmann::json::parse(readBytes(dir() / "scene.json"));
    EXPECT_EQ(j["leafon"], "leafon.tif");
    EXPECT_EQ(j["leafoff"], "leafoff.tif");
    EXPECT_EQ(j["elevation"], "dem.tif");
    EXPECT_EQ(j["truth"]["deciduous"], "truth_deciduous.png");
    EXPECT_EQ(j["truth"]["conifer"], "truth_conifer.png");
    EXPECT_EQ(j["truth"]["trees"], "trees.csv");
    EXPECT_EQ(j["generator"]["program"], "seasonview synth");
    EXPECT_EQ(j["generator"]["version"], kSynthGeneratorVersion);
    // 128 m hold no settlement: no city model is written and the manifest names none (a scene with buildings
    // names city/city.obj: CityModelTest.SyntheticSceneCityMatchesItsBuildings).
    EXPECT_FALSE(j.contains("buildings"));
    EXPECT_FALSE(std::filesystem::exists(dir() / "city/city.obj"));
    EXPECT_EQ(j["generator"]["seed"], 3);
    EXPECT_EQ(j["generator"]["size_m"], 128.0);
    EXPECT_EQ(j["generator"]["gsd"], 0.5);
    EXPECT_EQ(j["generator"]["dem"], "");
    const double h = j["parameters"]["tree_height_m"];
    EXPECT_GT(h, 5.0);
    EXPECT_LT(h, 32.0);
    // The scene loader accepts it.
    auto src = parseManifest(dir() / "scene.json");
    ASSERT_TRUE(src.ok()) << src.message();
    EXPECT_NEAR(src->treeHeightM, h, 1e-9);
}

TEST_F(SynthSceneTest, GeoreferencingIsUtm32NearMuensterOnOneExtent) {
    auto on = readRasterInfo(dir() / "leafon.tif");
    auto off = readRasterInfo(dir() / "leafoff.tif");
    auto dem = readRasterInfo(dir() / "dem.tif");
    ASSERT_TRUE(on.ok() && off.ok() && dem.ok());
    for (const RasterInfo* i : {&*on, &*off}) {
        EXPECT_EQ(i->width, 256);
        EXPECT_EQ(i->channels, 3);
        EXPECT_EQ(i->type, SampleType::U8);
        EXPECT_TRUE(i->tiled);
        ASSERT_TRUE(i->georef);
        EXPECT_EQ(i->georef->crs.epsg(), 32632);
        EXPECT_DOUBLE_EQ(i->georef->origin.x, 405000.0 - 64.0);
        EXPECT_DOUBLE_EQ(i->georef->origin.y, 5757000.0 + 64.0);
        EXPECT_DOUBLE_EQ(i->georef->pixelSize.x, 0.5);
    }
    EXPECT_EQ(dem->type, SampleType::F32);
    ASSERT_TRUE(dem->georef);
    EXPECT_EQ(dem->georef->crs.epsg(), 32632);
    EXPECT_DOUBLE_EQ(dem->georef->origin.x, on->georef->origin.x);
    EXPECT_DOUBLE_EQ(dem->georef->origin.y, on->georef->origin.y);
    EXPECT_NEAR(dem->georef->pixelSize.x * dem->width, 128.0, 1e-9); // same extent as the imagery
    EXPECT_NEAR(dem->georef->pixelSize.y * dem->height, 128.0, 1e-9);
}

TEST_F(SynthSceneTest, TruthMasksAreBinaryNonEmptyAndDisjoint) {
    auto dec = readImageU8(dir() / "truth_deciduous.png", 1);
    auto con = readImageU8(dir() / "truth_conifer.png", 1);
    ASSERT_TRUE(dec.ok() && con.ok());
    ASSERT_EQ(dec->width, 256);
    ASSERT_EQ(con->width, 256);
    size_t nd = 0, nc = 0;
    for (size_t i = 0; i < dec->pixels.size(); ++i) {
        const int a = dec->pixels[i], b = con->pixels[i];
        ASSERT_TRUE((a == 0 || a == 255) && (b == 0 || b == 255));
        ASSERT_FALSE(a == 255 && b == 255) << "pixel " << i << " is both deciduous and conifer";
        nd += a == 255;
        nc += b == 255;
    }
    EXPECT_GT(nd, 0u);
    EXPECT_GT(nc, 0u);
}

TEST_F(SynthSceneTest, TreeListAgreesWithTruthMasks) {
    const auto trees = readTrees(dir() / "trees.csv");
    auto dec = readImageU8(dir() / "truth_deciduous.png", 1);
    auto con = readImageU8(dir() / "truth_conifer.png", 1);
    ASSERT_TRUE(dec.ok() && con.ok());
    int inside = 0;
    for (const TreeRow& t : trees) {
        EXPECT_NEAR(t.easting - t.x, 405000.0, 1e-3);
        EXPECT_NEAR(t.northing - t.y, 5757000.0, 1e-3);
        EXPECT_GE(t.radius, 1.5);
        EXPECT_LE(t.radius, 7.0);
        // A tree's centre pixel shows that tree (no other crown covers a tree's centre).
        const int col = int(std::floor((t.x + 64.0) / 0.5)), row = int(std::floor((64.0 - t.y) / 0.5));
        if (col < 0 || row < 0 || col >= 256 || row >= 256) continue;
        ++inside;
        EXPECT_EQ((t.conifer ? con : dec)->at(col, row), 255) << "tree " << t.id << " at " << t.x << "," << t.y;
    }
    EXPECT_GT(inside, 0);
    // Every mask pixel lies in a listed crown disc of its type, and every pixel inside some disc is in a mask
    // (pixels within 1 cm of a rim are skipped: the CSV rounds to millimetres).
    int checked = 0;
    for (int row = 0; row < 256; ++row)
        for (int col = 0; col < 256; ++col) {
            const double x = -64.0 + (col + 0.5) * 0.5, y = 64.0 - (row + 0.5) * 0.5;
            bool inDec = false, inCon = false, nearRim = false;
            for (const TreeRow& t : trees) {
                const double d = std::hypot(x - t.x, y - t.y);
                if (std::abs(d - t.radius) < 0.01) nearRim = true;
                if (d < t.radius) (t.conifer ? inCon : inDec) = true;
            }
            if (nearRim) continue;
            ++checked;
            const bool mDec = dec->at(col, row) == 255, mCon = con->at(col, row) == 255;
            ASSERT_EQ(mDec || mCon, inDec || inCon) << "pixel " << col << "," << row;
            if (mDec) {
                ASSERT_TRUE(inDec) << "pixel " << col << "," << row;
            }
            if (mCon) {
                ASSERT_TRUE(inCon) << "pixel " << col << "," << row;
            }
        }
    EXPECT_GT(checked, 60000);
}

TEST_F(SynthSceneTest, SeasonsDifferInExposureAndColour) {
    auto on = readImageU8(dir() / "leafon.tif", 3);
    auto off = readImageU8(dir() / "leafoff.tif", 3);
    ASSERT_TRUE(on.ok() && off.ok());
    double mOn[3] = {0, 0, 0}, mOff[3] = {0, 0, 0};
    const size_t n = size_t(on->width) * size_t(on->height);
    for (size_t i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c) {
            mOn[c] += on->pixels[i * 3 + size_t(c)];
            mOff[c] += off->pixels[i * 3 + size_t(c)];
        }
    double diff = 0.0;
    for (int c = 0; c < 3; ++c) {
        mOn[c] /= double(n);
        mOff[c] /= double(n);
        EXPECT_GT(mOn[c], 20.0);  // neither season is black or blown out
        EXPECT_LT(mOn[c], 220.0);
        EXPECT_GT(mOff[c], 20.0);
        EXPECT_LT(mOff[c], 220.0);
        diff += std::abs(mOn[c] - mOff[c]);
    }
    EXPECT_GT(diff, 6.0) << "mean colours " << mOn[0] << "," << mOn[1] << "," << mOn[2] << " vs " << mOff[0] << ","
                         << mOff[1] << "," << mOff[2];
    // Leaf-on is the greener season.
    EXPECT_GT(mOn[1] - mOn[0], mOff[1] - mOff[0]);
}

TEST(SyntheticSceneTest, RealDemGivesItsHeightsInItsUtmZone) {
    const std::filesystem::path demPath = SEASONVIEW_DATA_DIR "/dem/mt_rainier_90m.tif";
    std::filesystem::path p = demPath;
    if (const char* e = std::getenv("SEASONVIEW_DATA"); e && *e) p = std::filesystem::path(e) / "dem/mt_rainier_90m.tif";
    if (!std::filesystem::exists(p)) GTEST_SKIP() << "real data not found (" << p << "); set SEASONVIEW_DATA";
    TempDir d("synth-dem");
    SynthOptions o = smallScene(2);
    o.dem = p;
    auto r = generateSyntheticScene(o, d.path());
    ASSERT_TRUE(r.ok()) << r.message();
    EXPECT_EQ(r->crs, Crs::utm(10, true).name()); // Mount Rainier: 121.8 W
    auto dem = readImageF32(d / "dem.tif", 1);
    auto info = readRasterInfo(d / "dem.tif");
    ASSERT_TRUE(dem.ok() && info.ok());
    ASSERT_TRUE(info->georef);
    EXPECT_EQ(info->georef->crs.epsg(), 32610);
    // Centred on the DEM's centre, rounded to whole metres.
    const glm::dvec2 c = info->georef->origin + glm::dvec2(64.0, -64.0);
    EXPECT_EQ(c.x, std::round(c.x));
    EXPECT_EQ(c.y, std::round(c.y));
    float lo = 1e9f, hi = -1e9f;
    for (float v : dem->pixels) {
        ASSERT_TRUE(std::isfinite(v));
        lo = std::min(lo, v);
        hi = std::max(hi, v);
    }
    EXPECT_GE(lo, 263.0f);
    EXPECT_LE(hi, 4371.0f);
    EXPECT_GT(hi - lo, 1.0f) << "a 128 m crop of a mountain DEM is not flat";
    const auto j = nlohmann::json::parse(readBytes(d / "scene.json"));
    EXPECT_EQ(j["generator"]["dem"], p.string());
}
