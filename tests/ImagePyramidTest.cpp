// The pyramid cache of `seasonview prepare`: level sizes, pixel values, tiling, idempotence, and rebuilding when
// the source changed or the cache is corrupt.
#include "ImagePyramid.h"
#include "PyramidBuilder.h"
#include "Stretch.h"
#include "TestUtil.h"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <functional>

using namespace seasonview;
using namespace seasonview::test;

namespace {

namespace fs = std::filesystem;

ImageryLayer layerOf(const fs::path& file, const fs::path& cache) {
    auto layer = openImageryLayer(file, "leaf-on", cache);
    EXPECT_TRUE(layer.ok()) << layer.message();
    return layer ? *layer : ImageryLayer{};
}

PrepareReport prepareOk(const ImageryLayer& layer, const fs::path& cache, bool force = false) {
    PrepareOptions o;
    o.cacheDir = cache;
    o.force = force;
    auto r = preparePyramid(layer, o);
    EXPECT_TRUE(r.ok()) << r.message();
    return r ? *r : PrepareReport{};
}

/// Nothing but finished pyramids in the cache: no partial folders.
void expectNoPartials(const fs::path& cache) {
    std::error_code ec;
    for (fs::directory_iterator it(cache / "pyramids", ec), end; !ec && it != end; it.increment(ec))
        EXPECT_EQ(it->path().filename().string().find(".partial"), std::string::npos) << it->path();
}

void expectLevelsMatchFiles(const ImagePyramid& p) {
    for (const PyramidLevel& l : p.levels) {
        auto info = readRasterInfo(l.file);
        ASSERT_TRUE(info.ok()) << info.message();
        EXPECT_EQ(info->width, l.width) << l.file;
        EXPECT_EQ(info->height, l.height) << l.file;
        EXPECT_EQ(info->channels, 4); // premultiplied RGBA
        EXPECT_EQ(info->type, SampleType::U8);
        EXPECT_TRUE(info->tiled);
    }
}

/// Level 1 must be the 2×2 box average of level 0, the last column/row of an odd size averaging what exists.
void expectBoxAverage(const Image<std::uint8_t>& fine, const Image<std::uint8_t>& coarse) {
    ASSERT_EQ(coarse.width, (fine.width + 1) / 2);
    ASSERT_EQ(coarse.height, (fine.height + 1) / 2);
    int worst = 0;
    for (int y = 0; y < coarse.height; ++y)
        for (int x = 0; x < coarse.width; ++x)
            for (int c = 0; c < 3; ++c) {
                int sum = 0, n = 0;
                for (int dy = 0; dy < 2; ++dy)
                    for (int dx = 0; dx < 2; ++dx)
                        if (2 * x + dx < fine.width && 2 * y + dy < fine.height) {
                            sum += fine.at(2 * x + dx, 2 * y + dy, c);
                            ++n;
                        }
                worst = std::max(worst, std::abs(int(coarse.at(x, y, c)) - sum / n));
            }
    EXPECT_LE(worst, 1); // rounding of the mean
}

} // namespace

TEST(ImagePyramidTest, LevelSizesHalveWithCeilDownToOne) {
    const std::vector<std::pair<int, int>> expected = {{300, 200}, {150, 100}, {75, 50}, {38, 25}, {19, 13},
                                                       {10, 7},    {5, 4},     {3, 2},   {2, 1},   {1, 1}};
    EXPECT_EQ(pyramidLevelSizes(300, 200), expected);
    EXPECT_EQ(pyramidLevelSizes(1, 1).size(), 1u);
    EXPECT_EQ(pyramidLevelSizes(1, 5), (std::vector<std::pair<int, int>>{{1, 5}, {1, 3}, {1, 2}, {1, 1}}));
    EXPECT_EQ(pyramidLevelSizes(65536, 65536).size(), 17u);
}

