// GeoTiffStreamWriter: round trips through core's readers (pixels, georeferencing, tiling, sample types), bytes
// independent of how rows arrive and of the thread count, the BigTIFF switch, atomic output.
#include "GeoTiffStreamWriter.h"
#include "Raster.h"
#include "TestUtil.h"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <limits>

using namespace seasonview;
using namespace seasonview::test;

namespace {


// Noisy RGB so that compression does not hide mistakes in the predictor.
std::vector<std::uint8_t> testRgb(int w, int h) {
    std::vector<std::uint8_t> px(size_t(w) * size_t(h) * 3);
    std::uint32_t s = 12345;
    for (size_t i = 0; i < px.size(); ++i) {
        s = s * 1664525u + 1013904223u;
        px[i] = std::uint8_t((i / 3 % size_t(w)) + (s >> 29));
    }
    return px;
}

// Writes `data` in batches of rows of the given sizes (cycled) and finishes.
template <typename T>
void writeInBatches(const std::filesystem::path& path, const std::vector<T>& data, int w, int h, int channels,
                    SampleType type, const std::optional<Georef>& g, const GeoTiffWriteOptions& o,
                    std::vector<int> batches) {
    auto writer = GeoTiffStreamWriter::open(path, w, h, channels, type, g, o);
    ASSERT_TRUE(writer.ok()) << writer.message();
    const size_t rowSamples = size_t(w) * size_t(channels);
    for (int y = 0, k = 0; y < h; k = (k + 1) % int(batches.size())) {
        const int rows = std::min(batches[size_t(k)], h - y);
        ASSERT_TRUE(writer->writeRows(y, rows, data.data() + size_t(y) * rowSamples).ok());
        y += rows;
        EXPECT_EQ(writer->rowsWritten(), y);
    }
    auto st = writer->finish();
    ASSERT_TRUE(st.ok()) << st.message();
}

bool onlyFile(const std::filesystem::path& dir, const std::string& name) {
    int n = 0;
    for (const auto& e : std::filesystem::directory_iterator(dir)) {
        if (e.path().filename() != name) return false;
        ++n;
    }
    return n == 1;
}

} // namespace

TEST(GeoTiffStreamWriterTest, RoundTripTiledRgbWithGeoref) {
    TempDir dir("gtsw-rgb");
    const int w = 300, h = 200; // partial tiles on the right and at the bottom
    const auto px = testRgb(w, h);
    GeoTiffWriteOptions o;
    o.tileSize = 64;
    writeInBatches(dir / "a.tif", px, w, h, 3, SampleType::U8, testGeoref(0.25, 405000, 5758000), o, {1, 37, 64, 100});
    auto info = readRasterInfo(dir / "a.tif");
    ASSERT_TRUE(info.ok()) << info.message();
    EXPECT_EQ(info->width, w);
    EXPECT_EQ(info->height, h);
    EXPECT_EQ(info->channels, 3);
    EXPECT_EQ(info->type, SampleType::U8);
    EXPECT_TRUE(info->tiled);
    ASSERT_TRUE(info->georef);
    EXPECT_EQ(info->georef->crs.epsg(), 32632);
    EXPECT_DOUBLE_EQ(info->georef->origin.x, 405000.0);
    EXPECT_DOUBLE_EQ(info->georef->origin.y, 5758000.0);
    EXPECT_DOUBLE_EQ(info->georef->pixelSize.x, 0.25);
    EXPECT_DOUBLE_EQ(info->georef->pixelSize.y, 0.25);
    auto back = readImageU8(dir / "a.tif", 3);
    ASSERT_TRUE(back.ok()) << back.message();
    EXPECT_TRUE(back->pixels == px);
    EXPECT_TRUE(onlyFile(dir.path(), "a.tif")) << "temporary files left behind";
}

