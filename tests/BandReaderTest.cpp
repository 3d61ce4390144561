// BandReader: the deflate, Zstandard and JPEG TIFFs it decodes itself (libdeflate, libzstd, libjpeg) give exactly the
// samples GDAL (libtiff's own codecs) gives, tiled or in strips, 8- or 16-bit, RGB (JPEG: YCbCr) or grey, with or
// without alpha, whole or some channels, any band height; the layouts and formats it leaves to GDAL still read;
// damaged tiles are one error naming the file.
#include "BandReader.h"
#include "Raster.h"
#include "TestUtil.h"

#include <gtest/gtest.h>
#include <tiffio.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>

using namespace seasonview;
using namespace seasonview::test;

namespace {

namespace fs = std::filesystem;

// Samples with structure (so the predictor matters) and noise (so deflate has work), different per channel.
template <typename T> std::vector<T> pattern(int w, int h, int channels, unsigned seed) {
    std::vector<T> v(size_t(w) * size_t(h) * size_t(channels));
    std::uint32_t s = seed * 2654435761u + 1;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < channels; ++c) {
                s = s * 1664525u + 1013904223u;
                const double smooth = 0.5 + 0.5 * std::sin(0.05 * x + 0.03 * y + c);
                const double max = sizeof(T) == 1 ? 255.0 : 65535.0;
                v[(size_t(y) * size_t(w) + size_t(x)) * size_t(channels) + size_t(c)] =
                    T(std::min(max, smooth * 0.9 * max + double(s >> 24) * (sizeof(T) == 1 ? 0.1 : 25.0)));
            }
    return v;
}

// Every band of `path` through BandReader, first `channels` channels, as one image.
template <typename T>
std::vector<T> readBands(const fs::path& path, int preferredRows, int channels, bool expectOwnDecoder) {
    auto r = BandReader::open(path, preferredRows);
    EXPECT_TRUE(r.ok()) << r.message();
    if (!r) return {};
    EXPECT_EQ(r->decodesTilesItself(), expectOwnDecoder) << path;
    std::vector<T> out(size_t(r->width()) * size_t(r->height()) * size_t(channels));
    for (int y = 0; y < r->height(); y += r->bandRows()) {
        const int y1 = std::min(r->height(), y + r->bandRows());
        auto st = r->read(y, y1, channels, sizeof(T) == 1 ? SampleType::U8 : SampleType::U16,
                          out.data() + size_t(y) * size_t(r->width()) * size_t(channels));
        EXPECT_TRUE(st.ok()) << st.message();
    }
    EXPECT_EQ(r->readsHandedOver(), 0) << path << ": the own decoder failed and GDAL stood in";
    return out;
}

template <typename T> std::vector<T> readWhole(const fs::path& path, int channels) {
    if constexpr (sizeof(T) == 1) {
        auto img = readImageU8(path, channels);
        EXPECT_TRUE(img.ok()) << img.message();
        return img ? img->pixels : std::vector<T>{};
    } else {
        auto img = readImageU16(path, channels);
        EXPECT_TRUE(img.ok()) << img.message();
        return img ? img->pixels : std::vector<T>{};
    }
}

template <typename T>
void expectSameAsGdal(const fs::path& dir, int w, int h, int channels, int tile,
                      TiffCompression compression = TiffCompression::Deflate) {
    const SampleType type = sizeof(T) == 1 ? SampleType::U8 : SampleType::U16;
    const std::vector<T> data = pattern<T>(w, h, channels, unsigned(w * 7 + channels));
    GeoTiffWriteOptions o;
    o.tileSize = tile;
    o.compression = compression;
    const fs::path path = dir / ("img_" + std::to_string(channels) + "_" + std::to_string(tile) + "_" +
                                 tiffCompressionName(compression) + ".tif");
    ASSERT_TRUE(writeGeoTiff(path, data.data(), type, w, h, channels, testGeoref(), o).ok());
    // Alpha (2 and 4 channels) is read raw, as GDAL reads it.
    const bool own = true;
    for (int wanted = 1; wanted <= channels; ++wanted) {
        const std::vector<T> whole = readWhole<T>(path, wanted);
        for (int rows : {1, 16, 50, 256, 1000}) {
            SCOPED_TRACE(std::string(tiffCompressionName(compression)) + ", " +"channels " + std::to_string(wanted) + " of " + std::to_string(channels) + ", tile " +
                         std::to_string(tile) + ", bands of " + std::to_string(rows));
            EXPECT_TRUE(readBands<T>(path, rows, wanted, own) == whole);
        }
    }
}