TEST(ImagePyramidTest, EightBitLevelZeroEqualsSourceAndLevelsAreBoxFiltered) {
    TempDir dir("pyramid-8bit");
    writeTestImage(dir / "a.tif", 300, 200, testGeoref(), false, 1);
    const ImageryLayer layer = layerOf(dir / "a.tif", dir / "cache");
    const PrepareReport r = prepareOk(layer, dir / "cache");
    EXPECT_TRUE(r.built);
    EXPECT_EQ(r.reason, "not prepared yet");
    ASSERT_EQ(r.pyramid.levels.size(), 10u);
    EXPECT_EQ(r.pyramid.width(), 300);
    EXPECT_EQ(r.pyramid.height(), 200);
    EXPECT_EQ(r.pyramid.levels[3].width, 38);
    EXPECT_EQ(r.pyramid.levels[3].height, 25);
    expectLevelsMatchFiles(r.pyramid);
    expectNoPartials(dir / "cache");

    auto src = readImageU8(dir / "a.tif", 3);
    auto l0 = readImageU8(r.pyramid.levels[0].file, 3);
    ASSERT_TRUE(src.ok() && l0.ok());
    EXPECT_EQ(l0->pixels, src->pixels);
    auto alpha = readImageU8(r.pyramid.levels[0].file, 4);
    ASSERT_TRUE(alpha.ok());
    for (size_t i = 3; i < alpha->pixels.size(); i += 4) ASSERT_EQ(alpha->pixels[i], 255) << "a season with data everywhere";
    for (size_t k = 0; k + 1 < r.pyramid.levels.size(); ++k) {
        auto fine = readImageU8(r.pyramid.levels[k].file, 3);
        auto coarse = readImageU8(r.pyramid.levels[k + 1].file, 3);
        ASSERT_TRUE(fine.ok() && coarse.ok());
        SCOPED_TRACE("level " + std::to_string(k + 1));
        expectBoxAverage(*fine, *coarse);
    }
}

TEST(ImagePyramidTest, SixteenBitLevelZeroIsTheStretchApplied) {
    TempDir dir("pyramid-16bit");
    writeTestImage(dir / "b.tif", 301, 203, testGeoref(), true, 2);
    const ImageryLayer layer = layerOf(dir / "b.tif", dir / "cache");
    ASSERT_FALSE(layer.stretch.identity);
    const PrepareReport r = prepareOk(layer, dir / "cache");
    auto src = readImageU16(dir / "b.tif", 3);
    auto l0 = readImageU8(r.pyramid.levels.at(0).file, 3);
    ASSERT_TRUE(src.ok() && l0.ok());
    ASSERT_EQ(l0->pixels.size(), src->pixels.size());
    int mismatches = 0;
    for (size_t i = 0; i < src->pixels.size(); ++i)
        mismatches += l0->pixels[i] != layer.stretch.apply(int(i % 3), float(src->pixels[i]));
    EXPECT_EQ(mismatches, 0);
    auto l1 = readImageU8(r.pyramid.levels.at(1).file, 3);
    ASSERT_TRUE(l1.ok());
    expectBoxAverage(*l0, *l1);
}

TEST(ImagePyramidTest, TilesAre256SquaredZstd) {
    TempDir dir("pyramid-tiles");
    writeTestImage(dir / "a.tif", 700, 300, testGeoref(), false, 3);
    const PrepareReport r = prepareOk(layerOf(dir / "a.tif", dir / "cache"), dir / "cache");
    EXPECT_EQ(r.pyramid.tileSize, 256);
    for (const PyramidLevel& l : r.pyramid.levels) {
        auto in = OIIO::ImageInput::open(l.file.string());
        ASSERT_TRUE(in) << l.file;
        EXPECT_EQ(in->spec().tile_width, 256);
        EXPECT_EQ(in->spec().tile_height, 256);
        // Zstandard (OpenImageIO 2.4 has no name for it): the loader decodes it five times faster than deflate.
        EXPECT_EQ(in->spec().get_int_attribute("tiff:Compression"), 50000);
    }
}