TEST(GeoTiffStreamWriterTest, BytesDoNotDependOnRowBatchesOrThreads) {
    for (TiffCompression compression : {TiffCompression::Deflate, TiffCompression::Zstd, TiffCompression::Jpeg}) {
        SCOPED_TRACE(tiffCompressionName(compression));
        TempDir dir("gtsw-bytes");
        const int w = 200, h = 150;
        const auto px = testRgb(w, h);
        GeoTiffWriteOptions one;
        one.tileSize = 32;
        one.threads = 1;
        one.compression = compression;
        GeoTiffWriteOptions three = one;
        three.threads = 3;
        writeInBatches(dir / "whole.tif", px, w, h, 3, SampleType::U8, testGeoref(), one, {h});
        writeInBatches(dir / "rows.tif", px, w, h, 3, SampleType::U8, testGeoref(), three, {1, 7, 32, 45});
        ASSERT_TRUE(writeGeoTiff(dir / "writeGeoTiff.tif", px.data(), SampleType::U8, w, h, 3, testGeoref(), one).ok());
        const std::string whole = readBytes(dir / "whole.tif");
        EXPECT_FALSE(whole.empty());
        EXPECT_TRUE(whole == readBytes(dir / "rows.tif"));
        EXPECT_TRUE(whole == readBytes(dir / "writeGeoTiff.tif"));
        // Tagged with the codec that compressed it, so that any libtiff reader decodes it.
        auto in = OIIO::ImageInput::open((dir / "whole.tif").string());
        ASSERT_TRUE(in);
        EXPECT_EQ(in->spec().get_int_attribute("tiff:Compression"),
                  compression == TiffCompression::Zstd   ? 50000 /* COMPRESSION_ZSTD */
                  : compression == TiffCompression::Jpeg ? 7 /* JPEG */
                                                         : 8 /* ADOBE_DEFLATE */);
    }
    // JPEG: stored as YCbCr; it takes 8-bit RGB only: anything else is one clear error, and no file.
    TempDir dir("gtsw-jpeg");
    GeoTiffWriteOptions o;
    o.compression = TiffCompression::Jpeg;
    const auto rgb = testRgb(64, 64);
    ASSERT_TRUE(writeGeoTiff(dir / "rgb.tif", rgb.data(), SampleType::U8, 64, 64, 3, testGeoref(), o).ok());
    {
        auto in = OIIO::ImageInput::open((dir / "rgb.tif").string());
        ASSERT_TRUE(in);
        EXPECT_EQ(in->spec().get_int_attribute("tiff:PhotometricInterpretation"), 6); // YCbCr
    }
    const std::vector<std::uint16_t> wide(64 * 64 * 3, 1000);
    const std::vector<std::uint8_t> rgba(64 * 64 * 4, 100);
    const Status wideSt = writeGeoTiff(dir / "wide.tif", wide.data(), SampleType::U16, 64, 64, 3, testGeoref(), o);
    const Status rgbaSt = writeGeoTiff(dir / "rgba.tif", rgba.data(), SampleType::U8, 64, 64, 4, testGeoref(), o);
    for (const auto& [name, st] : {std::pair{"wide.tif", wideSt}, std::pair{"rgba.tif", rgbaSt}}) {
        ASSERT_FALSE(st.ok()) << name;
        EXPECT_NE(st.message().find("JPEG"), std::string::npos) << st.message();
        EXPECT_FALSE(std::filesystem::exists(dir / name));
    }
}

TEST(GeoTiffStreamWriterTest, SampleTypesAndStripsRoundTrip) {
    TempDir dir("gtsw-types");
    const int w = 37, h = 41; // odd sizes: partial tiles, a short last strip
    std::vector<std::uint16_t> u16(size_t(w) * size_t(h) * 3);
    std::vector<std::int16_t> i16(size_t(w) * size_t(h));
    std::vector<float> f32(size_t(w) * size_t(h));
    for (size_t i = 0; i < u16.size(); ++i) u16[i] = std::uint16_t(i * 2654435761u >> 16);
    for (size_t i = 0; i < i16.size(); ++i) i16[i] = std::int16_t(int(i % 7919) - 4000);
    for (size_t i = 0; i < f32.size(); ++i) f32[i] = 250.0f + 40.0f * std::sin(float(i) * 0.37f) + float(i) * 1e-3f;
    f32[3] = std::numeric_limits<float>::quiet_NaN();
    f32[4] = -9999.0f;
    for (int round = 0; round < 4; ++round) { // tiled and strips with deflate, then with Zstandard
        const int tile = round % 2 ? 0 : 16;
        const TiffCompression compression = round < 2 ? TiffCompression::Deflate : TiffCompression::Zstd;
        GeoTiffWriteOptions o;
        o.tileSize = tile;
        o.nodata = -9999.0;
        o.compression = compression;
        const std::string suffix =
            std::string("-") + tiffCompressionName(compression) + (tile ? "-tiled.tif" : "-strips.tif");
        writeInBatches(dir / ("u16" + suffix), u16, w, h, 3, SampleType::U16, testGeoref(), o, {5, 16});
        writeInBatches(dir / ("i16" + suffix), i16, w, h, 1, SampleType::I16, testGeoref(), o, {3});
        writeInBatches(dir / ("f32" + suffix), f32, w, h, 1, SampleType::F32, testGeoref(), o, {h});

        auto iu = readRasterInfo(dir / ("u16" + suffix));
        ASSERT_TRUE(iu.ok()) << iu.message();
        EXPECT_EQ(iu->tiled, tile > 0);
        EXPECT_EQ(iu->type, SampleType::U16);
        EXPECT_EQ(iu->channels, 3);
        auto bu = readImageU16(dir / ("u16" + suffix), 3);
        ASSERT_TRUE(bu.ok()) << bu.message();
        EXPECT_TRUE(bu->pixels == u16) << suffix;

        auto bi = readImageF32(dir / ("i16" + suffix));
        ASSERT_TRUE(bi.ok()) << bi.message();
        for (size_t i = 0; i < i16.size(); ++i) ASSERT_EQ(bi->pixels[i], float(i16[i])) << suffix << " sample " << i;

        auto info = readRasterInfo(dir / ("f32" + suffix));
        ASSERT_TRUE(info.ok()) << info.message();
        EXPECT_EQ(info->type, SampleType::F32);
        ASSERT_TRUE(info->nodata);
        EXPECT_DOUBLE_EQ(*info->nodata, -9999.0);
        auto bf = readImageF32(dir / ("f32" + suffix));
        ASSERT_TRUE(bf.ok()) << bf.message();
        for (size_t i = 0; i < f32.size(); ++i) {
            if (std::isnan(f32[i])) EXPECT_TRUE(std::isnan(bf->pixels[i]));
            else ASSERT_EQ(bf->pixels[i], f32[i]) << suffix << " sample " << i; // bit-exact: lossless predictor
        }
    }
}