/// A JPEG-in-TIFF written by libtiff's own codec, tiled or in strips of 16 rows: by default as orthophotos come
/// (GDAL's COMPRESS=JPEG PHOTOMETRIC=YCBCR: RGB converted to YCbCr, 2×2 subsampled); `photometric` RGB or MINISBLACK
/// (then 1 channel) as the components are; `tablesMode` what the JPEGTABLES tag holds (quantisation and Huffman by
/// default; QUANT: the Huffman tables in every tile).
void writeJpegTiff(const fs::path& path, const std::vector<std::uint8_t>& px, int w, int h, int tile,
                   std::uint16_t photometric = PHOTOMETRIC_YCBCR,
                   int tablesMode = JPEGTABLESMODE_QUANT | JPEGTABLESMODE_HUFF) {
    const int channels = photometric == PHOTOMETRIC_MINISBLACK ? 1 : 3;
    TIFF* t = TIFFOpen(path.c_str(), "w");
    ASSERT_TRUE(t) << path;
    TIFFSetField(t, TIFFTAG_IMAGEWIDTH, std::uint32_t(w));
    TIFFSetField(t, TIFFTAG_IMAGELENGTH, std::uint32_t(h));
    TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, 8);
    TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, channels);
    TIFFSetField(t, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
    TIFFSetField(t, TIFFTAG_COMPRESSION, COMPRESSION_JPEG);
    TIFFSetField(t, TIFFTAG_PHOTOMETRIC, photometric);
    if (photometric == PHOTOMETRIC_YCBCR) TIFFSetField(t, TIFFTAG_JPEGCOLORMODE, JPEGCOLORMODE_RGB);
    TIFFSetField(t, TIFFTAG_JPEGQUALITY, 85);
    TIFFSetField(t, TIFFTAG_JPEGTABLESMODE, tablesMode);
    const int bw = tile > 0 ? tile : w, bh = tile > 0 ? tile : 16;
    if (tile > 0) {
        TIFFSetField(t, TIFFTAG_TILEWIDTH, std::uint32_t(tile));
        TIFFSetField(t, TIFFTAG_TILELENGTH, std::uint32_t(tile));
    } else {
        TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, std::uint32_t(bh));
    }
    const size_t pixel = size_t(channels);
    std::vector<std::uint8_t> block(size_t(bw) * size_t(bh) * pixel);
    for (int y = 0; y < h; y += bh)
        for (int x = 0; x < w; x += bw) {
            std::fill(block.begin(), block.end(), std::uint8_t(0));
            const int rows = std::min(bh, h - y), cols = std::min(bw, w - x);
            for (int r = 0; r < rows; ++r)
                std::memcpy(&block[size_t(r) * size_t(bw) * pixel],
                            &px[(size_t(y + r) * size_t(w) + size_t(x)) * pixel], size_t(cols) * pixel);
            const auto ux = std::uint32_t(x), uy = std::uint32_t(y);
            const tmsize_t n = tile > 0 ? TIFFWriteEncodedTile(t, TIFFComputeTile(t, ux, uy, 0, 0), block.data(),
                                                               tmsize_t(block.size()))
                                        : TIFFWriteEncodedStrip(t, TIFFComputeStrip(t, uy, 0), block.data(),
                                                                tmsize_t(size_t(rows) * size_t(bw) * pixel));
            ASSERT_GT(n, 0) << path;
        }
    TIFFClose(t);
}