TEST(ImagePyramidTest, SmallerThanATileAndOnePixelWide) {
    TempDir dir("pyramid-small");
    for (auto [w, h] : {std::pair{100, 60}, std::pair{1, 700}, std::pair{513, 1}, std::pair{1, 1}}) {
        SCOPED_TRACE(std::to_string(w) + "x" + std::to_string(h));
        const std::string name = "s" + std::to_string(w) + "x" + std::to_string(h) + ".tif";
        writeTestImage(dir / name, w, h, testGeoref(), false, 4);
        const PrepareReport r = prepareOk(layerOf(dir / name, dir / "cache"), dir / "cache");
        ASSERT_EQ(r.pyramid.levels.size(), pyramidLevelSizes(w, h).size());
        EXPECT_EQ(r.pyramid.levels.back().width, 1);
        EXPECT_EQ(r.pyramid.levels.back().height, 1);
        expectLevelsMatchFiles(r.pyramid);
        auto src = readImageU8(dir / name, 3);
        auto l0 = readImageU8(r.pyramid.levels[0].file, 3);
        ASSERT_TRUE(src.ok() && l0.ok());
        EXPECT_EQ(l0->pixels, src->pixels);
        if (r.pyramid.levels.size() > 1) {
            auto l1 = readImageU8(r.pyramid.levels[1].file, 3);
            ASSERT_TRUE(l1.ok());
            expectBoxAverage(*l0, *l1);
        }
    }
}

TEST(ImagePyramidTest, StripAndOddTiledSources) {
    // The source is read in bands: by rows for strip TIFFs, by whole tile rows (here 48, not dividing 256) for
    // tiled ones.
    TempDir dir("pyramid-layouts");
    const int w = 333, h = 517;
    std::vector<std::uint8_t> rgb(size_t(w) * h * 3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            for (int c = 0; c < 3; ++c) rgb[(size_t(y) * w + size_t(x)) * 3 + size_t(c)] = std::uint8_t((x * (c + 1) + y * 3) % 256);
        }
    GeoTiffWriteOptions strips, oddTiles;
    strips.tileSize = 0;
    oddTiles.tileSize = 48;
    // Copies: writeGeoTiff's strip path lets libtiff's predictor scribble on the buffer it is given.
    auto rgbCopy = rgb;
    ASSERT_TRUE(writeGeoTiff(dir / "strips.tif", rgbCopy.data(), SampleType::U8, w, h, 3, testGeoref(), strips).ok());
    rgbCopy = rgb;
    ASSERT_TRUE(writeGeoTiff(dir / "tiles48.tif", rgbCopy.data(), SampleType::U8, w, h, 3, testGeoref(), oddTiles).ok());
    for (const char* name : {"strips.tif", "tiles48.tif"}) {
        SCOPED_TRACE(name);
        const PrepareReport r = prepareOk(layerOf(dir / name, dir / "cache"), dir / "cache");
        auto l0 = readImageU8(r.pyramid.levels.at(0).file, 3);
        ASSERT_TRUE(l0.ok());
        EXPECT_EQ(l0->pixels, rgb);
        auto l1 = readImageU8(r.pyramid.levels.at(1).file, 3);
        ASSERT_TRUE(l1.ok());
        expectBoxAverage(*l0, *l1);
    }
}

TEST(ImagePyramidTest, SecondCallIsUpToDateAndTouchesNothing) {
    TempDir dir("pyramid-idem");
    writeTestImage(dir / "a.tif", 300, 200, testGeoref(), false, 1);
    const ImageryLayer layer = layerOf(dir / "a.tif", dir / "cache");
    const PrepareReport first = prepareOk(layer, dir / "cache");
    ASSERT_TRUE(first.built);
    std::vector<fs::file_time_type> times;
    for (const auto& l : first.pyramid.levels) times.push_back(fs::last_write_time(l.file));
    const auto manifestTime = fs::last_write_time(first.pyramid.folder / "pyramid.json");

    const PrepareReport second = prepareOk(layer, dir / "cache");
    EXPECT_FALSE(second.built);
    EXPECT_EQ(second.pyramid.folder, first.pyramid.folder);
    EXPECT_EQ(second.pyramid.sourceKey, first.pyramid.sourceKey);
    ASSERT_EQ(second.pyramid.levels.size(), first.pyramid.levels.size());
    for (size_t k = 0; k < times.size(); ++k) {
        EXPECT_EQ(second.pyramid.levels[k].file, first.pyramid.levels[k].file);
        EXPECT_EQ(fs::last_write_time(first.pyramid.levels[k].file), times[k]);
    }
    EXPECT_EQ(fs::last_write_time(first.pyramid.folder / "pyramid.json"), manifestTime);

    auto opened = openPyramid(layer, dir / "cache");
    ASSERT_TRUE(opened.ok()) << opened.message();
    EXPECT_EQ(opened->folder, first.pyramid.folder);

    const PrepareReport forced = prepareOk(layer, dir / "cache", true);
    EXPECT_TRUE(forced.built);
    EXPECT_EQ(forced.reason, "forced");
    expectNoPartials(dir / "cache");
}

