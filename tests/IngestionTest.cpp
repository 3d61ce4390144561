// Real data in (issue: seasons as delivered): mosaics of tiles with overlaps, gaps and nodata collars (a nodata value,
// an alpha band, an internal mask), JPEG-in-TIFF, VRTs, national CRSs and Web Mercator, DEM mosaics in another CRS,
// and the bad input of each; the default working grid of geographic and Web Mercator leaf-ons. Fixtures are made from
// a small synthetic scene with GDAL's own utilities, the way data providers make deliveries.
#include "GridReader.h"
#include "ToroidalWindow.h"
#include "ImagePyramid.h"
#include "SeasonCoverage.h"
#include "RasterMosaic.h"
#include "Scene.h"
#include "SyntheticScene.h"
#include "TestUtil.h"
#include "WorkingGrid.h"

#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <span>

using namespace seasonview;
using namespace seasonview::test;

namespace {

namespace fs = std::filesystem;

/// A 400×300 px synthetic scene at 0.5 m (its leafon.tif, leafoff.tif, dem.tif, truth), centred at `lonLat`.
fs::path smallScene(const TempDir& dir, glm::dvec2 lonLat = {7.62, 51.96}, double sizeM = 200.0) {
    SynthOptions o;
    o.sizeM = sizeM;
    o.gsd = 0.5;
    o.seed = 3;
    o.city = false;
    o.centreLonLat = lonLat;
    auto r = generateSyntheticScene(o, dir / "scene");
    EXPECT_TRUE(r.ok()) << r.message();
    return dir / "scene";
}

/// Every pixel of `mosaic` on `grid`: RGB samples and coverage.
struct GridPixels {
    std::vector<std::uint8_t> rgb, coverage;
    int width = 0, height = 0;
};
GridPixels readOnGrid(const RasterMosaic& mosaic, const WorkingGrid& grid, Resampling r = Resampling::Auto) {
    GridPixels p;
    auto reader = GridReader::open(mosaic, grid, r, 64);
    EXPECT_TRUE(reader.ok()) << reader.message();
    if (!reader) return p;
    p.width = grid.width;
    p.height = grid.height;
    p.rgb.resize(size_t(grid.width) * size_t(grid.height) * 3);
    p.coverage.resize(size_t(grid.width) * size_t(grid.height));
    for (int y = 0; y < grid.height; y += reader->bandRows()) {
        const int y1 = std::min(grid.height, y + reader->bandRows());
        auto st = reader->read(y, y1, 3, SampleType::U8, p.rgb.data() + size_t(y) * size_t(grid.width) * 3,
                               p.coverage.data() + size_t(y) * size_t(grid.width));
        EXPECT_TRUE(st.ok()) << st.message();
    }
    return p;
}

WorkingGrid gridOf(const fs::path& file) {
    auto info = readRasterInfo(file);
    EXPECT_TRUE(info.ok() && info->georef) << file;
    return WorkingGrid{*info->georef, info->width, info->height};
}

/// The scene's leaf-on re-delivered in Lambert-93 at 0.6 m with a nodata collar (dir/l93.tif).
fs::path lambert93Delivery(const fs::path& scene, const TempDir& dir) {
    gdalWarp(scene / "leafon.tif", dir / "l93.tif", {"-t_srs", "EPSG:2154", "-tr", "0.6", "0.6", "-r", "bilinear",
                                                     "-dstnodata", "0"});
    return dir / "l93.tif";
}

RasterMosaic mosaicOf(const SourceList& s) {
    auto m = openMosaic(s, "test");
    EXPECT_TRUE(m.ok()) << m.message();
    return m ? *m : RasterMosaic{};
}

/// "-srcwin" arguments of a window.
std::vector<std::string> window(int x, int y, int w, int h) {
    return {"-srcwin", std::to_string(x), std::to_string(y), std::to_string(w), std::to_string(h)};
}

std::vector<std::string> plus(std::vector<std::string> a, const std::vector<std::string>& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
}

/// A w×h RGB raster on `g` (its pixels do not matter: only its header is read).
void writeBlank(const fs::path& p, int w, int h, const Georef& g) {
    const std::vector<std::uint8_t> px(size_t(w) * size_t(h) * 3, 100);
    const Status st = writeGeoTiff(p, px.data(), SampleType::U8, w, h, 3, g);
    ASSERT_TRUE(st.ok()) << st.message();
}

/// The size of a pixel of `g` at pixel coordinates `at`, measured in `crs`: the square root of its area there.
double pixelSideIn(const Georef& g, glm::dvec2 at, const Crs& crs) {
    glm::dvec2 p[3] = {g.pixelToCrs(at), g.pixelToCrs(at + glm::dvec2(1.0, 0.0)),
                       g.pixelToCrs(at + glm::dvec2(0.0, 1.0))};
    convert(g.crs, crs, std::span<glm::dvec2>(p, 3));
    return std::sqrt(glm::length(p[1] - p[0]) * glm::length(p[2] - p[0]));
}

/// Whether `v` has at most 4 significant digits (what chooseWorkingGrid rounds a measured pixel to).
bool fourSignificantDigits(double v) {
    const double scale = std::pow(10.0, 3.0 - std::floor(std::log10(v)));
    return std::abs(v * scale - std::round(v * scale)) < 1e-6;
}

} // namespace