/// The whole image as libtiff's JPEG codec decodes it (JPEGCOLORMODE_RGB for YCbCr), tile by tile or strip by strip.
std::vector<std::uint8_t> libtiffPixels(const fs::path& path) {
    TIFF* t = TIFFOpen(path.c_str(), "r");
    EXPECT_TRUE(t) << path;
    if (!t) return {};
    std::uint16_t photometric = 0, spp = 0;
    TIFFGetField(t, TIFFTAG_PHOTOMETRIC, &photometric);
    TIFFGetFieldDefaulted(t, TIFFTAG_SAMPLESPERPIXEL, &spp);
    if (photometric == PHOTOMETRIC_YCBCR) TIFFSetField(t, TIFFTAG_JPEGCOLORMODE, JPEGCOLORMODE_RGB);
    std::uint32_t w = 0, h = 0;
    TIFFGetField(t, TIFFTAG_IMAGEWIDTH, &w);
    TIFFGetField(t, TIFFTAG_IMAGELENGTH, &h);
    const size_t pixel = spp;
    std::vector<std::uint8_t> out(size_t(w) * size_t(h) * pixel);
    std::uint32_t bw = w, bh = 0;
    const bool tiled = TIFFIsTiled(t);
    if (tiled) {
        TIFFGetField(t, TIFFTAG_TILEWIDTH, &bw);
        TIFFGetField(t, TIFFTAG_TILELENGTH, &bh);
    } else {
        TIFFGetFieldDefaulted(t, TIFFTAG_ROWSPERSTRIP, &bh);
    }
    std::vector<std::uint8_t> block(size_t(bw) * size_t(bh) * pixel);
    for (std::uint32_t y = 0; y < h; y += bh)
        for (std::uint32_t x = 0; x < w; x += bw) {
            const auto size = tmsize_t(block.size());
            const tmsize_t got = tiled ? TIFFReadEncodedTile(t, TIFFComputeTile(t, x, y, 0, 0), block.data(), size)
                                       : TIFFReadEncodedStrip(t, TIFFComputeStrip(t, y, 0), block.data(), size);
            EXPECT_GT(got, 0) << path << " at " << x << "," << y;
            for (std::uint32_t r = 0; r < bh && y + r < h; ++r)
                std::memcpy(&out[(size_t(y + r) * w + x) * pixel], &block[size_t(r) * bw * pixel],
                            size_t(std::min(bw, w - x)) * pixel);
        }
    TIFFClose(t);
    return out;
}

} // namespace

