#include "Raster.h"
#include "Stretch.h"
#include "TestUtil.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>

using namespace seasonview;
using namespace seasonview::test;

TEST(RasterTest, GeoTiffRoundTripUtm8Bit) {
    TempDir dir("raster-utm8");
    const Georef g = testGeoref(0.25, 405000, 5758000);
    writeTestImage(dir / "a.tif", 300, 200, g);
    auto info = readRasterInfo(dir / "a.tif");
    ASSERT_TRUE(info.ok()) << info.message();
    EXPECT_EQ(info->width, 300);
    EXPECT_EQ(info->height, 200);
    EXPECT_EQ(info->channels, 3);
    EXPECT_EQ(info->type, SampleType::U8);
    EXPECT_TRUE(info->tiled);
    ASSERT_TRUE(info->georef);
    EXPECT_EQ(info->georef->crs.epsg(), 32632);
    EXPECT_EQ(info->georef->crs, Crs::utm(32, true));
    EXPECT_DOUBLE_EQ(info->georef->origin.x, 405000);
    EXPECT_DOUBLE_EQ(info->georef->origin.y, 5758000);
    EXPECT_DOUBLE_EQ(info->georef->pixelSize.x, 0.25);
    // Pixel -> CRS: rows go south.
    const glm::dvec2 p = info->georef->pixelToCrs({4, 8});
    EXPECT_DOUBLE_EQ(p.x, 405001);
    EXPECT_DOUBLE_EQ(p.y, 5757998);
    auto px = readImageU8(dir / "a.tif");
    ASSERT_TRUE(px.ok()) << px.message();
    EXPECT_EQ(px->pixels.size(), 300u * 200u * 3u);
}

TEST(RasterTest, SixteenBitAndGeographic) {
    TempDir dir("raster-geo16");
    Georef g;
    g.crs = Crs::geographic();
    g.origin = {2.1, 48.8};
    g.pixelSize = {0.0001, 0.0001};
    writeTestImage(dir / "b.tif", 64, 48, g, true);
    auto info = readRasterInfo(dir / "b.tif");
    ASSERT_TRUE(info.ok()) << info.message();
    EXPECT_EQ(info->type, SampleType::U16);
    ASSERT_TRUE(info->georef);
    EXPECT_TRUE(info->georef->crs.isGeographic());
    EXPECT_NEAR(info->georef->origin.x, 2.1, 1e-12);
    auto px = readImageU16(dir / "b.tif");
    ASSERT_TRUE(px.ok());
    EXPECT_GE(*std::min_element(px->pixels.begin(), px->pixels.end()), 300);
    EXPECT_LE(*std::max_element(px->pixels.begin(), px->pixels.end()), 2500);
}

TEST(RasterTest, FloatDemWithNodataTag) {
    TempDir dir("raster-dem");
    std::vector<float> h(32 * 16, 123.5f);
    h[5] = std::numeric_limits<float>::quiet_NaN();
    h[6] = -9999.0f;
    GeoTiffWriteOptions o;
    o.nodata = -9999.0;
    ASSERT_TRUE(writeGeoTiff(dir / "dem.tif", h.data(), SampleType::F32, 32, 16, 1, testGeoref(2.0), o).ok());
    auto info = readRasterInfo(dir / "dem.tif");
    ASSERT_TRUE(info.ok()) << info.message();
    EXPECT_EQ(info->type, SampleType::F32);
    ASSERT_TRUE(info->nodata);
    EXPECT_DOUBLE_EQ(*info->nodata, -9999.0);
    auto px = readImageF32(dir / "dem.tif");
    ASSERT_TRUE(px.ok());
    EXPECT_FLOAT_EQ(px->pixels[0], 123.5f);
    EXPECT_TRUE(std::isnan(px->pixels[5]));
}

TEST(RasterTest, Int16KeepsRawValues) {
    TempDir dir("raster-i16");
    std::vector<std::int16_t> h = {-32768, 0, 263, 4371};
    GeoTiffWriteOptions strips;
    strips.tileSize = 0;
    ASSERT_TRUE(writeGeoTiff(dir / "i16.tif", h.data(), SampleType::I16, 2, 2, 1, testGeoref(90.0), strips).ok());
    auto px = readImageF32(dir / "i16.tif");
    ASSERT_TRUE(px.ok()) << px.message();
    EXPECT_FLOAT_EQ(px->pixels[0], -32768.0f);
    EXPECT_FLOAT_EQ(px->pixels[2], 263.0f);
    EXPECT_FLOAT_EQ(px->pixels[3], 4371.0f);
}