TEST(IngestionTest, MosaicTilesWithOverlapsGapsAndCollarsReadAsTheWhole) {
    TempDir dir("ingest-mosaic");
    const fs::path scene = smallScene(dir);
    const fs::path whole = scene / "leafon.tif";
    const WorkingGrid grid = gridOf(whole);
    auto original = readImageU8(whole, 3);
    ASSERT_TRUE(original.ok());
    ASSERT_EQ(grid.width, 400);
    ASSERT_EQ(grid.height, 400);
    // Four tiles: the west ones overlap the east ones by 20 columns, a 10-row gap runs between north and south, and
    // each of the three ways of marking nodata collars: the north-east tile's outer 12 columns zeroed with nodata 0,
    // the south-west tile with an alpha band that hides its last 15 rows, the south-east one an internal mask over
    // a 30×30 corner.
    fs::create_directories(dir / "tiles");
    gdalTranslate(whole, dir / "tiles/nw.tif", window(0, 0, 220, 195));
    {
        // The north-east tile with a zeroed collar and nodata 0.
        auto img = readImageU8(whole, 3);
        for (int y = 0; y < 195; ++y)
            for (int x = 388; x < 400; ++x)
                for (int c = 0; c < 3; ++c) img->at(x, y, c) = 0;
        GdalRasterSpec s;
        s.geotransform = geotransformOf(grid.georef);
        s.crs = "EPSG:32632";
        s.nodata = 0.0;
        writeGdalRaster(dir / "ne_full.tif", img->pixels.data(), SampleType::U8, 400, 400, 3, s);
        gdalTranslate(dir / "ne_full.tif", dir / "tiles/ne.tif", window(200, 0, 200, 195));
    }
    {
        // South-west: RGBA, alpha 0 on the tile's last 15 rows.
        std::vector<std::uint8_t> rgba(size_t(220) * 195 * 4);
        for (int y = 0; y < 195; ++y)
            for (int x = 0; x < 220; ++x) {
                for (int c = 0; c < 3; ++c) rgba[(size_t(y) * 220 + size_t(x)) * 4 + size_t(c)] = original->at(x, 205 + y, c);
                rgba[(size_t(y) * 220 + size_t(x)) * 4 + 3] = y < 180 ? 255 : 0;
            }
        GdalRasterSpec s;
        Georef g = grid.georef;
        g.origin.y -= 205 * g.pixelSize.y;
        s.geotransform = geotransformOf(g);
        s.crs = "EPSG:32632";
        s.lastBandIsAlpha = true;
        writeGdalRaster(dir / "tiles/sw.tif", rgba.data(), SampleType::U8, 220, 195, 4, s);
    }
    {
        // South-east: an internal (per-dataset) mask hiding a 30×30 corner.
        std::vector<std::uint8_t> rgb(size_t(200) * 195 * 3), mask(size_t(200) * 195, 255);
        for (int y = 0; y < 195; ++y)
            for (int x = 0; x < 200; ++x) {
                for (int c = 0; c < 3; ++c) rgb[(size_t(y) * 200 + size_t(x)) * 3 + size_t(c)] = original->at(200 + x, 205 + y, c);
                if (x >= 170 && y >= 165) mask[size_t(y) * 200 + size_t(x)] = 0;
            }
        GdalRasterSpec s;
        Georef g = grid.georef;
        g.origin += glm::dvec2(200 * g.pixelSize.x, -205 * g.pixelSize.y);
        s.geotransform = geotransformOf(g);
        s.crs = "EPSG:32632";
        s.mask = mask.data();
        s.creationOptions = {"TILED=YES"};
        writeGdalRaster(dir / "tiles/se.tif", rgb.data(), SampleType::U8, 200, 195, 3, s);
    }
    const RasterMosaic m = mosaicOf(SourceList(dir / "tiles"));
    ASSERT_EQ(m.tiles.size(), 4u);
    EXPECT_TRUE(m.hasNodata());
    const GridPixels p = readOnGrid(m, grid);
    int wrong = 0, gapCovered = 0, collarCovered = 0;
    for (int y = 0; y < 400; ++y)
        for (int x = 0; x < 400; ++x) {
            const size_t i = size_t(y) * 400 + size_t(x);
            const bool gap = y >= 195 && y < 205;
            const bool collar = (y < 195 && x >= 388) || (y >= 385 && x < 220 && x < 200) || (x >= 370 && y >= 370);
            if (gap) {
                gapCovered += p.coverage[i] != 0;
                continue;
            }
            if (collar) {
                collarCovered += p.coverage[i] != 0;
                continue;
            }
            if (p.coverage[i] != 255) {
                ++wrong;
                continue;
            }
            // Tiles on the grid's lattice are copied, not resampled: the original's bytes.
            for (int c = 0; c < 3; ++c) wrong += p.rgb[i * 3 + size_t(c)] != original->at(x, y, c);
        }
    EXPECT_EQ(wrong, 0);
    EXPECT_EQ(gapCovered, 0) << "the gap between tiles is no data";
    EXPECT_EQ(collarCovered, 0) << "nodata values, alpha and masks are no data";

    // The same tiles as a VRT: one raster, read the same.
    gdalBuildVrt(dir / "all.vrt", {dir / "tiles/nw.tif", dir / "tiles/ne.tif"});
    const GridPixels v = readOnGrid(mosaicOf(SourceList(dir / "all.vrt")), grid);
    int vrtWrong = 0;
    for (int y = 0; y < 195; ++y)
        for (int x = 0; x < 388; ++x) {
            const size_t i = size_t(y) * 400 + size_t(x);
            vrtWrong += v.coverage[i] != 255;
            for (int c = 0; c < 3; ++c) vrtWrong += v.rgb[i * 3 + size_t(c)] != original->at(x, y, c);
        }
    EXPECT_EQ(vrtWrong, 0);
    // A glob and a list name the same tiles.
    EXPECT_EQ(mosaicOf(SourceList((dir / "tiles/*.tif").string())).tiles.size(), 4u);
    EXPECT_EQ(mosaicOf(SourceList(std::vector<fs::path>{dir / "tiles/nw.tif", dir / "tiles/se.tif"})).tiles.size(), 2u);
}