TEST(ImagePyramidTest, ChangedSourceIsDetectedAndRebuilt) {
    TempDir dir("pyramid-changed");
    writeTestImage(dir / "a.tif", 300, 200, testGeoref(), false, 1);
    const PrepareReport first = prepareOk(layerOf(dir / "a.tif", dir / "cache"), dir / "cache");

    writeTestImage(dir / "a.tif", 300, 200, testGeoref(), false, 9); // same name, other pixels
    // File times are coarse (a clock tick): make sure the rewrite is visible even when it was that fast.
    fs::last_write_time(dir / "a.tif", fs::last_write_time(dir / "a.tif") + std::chrono::seconds(2));
    const ImageryLayer changed = layerOf(dir / "a.tif", dir / "cache");
    auto stale = openPyramid(changed, dir / "cache");
    ASSERT_FALSE(stale.ok());
    EXPECT_NE(stale.message().find("source changed"), std::string::npos) << stale.message();

    const PrepareReport second = prepareOk(changed, dir / "cache");
    EXPECT_TRUE(second.built);
    EXPECT_EQ(second.reason, "source changed");
    EXPECT_NE(second.pyramid.folder, first.pyramid.folder);
    EXPECT_FALSE(fs::exists(first.pyramid.folder)); // the stale pyramid of the old file is removed
    auto src = readImageU8(dir / "a.tif", 3);
    auto l0 = readImageU8(second.pyramid.levels.at(0).file, 3);
    ASSERT_TRUE(src.ok() && l0.ok());
    EXPECT_EQ(l0->pixels, src->pixels);
}

TEST(ImagePyramidTest, CorruptCacheIsDetectedAndRebuilt) {
    TempDir dir("pyramid-corrupt");
    writeTestImage(dir / "a.tif", 600, 300, testGeoref(), false, 5);
    const ImageryLayer layer = layerOf(dir / "a.tif", dir / "cache");
    const PrepareReport good = prepareOk(layer, dir / "cache");
    const fs::path folder = good.pyramid.folder;
    auto l0 = readImageU8(good.pyramid.levels.at(0).file, 3);
    ASSERT_TRUE(l0.ok());

    struct Damage {
        const char* name;
        std::function<void()> apply;
        const char* reason;
    };
    const fs::path level0 = folder / "level_00.tif", level2 = folder / "level_02.tif";
    const std::vector<Damage> damages = {
        {"truncated level", [&] { fs::resize_file(level0, fs::file_size(level0) / 2); }, "level_00.tif has"},
        {"deleted level", [&] { fs::remove(level2); }, "level_02.tif missing"},
        {"garbage level of the right size",
         [&] {
             const auto size = fs::file_size(level2);
             std::ofstream(level2, std::ios::binary | std::ios::trunc) << std::string(size, 'x');
         },
         "level_02.tif unreadable"},
        {"garbage manifest", [&] { std::ofstream(folder / "pyramid.json") << "{not json"; }, "pyramid.json unreadable"},
        {"deleted manifest", [&] { fs::remove(folder / "pyramid.json"); }, "pyramid.json missing"},
    };
    for (const Damage& d : damages) {
        SCOPED_TRACE(d.name);
        d.apply();
        auto opened = openPyramid(layer, dir / "cache");
        ASSERT_FALSE(opened.ok());
        EXPECT_NE(opened.message().find(d.reason), std::string::npos) << opened.message();
        const PrepareReport r = prepareOk(layer, dir / "cache");
        EXPECT_TRUE(r.built);
        EXPECT_EQ(r.reason.rfind("cache corrupt: ", 0), 0u) << r.reason;
        EXPECT_NE(r.reason.find(d.reason), std::string::npos) << r.reason;
        EXPECT_EQ(r.pyramid.folder, folder);
        auto again = readImageU8(r.pyramid.levels.at(0).file, 3);
        ASSERT_TRUE(again.ok());
        EXPECT_EQ(again->pixels, l0->pixels);
        EXPECT_TRUE(openPyramid(layer, dir / "cache").ok());
    }
    expectNoPartials(dir / "cache");
}