TEST(BandReaderTest, OwnJpegDecoderEqualsLibtiff) {
    // The reference is libtiff's JPEG codec with JPEGCOLORMODE_RGB, as GDAL reads them.
    TempDir dir("bandreader-jpeg");
    struct Variant {
        const char* name;
        std::uint16_t photometric;
        int tablesMode;
    };
    for (const Variant& var : {Variant{"ycbcr", PHOTOMETRIC_YCBCR, JPEGTABLESMODE_QUANT | JPEGTABLESMODE_HUFF},
                               Variant{"ycbcr-quant-tables", PHOTOMETRIC_YCBCR, JPEGTABLESMODE_QUANT},
                               Variant{"rgb", PHOTOMETRIC_RGB, JPEGTABLESMODE_QUANT | JPEGTABLESMODE_HUFF},
                               Variant{"grey", PHOTOMETRIC_MINISBLACK, JPEGTABLESMODE_QUANT | JPEGTABLESMODE_HUFF}})
        for (int tile : {0, 64, 256}) {
            const int w = 301, h = 197; // partial tiles, odd sizes against the 2×2 chroma subsampling
            const int channels = var.photometric == PHOTOMETRIC_MINISBLACK ? 1 : 3;
            const fs::path path = dir / (std::string(var.name) + "_" + std::to_string(tile) + ".tif");
            writeJpegTiff(path, pattern<std::uint8_t>(w, h, channels, unsigned(tile + 3)), w, h, tile, var.photometric,
                          var.tablesMode);
            const std::vector<std::uint8_t> all = libtiffPixels(path);
            ASSERT_EQ(all.size(), size_t(w) * size_t(h) * size_t(channels));
            for (int wanted = 1; wanted <= channels; ++wanted) {
                std::vector<std::uint8_t> ref(size_t(w) * size_t(h) * size_t(wanted));
                for (size_t p = 0; p < size_t(w) * size_t(h); ++p)
                    std::memcpy(&ref[p * size_t(wanted)], &all[p * size_t(channels)], size_t(wanted));
                for (int rows : {1, 16, 50, 256, 1000}) {
                    SCOPED_TRACE(std::string(var.name) + ", channels " + std::to_string(wanted) + ", tile " +
                                 std::to_string(tile) + ", bands of " + std::to_string(rows));
                    EXPECT_TRUE(readBands<std::uint8_t>(path, rows, wanted, true) == ref);
                }
            }
        }
    // GeoTiffStreamWriter's own JPEG tiles (complete streams, no JPEGTABLES tag; edge tiles padded with their edge):
    // the same through libtiff, close to what was written, at the image's last column and row too.
    for (int tile : {0, 256}) {
        const int w = 301, h = 197;
        const std::vector<std::uint8_t> src = pattern<std::uint8_t>(w, h, 3, 11);
        GeoTiffWriteOptions o;
        o.tileSize = tile;
        o.compression = TiffCompression::Jpeg;
        const fs::path path = dir / ("own_" + std::to_string(tile) + ".tif");
        ASSERT_TRUE(writeGeoTiff(path, src.data(), SampleType::U8, w, h, 3, testGeoref(), o).ok());
        const std::vector<std::uint8_t> mine = readBands<std::uint8_t>(path, 64, 3, true);
        ASSERT_EQ(mine.size(), src.size());
        EXPECT_TRUE(mine == libtiffPixels(path)) << "tile " << tile;
        auto psnr = [&](auto inside) {
            double sq = 0.0;
            size_t n = 0;
            for (int y = 0; y < h; ++y)
                for (int x = 0; x < w; ++x) {
                    if (!inside(x, y)) continue;
                    for (size_t c = 0; c < 3; ++c) {
                        const size_t i = (size_t(y) * size_t(w) + size_t(x)) * 3 + c;
                        sq += (double(src[i]) - double(mine[i])) * (double(src[i]) - double(mine[i]));
                        ++n;
                    }
                }
            return 10.0 * std::log10(255.0 * 255.0 / (sq / double(n)));
        };
        const double all = psnr([](int, int) { return true; });
        const double edge = psnr([&](int x, int y) { return x == w - 1 || y == h - 1; });
        EXPECT_GT(all, 30.0) << "tile " << tile << ": quality 90 on smooth colours with noise";
        EXPECT_GT(edge, all - 3.0) << "tile " << tile << ": the edge as good as the rest (not padded with black)";
        std::printf("own JPEG, tile %d: PSNR %.1f dB, last column and row %.1f dB\n", tile, all, edge);
    }
    // A tile that is not JPEG at all: the own decoder refuses it, finally (it is not handed to GDAL): one line
    // naming the file and saying what libjpeg said, no crash.
    const fs::path path = dir / "damaged.tif";
    writeJpegTiff(path, pattern<std::uint8_t>(512, 512, 3, 9), 512, 512, 256);
    std::uint64_t offset = 0;
    {
        TIFF* t = TIFFOpen(path.c_str(), "r");
        ASSERT_TRUE(t);
        offset = TIFFGetStrileOffset(t, 0);
        TIFFClose(t);
    }
    std::string bytes = readBytes(path);
    ASSERT_LT(offset + 64, bytes.size());
    for (size_t i = 0; i < 64; ++i) bytes[size_t(offset) + i] = char(i * 13 + 1); // no SOI marker any more
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
    auto r = BandReader::open(path, 256);
    ASSERT_TRUE(r.ok()) << r.message();
    EXPECT_TRUE(r->decodesTilesItself());
    std::vector<std::uint8_t> out(size_t(512) * 256 * 3);
    const Status st = r->read(0, 256, 3, SampleType::U8, out.data());
    ASSERT_FALSE(st.ok()) << "a tile without a JPEG stream must not read as pixels";
    EXPECT_EQ(st.message().rfind(path.string() + ": ", 0), 0u) << st.message();
    EXPECT_NE(st.message().find("JPEG tile 0"), std::string::npos) << st.message();
    EXPECT_EQ(st.message().find('\n'), std::string::npos) << st.message();
    EXPECT_EQ(r->readsHandedOver(), 0);
    EXPECT_TRUE(r->read(256, 512, 3, SampleType::U8, out.data()).ok()) << "the intact row of tiles still reads";
}