TEST(IngestionTest, JpegInTiffTilesWithMasksAsOrthophotosCome) {
    TempDir dir("ingest-jpeg");
    const fs::path scene = smallScene(dir);
    const fs::path whole = scene / "leafoff.tif";
    const WorkingGrid grid = gridOf(whole);
    fs::create_directories(dir / "tiles");
    // 2×2 YCbCr JPEG tiles with internal masks over a collar (GDAL's way: COMPRESS=JPEG PHOTOMETRIC=YCBCR, the mask
    // as a second, deflated directory).
    std::vector<std::uint8_t> mask(size_t(200) * 200, 255);
    for (int y = 0; y < 200; ++y)
        for (int x = 0; x < 16; ++x) mask[size_t(y) * 200 + size_t(x)] = 0;
    for (int ty = 0; ty < 2; ++ty)
        for (int tx = 0; tx < 2; ++tx) {
            auto img = readImageU8(whole, 3);
            Image<std::uint8_t> t;
            t.width = t.height = 200;
            t.channels = 3;
            t.pixels.resize(200 * 200 * 3);
            for (int y = 0; y < 200; ++y)
                for (int x = 0; x < 200; ++x)
                    for (int c = 0; c < 3; ++c) t.at(x, y, c) = img->at(tx * 200 + x, ty * 200 + y, c);
            GdalRasterSpec s;
            Georef g = grid.georef;
            g.origin += glm::dvec2(tx * 200 * g.pixelSize.x, -ty * 200 * g.pixelSize.y);
            s.geotransform = geotransformOf(g);
            s.crs = "EPSG:32632";
            s.mask = tx == 0 ? mask.data() : nullptr; // the west tiles' first 16 columns are a collar
            s.creationOptions = {"TILED=YES", "COMPRESS=JPEG", "PHOTOMETRIC=YCBCR", "JPEG_QUALITY=90"};
            writeGdalRaster(dir / "tiles" / ("t" + std::to_string(tx) + std::to_string(ty) + ".tif"), t.pixels.data(),
                            SampleType::U8, 200, 200, 3, s);
        }
    const RasterMosaic m = mosaicOf(SourceList(dir / "tiles"));
    ASSERT_EQ(m.tiles.size(), 4u);
    EXPECT_EQ(m.tiles[0].nodataKind, NodataKind::Mask);
    const GridPixels p = readOnGrid(m, grid);
    auto original = readImageU8(whole, 3);
    double err = 0.0;
    int n = 0, collar = 0;
    for (int y = 0; y < 400; ++y)
        for (int x = 0; x < 400; ++x) {
            const size_t i = size_t(y) * 400 + size_t(x);
            if (x < 16) {
                collar += p.coverage[i] != 0;
                continue;
            }
            ASSERT_EQ(p.coverage[i], 255) << x << "," << y;
            for (int c = 0; c < 3; ++c) err += std::abs(int(p.rgb[i * 3 + size_t(c)]) - int(original->at(x, y, c)));
            n += 3;
        }
    EXPECT_EQ(collar, 0);
    EXPECT_LT(err / n, 4.0) << "JPEG quality 90 decoded to RGB (YCbCr) is close to the original";
}