TEST(RasterTest, BadFilesGiveOneLineNamingTheFile) {
    TempDir dir("raster-bad");
    auto missing = readRasterInfo(dir / "nope.tif");
    ASSERT_FALSE(missing.ok());
    EXPECT_NE(missing.message().find("nope.tif: file not found"), std::string::npos) << missing.message();

    std::ofstream(dir / "text.tif") << "this is not a TIFF\n";
    auto text = readRasterInfo(dir / "text.tif");
    ASSERT_FALSE(text.ok());
    EXPECT_NE(text.message().find("text.tif: not a readable image"), std::string::npos) << text.message();

    writeTestImage(dir / "full.tif", 512, 512, testGeoref(), false, 3);
    const auto size = std::filesystem::file_size(dir / "full.tif");
    std::filesystem::copy_file(dir / "full.tif", dir / "cut.tif");
    std::filesystem::resize_file(dir / "cut.tif", size / 2);
    auto cut = readImageU8(dir / "cut.tif");
    ASSERT_FALSE(cut.ok());
    EXPECT_NE(cut.message().find("cut.tif"), std::string::npos) << cut.message();
    for (const auto* r : {&missing.message(), &text.message(), &cut.message()})
        EXPECT_EQ(r->find('\n'), std::string::npos) << *r;
}

TEST(RasterTest, AnyCrsAndNoCrs) {
    TempDir dir("raster-crs");
    std::vector<std::uint8_t> px(16 * 16 * 3, 90);
    GdalRasterSpec spec;
    spec.geotransform = std::array<double, 6>{238044.0, 12.0, 0.0, 6230904.0, 0.0, -12.0};
    spec.crs = "EPSG:3857";
    writeGdalRaster(dir / "merc.tif", px.data(), SampleType::U8, 16, 16, 3, spec);
    auto info = readRasterInfo(dir / "merc.tif");
    ASSERT_TRUE(info.ok()) << info.message();
    ASSERT_TRUE(info->georef);
    EXPECT_EQ(info->georef->crs.epsg(), 3857);
    EXPECT_DOUBLE_EQ(info->georef->origin.x, 238044.0);
    // A geotransform without a CRS: no georef unless one is assumed (--crs).
    spec.crs.clear();
    writeGdalRaster(dir / "nocrs.tif", px.data(), SampleType::U8, 16, 16, 3, spec);
    auto bare = readRasterInfo(dir / "nocrs.tif");
    ASSERT_TRUE(bare.ok()) << bare.message();
    EXPECT_FALSE(bare->georef);
    EXPECT_TRUE(bare->geotransformWithoutCrs);
    auto assumed = readRasterInfo(dir / "nocrs.tif", *Crs::fromEpsg(2154));
    ASSERT_TRUE(assumed.ok());
    ASSERT_TRUE(assumed->georef);
    EXPECT_EQ(assumed->georef->crs.epsg(), 2154);
    // Our own writer stamps any CRS too (here one without an EPSG code).
    auto custom = Crs::fromUserInput("+proj=tmerc +lat_0=0 +lon_0=2.25 +k=1 +x_0=500000 +y_0=0 +ellps=GRS80 +units=m");
    ASSERT_TRUE(custom.ok()) << custom.message();
    ASSERT_EQ(custom->epsg(), 0);
    const Georef g{*custom, {512000.0, 5396000.0}, {0.5, 0.5}};
    ASSERT_TRUE(writeGeoTiff(dir / "tm.tif", px.data(), SampleType::U8, 16, 16, 3, g).ok());
    auto tm = readRasterInfo(dir / "tm.tif");
    ASSERT_TRUE(tm.ok()) << tm.message();
    ASSERT_TRUE(tm->georef);
    EXPECT_EQ(tm->georef->crs, *custom);
    EXPECT_DOUBLE_EQ(tm->georef->origin.y, 5396000.0);
    EXPECT_DOUBLE_EQ(tm->georef->pixelSize.x, 0.5);
}

TEST(RasterTest, WriteIsAtomic) {
    TempDir dir("raster-atomic");
    std::vector<std::uint8_t> px(8 * 8 * 3, 7);
    ASSERT_TRUE(writeImageAtomic(dir / "a.png", px.data(), 8, 8, 3).ok());
    auto bad = writeImageAtomic(dir / "missing-folder" / "a.png", px.data(), 8, 8, 3);
    EXPECT_FALSE(bad.ok());
    size_t files = 0;
    for (auto& e : std::filesystem::directory_iterator(dir.path())) {
        (void)e;
        ++files;
    }
    EXPECT_EQ(files, 1u) << "no temporary files left behind";
}

TEST(RasterTest, RealDataHeaders) {
    auto data = realDataDir();
    if (!data) GTEST_SKIP() << "real data not found (set SEASONVIEW_DATA or provide ../shared/data)";
    auto dem = readRasterInfo(*data / "dem/mt_rainier_90m.tif");
    ASSERT_TRUE(dem.ok()) << dem.message();
    EXPECT_EQ(dem->width, 1201);
    EXPECT_EQ(dem->type, SampleType::I16);
    ASSERT_TRUE(dem->georef);
    EXPECT_TRUE(dem->georef->crs.isGeographic());
    EXPECT_NEAR(dem->georef->pixelSize.x, 1.0 / 1200.0, 1e-9);
    auto on = readRasterInfo(*data / "seasons/saclay_w/leafon_2017-08-29.tif");
    ASSERT_TRUE(on.ok()) << on.message();
    EXPECT_EQ(on->type, SampleType::U16);
    EXPECT_EQ(on->width, 688);
    EXPECT_EQ(on->height, 639);
    ASSERT_TRUE(on->georef);
    EXPECT_TRUE(on->georef->crs.isGeographic());
}