TEST(BandReaderTest, OwnDeflateDecoderEqualsGdal) {
    TempDir dir("bandreader-same");
    for (int tile : {0, 64, 256}) { // strips of 16 rows, small and usual tiles
        expectSameAsGdal<std::uint8_t>(dir.path(), 301, 197, 3, tile);
        expectSameAsGdal<std::uint8_t>(dir.path(), 301, 197, 1, tile);
        expectSameAsGdal<std::uint16_t>(dir.path(), 301, 197, 3, tile);
        expectSameAsGdal<std::uint16_t>(dir.path(), 130, 67, 1, tile);
    }
    expectSameAsGdal<std::uint8_t>(dir.path(), 100, 90, 4, 64); // RGBA
    expectSameAsGdal<std::uint8_t>(dir.path(), 1, 1, 3, 16);    // one pixel, one mostly empty tile
}

TEST(BandReaderTest, OwnZstdDecoderEqualsGdal) {
    TempDir dir("bandreader-zstd");
    constexpr TiffCompression zstd = TiffCompression::Zstd;
    for (int tile : {0, 64, 256}) {
        expectSameAsGdal<std::uint8_t>(dir.path(), 301, 197, 3, tile, zstd);
        expectSameAsGdal<std::uint8_t>(dir.path(), 301, 197, 1, tile, zstd);
        expectSameAsGdal<std::uint16_t>(dir.path(), 301, 197, 3, tile, zstd);
    }
    expectSameAsGdal<std::uint8_t>(dir.path(), 100, 90, 4, 64, zstd);
    expectSameAsGdal<std::uint8_t>(dir.path(), 1, 1, 3, 16, zstd);
}

TEST(BandReaderTest, OtherFormatsStillReadThroughGdal) {
    TempDir dir("bandreader-other");
    const std::vector<std::uint8_t> grey = pattern<std::uint8_t>(77, 45, 1, 3);
    ASSERT_TRUE(writeImageAtomic(dir / "mask.png", grey.data(), 77, 45, 1).ok());
    EXPECT_TRUE(readBands<std::uint8_t>(dir / "mask.png", 10, 1, false) == grey);
    // LZW (GDAL's codec) and JPEG 2000 files.
    const std::vector<std::uint8_t> rgbLzw = pattern<std::uint8_t>(70, 50, 3, 6);
    GdalRasterSpec lzw;
    lzw.creationOptions = {"COMPRESS=LZW", "TILED=YES", "BLOCKXSIZE=32", "BLOCKYSIZE=32"};
    writeGdalRaster(dir / "lzw.tif", rgbLzw.data(), SampleType::U8, 70, 50, 3, lzw);
    EXPECT_TRUE(readBands<std::uint8_t>(dir / "lzw.tif", 40, 3, false) == rgbLzw);
    GdalRasterSpec jp2;
    jp2.driver = "JP2OpenJPEG";
    jp2.creationOptions = {"REVERSIBLE=YES", "QUALITY=100"};
    writeGdalRaster(dir / "a.jp2", rgbLzw.data(), SampleType::U8, 70, 50, 3, jp2);
    EXPECT_TRUE(readBands<std::uint8_t>(dir / "a.jp2", 40, 3, false) == rgbLzw);
    // An 8-bit file read as 16-bit: GDAL converts numerically (the values stay, nothing is rescaled).
    const std::vector<std::uint8_t> rgb = pattern<std::uint8_t>(64, 40, 3, 4);
    ASSERT_TRUE(writeGeoTiff(dir / "rgb.tif", rgb.data(), SampleType::U8, 64, 40, 3, testGeoref()).ok());
    auto r = BandReader::open(dir / "rgb.tif", 64);
    ASSERT_TRUE(r.ok());
    std::vector<std::uint16_t> wide(rgb.size());
    ASSERT_TRUE(r->read(0, 40, 3, SampleType::U16, wide.data()).ok());
    for (size_t i = 0; i < rgb.size(); ++i) ASSERT_EQ(wide[i], std::uint16_t(rgb[i])) << i;
}