TEST(IngestionTest, NationalGridsAndWebMercatorLandWhereTheOriginalWas) {
    // The leaf-on of a scene in France, the Netherlands, Switzerland and anywhere (Web Mercator) delivered in that
    // CRS, read back onto the original UTM grid: the picture lands on the original, not a pixel off.
    struct Case {
        const char* crs;
        glm::dvec2 lonLat;
    } cases[] = {{"EPSG:2154", {2.18, 48.70}}, {"EPSG:28992", {5.39, 52.16}}, {"EPSG:2056", {7.44, 46.95}},
                 {"EPSG:3857", {7.62, 51.96}}, {"EPSG:27700", {-1.26, 51.75}}};
    for (const Case& c : cases) {
        SCOPED_TRACE(c.crs);
        TempDir dir("ingest-crs");
        const fs::path scene = smallScene(dir, c.lonLat);
        const fs::path whole = scene / "leafon.tif";
        const WorkingGrid grid = gridOf(whole);
        gdalWarp(whole, dir / "delivered.tif", {"-t_srs", c.crs, "-r", "bilinear", "-dstalpha"});
        const RasterMosaic m = mosaicOf(SourceList(dir / "delivered.tif"));
        ASSERT_EQ(m.crs, *Crs::fromUserInput(c.crs));
        const GridPixels p = readOnGrid(m, grid, Resampling::Bilinear);
        auto original = readImageU8(whole, 3);
        // Mean difference to the original shifted by (dx, dy) pixels, over the inner part: least at (0, 0).
        auto diff = [&](int dx, int dy) {
            double e = 0.0;
            int n = 0;
            for (int y = 40; y < 360; ++y)
                for (int x = 40; x < 360; ++x) {
                    const size_t i = size_t(y) * 400 + size_t(x);
                    if (p.coverage[i] != 255) continue;
                    for (int ch = 0; ch < 3; ++ch)
                        e += std::abs(int(p.rgb[i * 3 + size_t(ch)]) - int(original->at(x + dx, y + dy, ch)));
                    n += 3;
                }
            return n ? e / n : 1e9;
        };
        const double at0 = diff(0, 0);
        EXPECT_LT(at0, 12.0) << "resampled twice (bilinear), the picture stays close";
        for (auto [dx, dy] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}})
            EXPECT_LT(at0, diff(dx, dy)) << "shifted by " << dx << "," << dy;
    }
}

