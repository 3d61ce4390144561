// ImageStreamWriter: a PNG streamed in bands is the same file as one written whole; abandoned files vanish.
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
