// ImageStreamWriter: a PNG streamed in bands is the same file as one written whole; abandoned files vanish; the fast
// mask encoding keeps the pixels.
#include "ImageStreamWriter.h"
#include "Raster.h"
#include "TestUtil.h"

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>

using namespace seasonview;
using namespace seasonview::test;

namespace {


} // namespace

TEST(ImageStreamWriterTest, PngInBandsEqualsWholePng) {
    TempDir dir("isw-png");
    const int w = 120, h = 90;
    std::vector<std::uint8_t> grey(size_t(w) * size_t(h));
    for (size_t i = 0; i < grey.size(); ++i) grey[i] = (i / 7 + i / size_t(w)) % 3 == 0 ? 255 : 0;
    ASSERT_TRUE(writeImageAtomic(dir / "whole.png", grey.data(), w, h, 1).ok());
    {
        auto writer = ImageStreamWriter::open(dir / "bands.png", w, h, 1);
        ASSERT_TRUE(writer.ok()) << writer.message();
        for (int y = 0; y < h; y += 25)
            ASSERT_TRUE(writer->writeRows(y, std::min(25, h - y), grey.data() + size_t(y) * size_t(w)).ok());
        ASSERT_TRUE(writer->finish().ok());
    }
    EXPECT_TRUE(readBytes(dir / "whole.png") == readBytes(dir / "bands.png"));
    auto back = readImageU8(dir / "bands.png", 1);
    ASSERT_TRUE(back.ok());
    EXPECT_TRUE(back->pixels == grey);
    {
        auto writer = ImageStreamWriter::open(dir / "abandoned.png", w, h, 1);
        ASSERT_TRUE(writer.ok());
        ASSERT_TRUE(writer->writeRows(0, 10, grey.data()).ok());
    }
    EXPECT_FALSE(std::filesystem::exists(dir / "abandoned.png"));
    int files = 0;
    for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir.path())) ++files;
    EXPECT_EQ(files, 2) << "temporary files left behind";
}

TEST(ImageStreamWriterTest, FastMaskKeepsThePixels) {
    TempDir dir("isw-fast");
    const int w = 301, h = 97;
    std::vector<std::uint8_t> mask(size_t(w) * size_t(h)), rgb(size_t(w) * size_t(h) * 3);
    for (size_t i = 0; i < mask.size(); ++i) mask[i] = (i / 11 + i / size_t(w)) % 5 < 2 ? 255 : 0;
    for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = std::uint8_t(i * 7 / 3);
    for (const char* name : {"m.png", "m.tif"})
        for (int band : {1, 30, h}) {
            SCOPED_TRACE(std::string(name) + ", bands of " + std::to_string(band));
            auto writer = ImageStreamWriter::open(dir / name, w, h, 1, ImageEncoding::FastMask);
            ASSERT_TRUE(writer.ok()) << writer.message();
            for (int y = 0; y < h; y += band)
                ASSERT_TRUE(writer->writeRows(y, std::min(band, h - y), mask.data() + size_t(y) * size_t(w)).ok());
            ASSERT_TRUE(writer->finish().ok());
            auto back = readImageU8(dir / name, 1);
            ASSERT_TRUE(back.ok()) << back.message();
            EXPECT_EQ(back->width, w);
            EXPECT_EQ(back->channels, 1);
            EXPECT_TRUE(back->pixels == mask);
        }
    {
        // RGB works too.
        auto writer = ImageStreamWriter::open(dir / "rgb.png", w, h, 3, ImageEncoding::FastMask);
        ASSERT_TRUE(writer.ok());
        ASSERT_TRUE(writer->writeRows(0, h, rgb.data()).ok());
        ASSERT_TRUE(writer->finish().ok());
        auto back = readImageU8(dir / "rgb.png", 3);
        ASSERT_TRUE(back.ok());
        EXPECT_TRUE(back->pixels == rgb);
    }
    {
        auto writer = ImageStreamWriter::open(dir / "abandoned.png", w, h, 1, ImageEncoding::FastMask);
        ASSERT_TRUE(writer.ok());
        ASSERT_TRUE(writer->writeRows(0, 10, mask.data()).ok());
    }
    EXPECT_FALSE(std::filesystem::exists(dir / "abandoned.png"));
    for (const auto& e : std::filesystem::directory_iterator(dir.path()))
        EXPECT_EQ(e.path().filename().string().find(".partial"), std::string::npos) << e.path();
    // A folder that does not exist: one line naming the file, nothing created.
    auto bad = ImageStreamWriter::open(dir / "missing" / "m.png", w, h, 1, ImageEncoding::FastMask);
    ASSERT_FALSE(bad.ok());
    EXPECT_EQ(bad.message().rfind((dir / "missing" / "m.png").string() + ": ", 0), 0u) << bad.message();
}