TEST(ImagePyramidTest, NotPreparedYet) {
    TempDir dir("pyramid-none");
    writeTestImage(dir / "a.tif", 40, 30, testGeoref(), false, 1);
    auto opened = openPyramid(layerOf(dir / "a.tif", dir / "cache"), dir / "cache");
    ASSERT_FALSE(opened.ok());
    EXPECT_NE(opened.message().find("not prepared yet"), std::string::npos) << opened.message();
}

TEST(ImagePyramidTest, MissingOrCorruptSourceNamesTheSource) {
    TempDir dir("pyramid-badsource");
    writeTestImage(dir / "a.tif", 600, 400, testGeoref(), false, 1);
    const ImageryLayer layer = layerOf(dir / "a.tif", dir / "cache");
    PrepareOptions o;
    o.cacheDir = dir / "cache";

    fs::resize_file(dir / "a.tif", fs::file_size(dir / "a.tif") / 2); // header intact, tiles cut off
    auto truncated = preparePyramid(layer, o);
    ASSERT_FALSE(truncated.ok());
    EXPECT_EQ(truncated.message().rfind((dir / "a.tif").string() + ": ", 0), 0u) << truncated.message();
    EXPECT_EQ(truncated.message().find('\n'), std::string::npos);
    expectNoPartials(dir / "cache");
    EXPECT_FALSE(openPyramid(layer, dir / "cache").ok());

    fs::remove(dir / "a.tif");
    auto missing = preparePyramid(layer, o);
    ASSERT_FALSE(missing.ok());
    EXPECT_EQ(missing.message(), (dir / "a.tif").string() + ": file not found");
}

TEST(ImagePyramidTest, UnwritableCacheNamesTheCacheFolder) {
    TempDir dir("pyramid-unwritable");
    writeTestImage(dir / "a.tif", 40, 30, testGeoref(), false, 1);
    std::ofstream(dir / "plainfile") << "not a folder";
    PrepareOptions o;
    o.cacheDir = dir / "plainfile" / "cache"; // cannot be created, even as root
    auto r = preparePyramid(layerOf(dir / "a.tif", dir / "cache"), o);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.message().rfind((o.cacheDir / "pyramids").string() + ": ", 0), 0u) << r.message();
}

TEST(ImagePyramidTest, BoxFilterRow) {
    const std::uint8_t a[] = {0, 10, 20, 4, 10, 20, 255, 1, 2};
    const std::uint8_t b[] = {2, 10, 20, 2, 11, 20, 100, 3, 2};
    std::uint8_t out[6] = {};
    downsampleRow(a, b, 3, out, 3);
    EXPECT_EQ(out[0], 2);   // (0+4+2+2)/4
    EXPECT_EQ(out[1], 10);  // (10+10+10+11)/4 = 10.25
    EXPECT_EQ(out[3], 178); // odd width: (255+100+1)/2
    EXPECT_EQ(out[4], 2);
    downsampleRow(a, nullptr, 3, out, 3);
    EXPECT_EQ(out[0], 2);   // (0+4+1)/2
    EXPECT_EQ(out[3], 255); // a lone corner sample is copied
}