TEST(BandReaderTest, DamagedTilesAreOneLineNamingTheFile) {
    for (TiffCompression compression : {TiffCompression::Deflate, TiffCompression::Zstd}) {
        SCOPED_TRACE(tiffCompressionName(compression));
        TempDir dir("bandreader-damaged");
        const int w = 512, h = 512;
        const std::vector<std::uint8_t> rgb = pattern<std::uint8_t>(w, h, 3, 5);
        const fs::path path = dir / "a.tif";
        GeoTiffWriteOptions o;
        o.compression = compression;
        ASSERT_TRUE(writeGeoTiff(path, rgb.data(), SampleType::U8, w, h, 3, testGeoref(), o).ok());
        const std::string bytes = readBytes(path);
        std::string garbled = bytes; // the directory (at the end) intact, tile data in the middle garbled
        for (size_t i = bytes.size() / 4; i < bytes.size() / 2; ++i) garbled[i] = char(i * 13);
        std::ofstream(path, std::ios::binary | std::ios::trunc) << garbled;
        auto r = BandReader::open(path, 256);
        ASSERT_TRUE(r.ok()) << r.message();
        std::vector<std::uint8_t> out(size_t(w) * 256 * 3);
        bool failed = false;
        for (int y = 0; y < h; y += 256) {
            const Status st = r->read(y, y + 256, 3, SampleType::U8, out.data());
            if (st) continue;
            failed = true;
            EXPECT_EQ(st.message().rfind(path.string() + ": ", 0), 0u) << st.message();
            EXPECT_NE(st.message().find(compression == TiffCompression::Zstd ? "Zstandard tile " : "deflate tile "),
                      std::string::npos)
                << st.message();
            EXPECT_EQ(st.message().find('\n'), std::string::npos) << st.message();
        }
        EXPECT_TRUE(failed) << "garbled tiles must not read as pixels";
        EXPECT_EQ(r->readsHandedOver(), 0) << "the own decoder's refusal is final";
    }
}

// A deflate tile whose Adler-32 (the stream's last four bytes) is damaged: the own decoder checks it and refuses the
// read, naming the tile and the check, and does not hand the tile to GDAL (its refusal is final).
TEST(BandReaderTest, DeflateChecksumDamageIsFinal) {
    TempDir dir("bandreader-adler");
    const int w = 256, h = 256;
    const std::vector<std::uint8_t> rgb = pattern<std::uint8_t>(w, h, 3, 7);
    const fs::path path = dir / "a.tif";
    GeoTiffWriteOptions o;
    o.compression = TiffCompression::Deflate;
    ASSERT_TRUE(writeGeoTiff(path, rgb.data(), SampleType::U8, w, h, 3, testGeoref(), o).ok());
    std::uint64_t offset = 0, size = 0;
    {
        TIFF* t = TIFFOpen(path.c_str(), "r");
        ASSERT_TRUE(t);
        ASSERT_TRUE(TIFFIsTiled(t)) << "one 256² tile";
        offset = TIFFGetStrileOffset(t, 0);
        size = TIFFGetStrileByteCount(t, 0);
        TIFFClose(t);
    }
    std::string bytes = readBytes(path);
    ASSERT_GT(size, 4u);
    bytes[size_t(offset + size - 1)] = char(bytes[size_t(offset + size - 1)] ^ 0x5a);
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
    auto r = BandReader::open(path, 256);
    ASSERT_TRUE(r.ok()) << r.message();
    ASSERT_TRUE(r->decodesTilesItself());
    std::vector<std::uint8_t> out(size_t(w) * size_t(h) * 3);
    const Status st = r->read(0, h, 3, SampleType::U8, out.data());
    ASSERT_FALSE(st.ok()) << "a tile failing its checksum must not read as pixels";
    EXPECT_EQ(st.message().rfind(path.string() + ": ", 0), 0u) << st.message();
    EXPECT_NE(st.message().find("deflate tile 0"), std::string::npos) << st.message();
    EXPECT_EQ(r->readsHandedOver(), 0);
}