TEST(GeoTiffStreamWriterTest, BigTiffAboveTheThreshold) {
    TempDir dir("gtsw-big");
    const int w = 64, h = 48;
    const auto px = testRgb(w, h);
    GeoTiffWriteOptions small;
    small.tileSize = 16;
    GeoTiffWriteOptions big = small;
    big.bigTiffAbove = std::uint64_t(w) * h * 3 - 1; // one byte less than the raw pixels
    for (const auto& [name, o, isBig] : {std::tuple{"classic.tif", small, false}, std::tuple{"big.tif", big, true}}) {
        auto writer = GeoTiffStreamWriter::open(dir / name, w, h, 3, SampleType::U8, testGeoref(0.5), o);
        ASSERT_TRUE(writer.ok()) << writer.message();
        EXPECT_EQ(writer->bigTiff(), isBig);
        ASSERT_TRUE(writer->writeRows(0, h, px.data()).ok());
        ASSERT_TRUE(writer->finish().ok());
        const std::string bytes = readBytes(dir / name);
        ASSERT_GE(bytes.size(), 4u);
        EXPECT_EQ(int(static_cast<unsigned char>(bytes[2])), isBig ? 43 : 42) << name << ": TIFF version in the header";
        auto back = readImageU8(dir / name, 3);
        ASSERT_TRUE(back.ok()) << back.message();
        EXPECT_TRUE(back->pixels == px) << name;
        auto info = readRasterInfo(dir / name);
        ASSERT_TRUE(info.ok() && info->georef) << name;
        EXPECT_DOUBLE_EQ(info->georef->pixelSize.x, 0.5);
    }
}

TEST(GeoTiffStreamWriterTest, NoGeorefGivesAPlainTiff) {
    TempDir dir("gtsw-plain");
    const auto px = testRgb(20, 20);
    writeInBatches(dir / "plain.tif", px, 20, 20, 3, SampleType::U8, std::nullopt, GeoTiffWriteOptions{}, {20});
    auto info = readRasterInfo(dir / "plain.tif");
    ASSERT_TRUE(info.ok()) << info.message();
    EXPECT_FALSE(info->georef);
    auto back = readImageU8(dir / "plain.tif", 3);
    ASSERT_TRUE(back.ok());
    EXPECT_TRUE(back->pixels == px);
}

TEST(GeoTiffStreamWriterTest, UnfinishedWriterLeavesNoFile) {
    TempDir dir("gtsw-abandon");
    const auto px = testRgb(64, 64);
    {
        auto writer = GeoTiffStreamWriter::open(dir / "a.tif", 64, 64, 3, SampleType::U8, testGeoref());
        ASSERT_TRUE(writer.ok());
        ASSERT_TRUE(writer->writeRows(0, 40, px.data()).ok());
        GeoTiffStreamWriter moved = std::move(*writer); // the moved-from writer must not discard anything
    }
    EXPECT_TRUE(std::filesystem::is_empty(dir.path())) << "an abandoned writer left a file";
    auto missing = GeoTiffStreamWriter::open(dir / "no-such-folder" / "a.tif", 8, 8, 1, SampleType::U8, testGeoref());
    ASSERT_FALSE(missing.ok());
    EXPECT_NE(missing.message().find("a.tif"), std::string::npos) << missing.message();
    EXPECT_EQ(missing.message().find('\n'), std::string::npos) << missing.message();
}