TEST(StretchTest, PercentilesPerBand) {
    Image<std::uint16_t> img;
    img.width = 1000;
    img.height = 1;
    img.channels = 2;
    for (int i = 0; i < 1000; ++i) {
        img.pixels.push_back(std::uint16_t(1000 + i));     // band 0: 1000..1999
        img.pixels.push_back(std::uint16_t(i < 5 ? 60000 : 500)); // band 1: outliers above
    }
    const Stretch s = computeStretch(img);
    EXPECT_FALSE(s.identity);
    EXPECT_NEAR(s.low[0], 1004, 1);
    EXPECT_NEAR(s.high[0], 1994, 1);
    EXPECT_EQ(s.apply(0, 500.0f), 0);
    EXPECT_EQ(s.apply(0, 5000.0f), 255);
    EXPECT_NEAR(s.apply(0, 1500.0f), 127, 2);
    EXPECT_LT(s.high[1], 60000) << "0.5 % outliers do not set the white point";
}

TEST(StretchTest, StoredInCacheNotRecomputed) {
    TempDir dir("stretch-cache");
    writeTestImage(dir / "s16.tif", 64, 150, testGeoref(), true); // 150 rows: more than one 64-row band
    auto info = readRasterInfo(dir / "s16.tif");
    ASSERT_TRUE(info.ok());
    auto a = stretchFor(*info, dir / "cache");
    ASSERT_TRUE(a.ok()) << a.message();
    // The streamed histogram (bands of rows) gives exactly the in-memory result.
    const Stretch whole = computeStretch(*readImageU16(dir / "s16.tif"));
    for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(a->low[size_t(c)], whole.low[size_t(c)]);
        EXPECT_EQ(a->high[size_t(c)], whole.high[size_t(c)]);
    }
    size_t cached = 0;
    std::filesystem::path file;
    for (auto& e : std::filesystem::directory_iterator(dir / "cache")) {
        ++cached;
        file = e.path();
    }
    ASSERT_EQ(cached, 1u);
    // The stored value is read, not recomputed: the image made unreadable in place (same size and time, so the same
    // cache key), the stretch still comes back, the same.
    const auto when = std::filesystem::last_write_time(dir / "s16.tif");
    std::string image = readBytes(dir / "s16.tif");
    const std::string intact = image;
    for (size_t i = 16; i < image.size(); ++i) image[i] = char(0x5a);
    std::ofstream(dir / "s16.tif", std::ios::binary | std::ios::trunc) << image;
    std::filesystem::last_write_time(dir / "s16.tif", when);
    auto b = stretchFor(*info, dir / "cache");
    ASSERT_TRUE(b.ok()) << b.message();
    EXPECT_EQ(a->low[0], b->low[0]);
    std::ofstream(dir / "s16.tif", std::ios::binary | std::ios::trunc) << intact;
    std::filesystem::last_write_time(dir / "s16.tif", when);
    // A flipped digit that still reads as a number in range fails the file's digest: computed again, the same.
    std::ifstream in(file);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    in.close();
    const auto pos = text.find("\"low\"");
    ASSERT_NE(pos, std::string::npos);
    const auto num = text.find_first_of("0123456789", pos);
    text.insert(num, "1");
    std::ofstream(file) << text;
    auto c = stretchFor(*info, dir / "cache");
    ASSERT_TRUE(c.ok()) << c.message();
    EXPECT_EQ(a->low[0], c->low[0]);
    EXPECT_EQ(a->high[0], c->high[0]);
    // 8-bit imagery is never stretched.
    writeTestImage(dir / "s8.tif", 8, 8, testGeoref());
    auto i8 = readRasterInfo(dir / "s8.tif");
    EXPECT_TRUE(stretchFor(*i8, dir / "cache")->identity);
}

TEST(StretchTest, SixteenBitRgbaKeepsAlpha) {
    TempDir dir("rgba16");
    std::vector<std::uint16_t> px;
    for (int i = 0; i < 16 * 8; ++i) px.insert(px.end(), {std::uint16_t(300 + i * 10), 900, 1500, std::uint16_t(i % 2 ? 65535 : 0)});
    ASSERT_TRUE(writeGeoTiff(dir / "rgba.tif", px.data(), SampleType::U16, 16, 8, 4, testGeoref()).ok());
    auto info = readRasterInfo(dir / "rgba.tif");
    ASSERT_TRUE(info.ok()) << info.message();
    EXPECT_EQ(info->channels, 4);
    auto stretch = stretchFor(*info, dir / "cache");
    ASSERT_TRUE(stretch.ok()) << stretch.message();
    auto rgba = readDisplayRgba(*info, *stretch);
    ASSERT_TRUE(rgba.ok()) << rgba.message();
    EXPECT_EQ(rgba->at(0, 0, 3), 0);
    EXPECT_EQ(rgba->at(1, 0, 3), 255);
    EXPECT_LT(rgba->at(0, 0, 0), rgba->at(15, 7, 0)) << "red rises with the index: the stretch keeps the order";
}