TEST(IngestionTest, BadMosaicsAreOneLineNamingTheTile) {
    TempDir dir("ingest-bad");
    const fs::path scene = smallScene(dir);
    fs::create_directories(dir / "bands");
    gdalTranslate(scene / "leafon.tif", dir / "bands/a.tif", window(0, 0, 200, 200));
    gdalTranslate(scene / "leafon.tif", dir / "bands/b.tif", plus(window(200, 0, 200, 200), {"-b", "1", "-b", "2"}));
    auto bands = openMosaic(SourceList(dir / "bands"), "leaf-on");
    ASSERT_FALSE(bands.ok());
    EXPECT_EQ(bands.message().rfind((dir / "bands/b.tif").string() + ": 2 bands but ", 0), 0u) << bands.message();

    fs::create_directories(dir / "crs");
    gdalTranslate(scene / "leafon.tif", dir / "crs/a.tif", window(0, 0, 200, 200));
    gdalWarp(scene / "leafon.tif", dir / "crs/b.tif", {"-t_srs", "EPSG:3857"});
    auto crs = openMosaic(SourceList(dir / "crs"), "leaf-on");
    ASSERT_FALSE(crs.ok());
    EXPECT_EQ(crs.message().rfind((dir / "crs/b.tif").string() + ": CRS EPSG:3857", 0), 0u) << crs.message();
    EXPECT_NE(crs.message().find("must share a CRS"), std::string::npos) << crs.message();

    fs::create_directories(dir / "empty");
    std::ofstream(dir / "empty/readme.txt") << "no rasters here";
    std::ofstream(dir / "empty/a.prj") << "PROJCS[]";
    auto empty = openMosaic(SourceList(dir / "empty"), "leaf-on");
    ASSERT_FALSE(empty.ok());
    EXPECT_EQ(empty.message(), (dir / "empty").string() + ": no rasters in this folder");

    auto glob = openMosaic(SourceList((dir / "nothing/*.tif").string()), "leaf-on");
    ASSERT_FALSE(glob.ok());
    EXPECT_EQ(glob.message(), (dir / "nothing/*.tif").string() + ": matches no file");

    for (const auto* r : {&bands, &crs, &empty, &glob}) EXPECT_EQ(r->message().find('\n'), std::string::npos);
}

TEST(IngestionTest, DemTilesInAnotherCrsAndInFeet) {
    // The scene's DEM delivered as SRTM comes: geographic 1° tiles (here two halves of the scene, overlapping by a
    // sample), Int16. And a DEM in feet.
    TempDir dir("ingest-dem");
    const fs::path scene = smallScene(dir);
    auto src = parseManifest(scene / "scene.json");
    ASSERT_TRUE(src.ok());
    auto reference = loadScene(*src, dir / "cache");
    ASSERT_TRUE(reference.ok()) << reference.message();
    gdalWarp(scene / "dem.tif", dir / "dem4326.tif", {"-t_srs", "EPSG:4326", "-r", "bilinear"});
    auto info = readRasterInfo(dir / "dem4326.tif");
    ASSERT_TRUE(info.ok());
    fs::create_directories(dir / "srtm");
    const int half = info->width / 2;
    gdalTranslate(dir / "dem4326.tif", dir / "srtm/w.tif", window(0, 0, half + 1, info->height));
    gdalTranslate(dir / "dem4326.tif", dir / "srtm/e.tif", window(half, 0, info->width - half, info->height));
    src->elevation = dir / "srtm";
    auto tiled = loadScene(*src, dir / "cache");
    ASSERT_TRUE(tiled.ok()) << tiled.message();
    ASSERT_TRUE(tiled->elevation);
    EXPECT_EQ(tiled->elevation->georef.crs, Crs::geographic());
    double worst = 0.0;
    for (double x = -80; x <= 80; x += 20)
        for (double y = -80; y <= 80; y += 20)
            worst = std::max(worst, std::abs(tiled->terrainHeight(x, y) - reference->terrainHeight(x, y)));
    EXPECT_LT(worst, 0.6) << "heights through two warps and a tile seam";

    // Feet: the same heights / 0.3048, the band's unit saying so.
    auto dem = readImageF32(scene / "dem.tif", 1);
    ASSERT_TRUE(dem.ok());
    for (float& v : dem->pixels) v = float(v / 0.3048);
    GdalRasterSpec s;
    s.geotransform = geotransformOf(*readRasterInfo(scene / "dem.tif")->georef);
    s.crs = "EPSG:32632";
    writeGdalRaster(dir / "feet.tif", dem->pixels.data(), SampleType::F32, dem->width, dem->height, 1, s);
    {
        GDALAllRegister();
        GDALDataset* d = GDALDataset::FromHandle(GDALOpen((dir / "feet.tif").c_str(), GA_Update));
        ASSERT_TRUE(d);
        d->GetRasterBand(1)->SetUnitType("ft");
        GDALClose(GDALDataset::ToHandle(d));
    }
    src->elevation = dir / "feet.tif";
    auto feet = loadScene(*src, dir / "cache");
    ASSERT_TRUE(feet.ok()) << feet.message();
    EXPECT_NEAR(feet->terrainHeight(10, 20), reference->terrainHeight(10, 20), 2e-3);
}

TEST(IngestionTest, CoverageUnderACursorSaysWhichSeasonHasData) {
    // The leaf-off 10 m east of the leaf-on: on the union grid the west strip has the leaf-on only, the east strip the
    // leaf-off only, the middle both (what the viewer's HUD reports under the cursor).
    TempDir dir("ingest-coverage");
    writeTestImage(dir / "on.tif", 64, 48, testGeoref(0.5), false, 1);
    writeTestImage(dir / "off.tif", 64, 48, testGeoref(0.5, 405010.0), false, 2);
    SceneSources s;
    s.leafon = dir / "on.tif";
    s.leafoff = dir / "off.tif";
    auto scene = loadScene(s, dir / "cache");
    ASSERT_TRUE(scene.ok()) << scene.message();
    ASSERT_EQ(scene->grid.width, 84);
    std::vector<ImagePyramid> pyramids;
    for (const ImageryLayer* l : {&scene->leafon, &scene->leafoff}) {
        PrepareOptions o;
        o.cacheDir = dir / "cache";
        auto r = preparePyramid(*l, o);
        ASSERT_TRUE(r.ok()) << r.message();
        pyramids.push_back(r->pyramid);
    }
    auto probe = SeasonCoverageProbe::open(pyramids);
    ASSERT_TRUE(probe.ok()) << probe.message();
    EXPECT_STREQ(probe->at({5.5, 10.0})->describe(), "leaf-on only");
    EXPECT_STREQ(probe->at({40.0, 10.0})->describe(), "both seasons");
    EXPECT_STREQ(probe->at({80.2, 47.9})->describe(), "leaf-off only");
    EXPECT_FALSE(probe->at({84.5, 10.0}));
    EXPECT_FALSE(probe->at({-0.5, 10.0}));
}

TEST(IngestionTest, OwnBilinearKernelMatchesGdalsWarper) {
    // A Lambert-93 delivery with a nodata collar warped back onto the UTM grid by GridReader (own kernel) and by
    // gdalwarp -r bilinear onto the same grid: the same pixels, to rounding and GDAL's 1/8-pixel approximation.
    TempDir dir("ingest-kernel");
    const fs::path scene = smallScene(dir, {2.18, 48.70});
    const WorkingGrid grid = gridOf(scene / "leafon.tif");
    const fs::path l93 = lambert93Delivery(scene, dir);
    const GridPixels own = readOnGrid(mosaicOf(SourceList(l93)), grid, Resampling::Bilinear);
    const glm::dvec2 lo = grid.min(), hi = grid.max();
    gdalWarp(l93, dir / "back.tif",
             {"-t_srs", "EPSG:32631", "-tr", "0.5", "0.5", "-te", std::to_string(lo.x), std::to_string(lo.y),
              std::to_string(hi.x), std::to_string(hi.y), "-r", "bilinear", "-dstalpha"});
    auto gdal = readImageU8(dir / "back.tif", 4);
    ASSERT_TRUE(gdal.ok());
    ASSERT_EQ(gdal->width, grid.width);
    double sum = 0.0;
    int worst = 0, n = 0, coverageDiffers = 0;
    for (int y = 0; y < grid.height; ++y)
        for (int x = 0; x < grid.width; ++x) {
            const size_t i = size_t(y) * size_t(grid.width) + size_t(x);
            const bool theirs = gdal->at(x, y, 3) >= 128, ours = own.coverage[i] == 255;
            coverageDiffers += theirs != ours;
            if (!theirs || !ours) continue;
            for (int c = 0; c < 3; ++c) {
                const int d = std::abs(int(own.rgb[i * 3 + size_t(c)]) - int(gdal->at(x, y, c)));
                sum += d;
                worst = std::max(worst, d);
                ++n;
            }
        }
    ASSERT_GT(n, 3 * 400 * 300);
    std::printf("own vs gdalwarp bilinear: mean %.3f, max %d, coverage differs at %d pixels\n", sum / n, worst,
                coverageDiffers);
    EXPECT_LT(sum / n, 0.05);
    EXPECT_LE(worst, 2) << "rounding, and GDAL's 1/8-pixel approximation against our 1/20";
    EXPECT_LT(coverageDiffers, 40) << "a few pixels of the collar's edge";
}

TEST(IngestionTest, WindowsReadAsTheRowsDo) {
    // GridReader::readWindow (a streamed clip level's regions, in any order) gives the pixels and coverage read() gives
    // in bands of rows: warped by our kernel, by GDAL's warper (average), and a file that is the grid as it is.
    TempDir dir("ingest-windows");
    const fs::path scene = smallScene(dir, {2.18, 48.70});
    const WorkingGrid grid = gridOf(scene / "leafon.tif");
    const fs::path l93 = lambert93Delivery(scene, dir);
    const int w = grid.width, h = grid.height;
    const TexelRect windows[] = {{100, 50, 356, 306}, {0, 0, 64, 64}, {w - 70, h - 33, w, h}, {5, 7, 6, 300}};
    const std::pair<fs::path, Resampling> cases[] = {{l93, Resampling::Bilinear},
                                                     {l93, Resampling::Average},
                                                     {scene / "leafon.tif", Resampling::Auto}};
    for (const auto& [file, resampling] : cases) {
        SCOPED_TRACE(file.filename().string() + " " + resamplingName(resampling));
        const RasterMosaic mosaic = mosaicOf(SourceList(file));
        const GridPixels rows = readOnGrid(mosaic, grid, resampling);
        auto reader = GridReader::open(mosaic, grid, resampling, 64);
        ASSERT_TRUE(reader.ok()) << reader.message();
        for (const TexelRect& t : windows) {
            std::vector<std::uint8_t> rgb(size_t(t.area()) * 3), coverage(size_t(t.area()));
            ASSERT_TRUE(reader->readWindow(t.x0, t.y0, t.x1, t.y1, 3, SampleType::U8, rgb.data(), coverage.data()).ok());
            int differ = 0;
            for (int y = t.y0; y < t.y1; ++y)
                for (int x = t.x0; x < t.x1; ++x) {
                    const size_t i = size_t(y - t.y0) * size_t(t.width()) + size_t(x - t.x0);
                    const size_t j = size_t(y) * size_t(w) + size_t(x);
                    differ += coverage[i] != rows.coverage[j] || rgb[i * 3] != rows.rgb[j * 3] ||
                              rgb[i * 3 + 1] != rows.rgb[j * 3 + 1] || rgb[i * 3 + 2] != rows.rgb[j * 3 + 2];
                }
            // GDAL's warper chunks and approximates per call: a window's edge may round differently.
            EXPECT_LE(differ, resampling == Resampling::Average ? int(t.area() / 100) : 0)
                << t.x0 << "," << t.y0 << " " << t.width() << "x" << t.height();
        }
    }
}

TEST(IngestionTest, DefaultGridOfAGeographicOrWebMercatorLeafOn) {
    // WorkingGrid.h and the README: the grid is in the leaf-on's CRS when that is projected, else (geographic) in the
    // UTM zone of the leaf-on's centre; its pixel is the finest season's, exactly when that season is in the grid's
    // CRS (and the grid on its lattice), else measured in the grid's CRS at its centre, to 4 significant digits.
    TempDir dir("ingest-default-grid");
    const GridOptions none{};
    auto grid = [&](const char* on, const char* off) {
        auto g = chooseWorkingGrid(mosaicOf(SourceList(dir / on)), mosaicOf(SourceList(dir / off)), none, on, off);
        EXPECT_TRUE(g.ok()) << g.message();
        return g ? *g : WorkingGrid{};
    };
    // Geographic seasons (EPSG:4326, 5e-6° pixels: 0.37-0.56 m), north and south, east and west of Greenwich. The
    // leaf-off is 20 pixels east of the leaf-on, so that in the last case the leaf-on's centre (5.99996° E) is in
    // zone 31 but the centre of both (6.00001° E) is in zone 32: the leaf-on decides.
    struct Case {
        glm::dvec2 corner; // the leaf-on's north-west corner, longitude and latitude
        int epsg;
    } cases[] = {{{2.18, 48.70}, 32631},
                 {{-3.70, 40.42}, 32630},
                 {{151.20, -33.87}, 32756},
                 {{-70.65, -33.45}, 32719},
                 {{5.9998, 47.0}, 32631}};
    const double deg = 5e-6;
    for (const Case& c : cases) {
        SCOPED_TRACE(c.epsg);
        const Georef on{Crs::geographic(), c.corner, glm::dvec2(deg)};
        Georef off = on;
        off.origin += glm::dvec2(20 * deg, -10 * deg);
        writeBlank(dir / "geo_on.tif", 64, 64, on);
        writeBlank(dir / "geo_off.tif", 64, 64, off);
        const WorkingGrid g = grid("geo_on.tif", "geo_off.tif");
        EXPECT_EQ(g.georef.crs.epsg(), c.epsg) << g.georef.crs.name();
        EXPECT_EQ(g.georef.pixelSize.x, g.georef.pixelSize.y);
        const double side = pixelSideIn(on, {32.0, 32.0}, g.georef.crs);
        EXPECT_NEAR(g.georef.pixelSize.x, side, 1e-3 * side); // 4 digits, and the leaf-off's pixel may be the finer
        EXPECT_TRUE(fourSignificantDigits(g.georef.pixelSize.x)) << g.georef.pixelSize.x;
        for (const char* f : {"geo_on.tif", "geo_off.tif"}) { // the union of both
            const auto [lo, hi] = extentIn(mosaicOf(SourceList(dir / f)), g.georef.crs);
            EXPECT_LE(g.min().x, lo.x + 1e-6) << f;
            EXPECT_LE(g.min().y, lo.y + 1e-6) << f;
            EXPECT_GE(g.max().x, hi.x - 1e-6) << f;
            EXPECT_GE(g.max().y, hi.y - 1e-6) << f;
        }
    }

    // A Web Mercator leaf-on is projected: the grid stays in EPSG:3857, not UTM. Both seasons' north-west corner at
    // 2.18° E, 48.70° N, where a Web Mercator metre is cos(48.70°) = 0.66 m on the ground.
    const Crs merc = *Crs::fromEpsg(3857), utm = Crs::utm(31, true);
    const glm::dvec2 m0 = glm::round(convert(Crs::geographic(), merc, {2.18, 48.70}));
    const glm::dvec2 u0 = glm::round(convert(Crs::geographic(), utm, {2.18, 48.70}));
    // The UTM leaf-off (0.5 m) is finer than the leaf-on (1.5 Web Mercator m = 0.99 m): the grid's pixel is the
    // leaf-off's measured in Web Mercator (0.5 / 0.66 = 0.76), on multiples of itself.
    writeBlank(dir / "merc_on.tif", 64, 64, Georef{merc, m0, glm::dvec2(1.5)});
    writeBlank(dir / "utm_off.tif", 128, 128, Georef{utm, u0, glm::dvec2(0.5)});
    const WorkingGrid a = grid("merc_on.tif", "utm_off.tif");
    EXPECT_EQ(a.georef.crs.epsg(), 3857) << a.georef.crs.name();
    const double side = pixelSideIn(Georef{utm, u0, glm::dvec2(0.5)}, {64.0, 64.0}, merc);
    EXPECT_NEAR(side, 0.76, 0.01);
    EXPECT_NEAR(a.georef.pixelSize.x, side, 1e-3 * side);
    EXPECT_TRUE(fourSignificantDigits(a.georef.pixelSize.x)) << a.georef.pixelSize.x;
    const glm::dvec2 steps = a.georef.origin / a.georef.pixelSize;
    EXPECT_NEAR(steps.x, std::round(steps.x), 1e-6);
    EXPECT_NEAR(steps.y, std::round(steps.y), 1e-6);
    // The Web Mercator leaf-on is the finer (0.75 Web Mercator m = 0.50 m against a 1 m UTM leaf-off): its own pixel,
    // exactly, and the grid on its lattice (it is read as it is, not resampled).
    writeBlank(dir / "merc_on_fine.tif", 128, 128, Georef{merc, m0, glm::dvec2(0.75)});
    writeBlank(dir / "utm_off_coarse.tif", 64, 64, Georef{utm, u0, glm::dvec2(1.0)});
    const WorkingGrid b = grid("merc_on_fine.tif", "utm_off_coarse.tif");
    EXPECT_EQ(b.georef.crs.epsg(), 3857);
    EXPECT_EQ(b.georef.pixelSize, glm::dvec2(0.75));
    const glm::dvec2 shift = (b.georef.origin - m0) / 0.75;
    EXPECT_NEAR(shift.x, std::round(shift.x), 1e-6);
    EXPECT_NEAR(shift.y, std::round(shift.y), 1e-6);
}
