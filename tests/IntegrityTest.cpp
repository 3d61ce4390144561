// Damaged input is never read as pixels: bit flips anywhere in a Zstandard tile (its content checksum), files cut short
// at many offsets, JPEG streams cut short — each one error naming the file, through every reader (BandReader's own
// decoders, GDAL, the grid reader).
#include "BandReader.h"
#include "GridReader.h"
#include "Raster.h"
#include "TestUtil.h"
#include "ZstdTileCheck.h"

#include <gtest/gtest.h>
#include <tiffio.h>

#include <chrono>
#include <cstring>
#include <fstream>

using namespace seasonview;
using namespace seasonview::test;

namespace {

namespace fs = std::filesystem;

std::vector<std::uint8_t> noiseRgb(int w, int h, unsigned seed) {
    std::vector<std::uint8_t> v(size_t(w) * size_t(h) * 3);
    std::uint32_t s = seed;
    for (auto& b : v) {
        s = s * 1664525u + 1013904223u;
        b = std::uint8_t((s >> 24) / 2 + 64);
    }
    return v;
}

/// Offset and size of tile `index` of a TIFF.
std::pair<std::uint64_t, std::uint64_t> tileBytes(const fs::path& p, int index) {
    TIFF* t = TIFFOpen(p.c_str(), "r");
    EXPECT_TRUE(t);
    const std::uint64_t o = TIFFGetStrileOffset(t, std::uint32_t(index)), n = TIFFGetStrileByteCount(t, std::uint32_t(index));
    TIFFClose(t);
    return {o, n};
}

/// Whether every reader refuses the file (one line naming it); false when any read it as pixels.
bool everyReaderRefuses(const fs::path& p, std::string* why = nullptr) {
    auto img = readImageU8(p, 3);
    if (img.ok()) return false;
    if (why) *why = img.message();
    if (img.message().rfind(p.string() + ": ", 0) != 0 || img.message().find('\n') != std::string::npos) return false;
    auto r = BandReader::open(p, 256);
    if (!r) return true;
    std::vector<std::uint8_t> buf(size_t(r->width()) * size_t(r->bandRows()) * 3);
    bool failed = false;
    for (int y = 0; y < r->height(); y += r->bandRows()) {
        const Status st = r->read(y, std::min(r->height(), y + r->bandRows()), 3, SampleType::U8, buf.data());
        if (!st) {
            failed = true;
            if (st.message().rfind(p.string() + ": ", 0) != 0) return false;
        }
    }
    return failed;
}

} // namespace

TEST(IntegrityTest, BitFlipsAnywhereInAZstdTileAreCaught) {
    // Without a checksum, a flipped byte among a Zstandard frame's literals decodes to other pixels without a word.
    TempDir dir("integrity-zstd");
    const std::vector<std::uint8_t> px = noiseRgb(256, 256, 7);
    GeoTiffWriteOptions o;
    o.compression = TiffCompression::Zstd;
    ASSERT_TRUE(writeGeoTiff(dir / "clean.tif", px.data(), SampleType::U8, 256, 256, 3, testGeoref(), o).ok());
    const auto [offset, size] = tileBytes(dir / "clean.tif", 0);
    ASSERT_GT(size, 64u);
    int caught = 0, tried = 0;
    for (std::uint64_t k = 1; k < 40; ++k) {
        fs::copy_file(dir / "clean.tif", dir / "flipped.tif", fs::copy_options::overwrite_existing);
        flipByte(dir / "flipped.tif", offset + size * k / 40);
        ++tried;
        caught += everyReaderRefuses(dir / "flipped.tif") ? 1 : 0;
    }
    EXPECT_EQ(caught, tried);
}

TEST(IntegrityTest, ZstdTileCheckCatchesFlipsInFloatTilesThatDecodeSilently) {
    // Heights as the elevation pyramid stores them: floats, Zstandard with the floating-point predictor. Noise
    // leaves most of a frame as raw literals, where a flipped byte breaks nothing but the content checksum, which
    // libtiff's codec never reaches (GDAL and OpenImageIO read such a tile as other heights).
    TempDir dir("integrity-zstd-float");
    const std::vector<float> heights = noiseHeights(size_t(256) * 256, 11, 100.0f, 50.0f);
    GeoTiffWriteOptions o;
    o.compression = TiffCompression::Zstd;
    o.tileSize = 128;
    ASSERT_TRUE(writeGeoTiff(dir / "clean.tif", heights.data(), SampleType::F32, 256, 256, 1, testGeoref(), o).ok());
    {
        ZstdTileCheck check;
        EXPECT_TRUE(check.check(dir / "clean.tif", 0, 0, 256, 256).ok());
    }
    const auto [offset, size] = tileBytes(dir / "clean.tif", 3);
    ASSERT_GT(size, 64u);
    int caught = 0, tried = 0;
    for (std::uint64_t k = 1; k < 40; ++k) {
        fs::copy_file(dir / "clean.tif", dir / "flipped.tif", fs::copy_options::overwrite_existing);
        flipByte(dir / "flipped.tif", offset + size * k / 40);
        ++tried;
        ZstdTileCheck check;
        EXPECT_TRUE(check.check(dir / "flipped.tif", 0, 0, 128, 128).ok()) << "tile 0 is intact";
        const Status st = check.check(dir / "flipped.tif", 100, 100, 300, 300); // tiles 0, 1, 2 and 3
        if (!st) {
            ++caught;
            EXPECT_EQ(st.message().rfind((dir / "flipped.tif").string() + ": tile 3 (column 1, row 1)", 0), 0u)
                << st.message();
        }
    }
    EXPECT_EQ(caught, tried);

    // Checked once per file: a file rewritten in place (another size or time) is checked again.
    ZstdTileCheck check;
    fs::copy_file(dir / "clean.tif", dir / "rewritten.tif");
    ASSERT_TRUE(check.check(dir / "rewritten.tif", 0, 0, 256, 256).ok());
    fs::copy_file(dir / "flipped.tif", dir / "rewritten.tif", fs::copy_options::overwrite_existing);
    fs::last_write_time(dir / "rewritten.tif", fs::last_write_time(dir / "rewritten.tif") + std::chrono::seconds(2));
    EXPECT_FALSE(check.check(dir / "rewritten.tif", 0, 0, 256, 256).ok());
    // Files of other compressions pass: there is no checksum to verify.
    o.compression = TiffCompression::Deflate;
    ASSERT_TRUE(writeGeoTiff(dir / "deflate.tif", heights.data(), SampleType::F32, 256, 256, 1, testGeoref(), o).ok());
    EXPECT_TRUE(check.check(dir / "deflate.tif", 0, 0, 256, 256).ok());
}

TEST(IntegrityTest, ZstdTilesCarryACrcTheCheckVerifiesWithoutDecoding) {
    // GeoTiffStreamWriter ends each Zstandard tile with a skippable frame holding a CRC-32 of the bytes before it:
    // readers pass over it (the pixels read back the same), ZstdTileCheck verifies it instead of decoding the tile,
    // and a tile without one (another writer's) is still checked by decoding it.
    TempDir dir("integrity-zstd-crc");
    const std::vector<std::uint8_t> px = noiseRgb(256, 256, 5);
    GeoTiffWriteOptions o;
    o.compression = TiffCompression::Zstd;
    o.tileSize = 128;
    ASSERT_TRUE(writeGeoTiff(dir / "clean.tif", px.data(), SampleType::U8, 256, 256, 3, testGeoref(), o).ok());
    const auto rawTile = [](const fs::path& p, int index) {
        TIFF* t = TIFFOpen(p.c_str(), "r");
        std::vector<std::uint8_t> raw;
        if (!t) return raw;
        raw.resize(size_t(TIFFGetStrileByteCount(t, std::uint32_t(index))));
        if (TIFFReadRawTile(t, std::uint32_t(index), raw.data(), tmsize_t(raw.size())) != tmsize_t(raw.size())) raw.clear();
        TIFFClose(t);
        return raw;
    };
    for (int i = 0; i < 4; ++i) {
        const std::vector<std::uint8_t> raw = rawTile(dir / "clean.tif", i);
        ASSERT_GT(raw.size(), kTileChecksumBytes);
        EXPECT_EQ(verifyTileChecksum(raw.data(), raw.size()), TileChecksum::Matches) << "tile " << i;
    }
    auto img = readImageU8(dir / "clean.tif", 3);
    ASSERT_TRUE(img.ok()) << img.message();
    EXPECT_EQ(img->pixels, px);
    auto band = BandReader::open(dir / "clean.tif", 64);
    ASSERT_TRUE(band.ok()) << band.message();
    std::vector<std::uint8_t> rows(px.size());
    ASSERT_TRUE(band->read(0, 256, 3, SampleType::U8, rows.data()).ok());
    EXPECT_EQ(rows, px);
    {
        ZstdTileCheck check;
        EXPECT_TRUE(check.check(dir / "clean.tif", 0, 0, 256, 256).ok());
    }

    // The CRC itself damaged: the tile is refused, by name.
    const auto [offset, size] = tileBytes(dir / "clean.tif", 2);
    fs::copy_file(dir / "clean.tif", dir / "crc.tif");
    flipByte(dir / "crc.tif", offset + size - 1);
    {
        ZstdTileCheck check;
        EXPECT_TRUE(check.check(dir / "crc.tif", 0, 0, 256, 128).ok()) << "tiles 0 and 1 are intact";
        const Status st = check.check(dir / "crc.tif", 0, 0, 256, 256);
        ASSERT_FALSE(st.ok());
        EXPECT_EQ(st.message(), (dir / "crc.tif").string() + ": tile 2 (column 0, row 1) fails its CRC-32 checksum (damaged)");
    }

    // libtiff's own codec writes no trailer: those tiles are decoded, and a frame that does not decode is refused.
    {
        TIFF* t = TIFFOpen((dir / "libtiff.tif").c_str(), "w");
        ASSERT_TRUE(t);
        TIFFSetField(t, TIFFTAG_IMAGEWIDTH, 256u);
        TIFFSetField(t, TIFFTAG_IMAGELENGTH, 256u);
        TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, std::uint16_t(3));
        TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, std::uint16_t(8));
        TIFFSetField(t, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_RGB);
        TIFFSetField(t, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
        TIFFSetField(t, TIFFTAG_TILEWIDTH, 128u);
        TIFFSetField(t, TIFFTAG_TILELENGTH, 128u);
        TIFFSetField(t, TIFFTAG_COMPRESSION, COMPRESSION_ZSTD);
        std::vector<std::uint8_t> tile(size_t(128) * 128 * 3);
        for (int ty = 0; ty < 2; ++ty)
            for (int tx = 0; tx < 2; ++tx) {
                for (int y = 0; y < 128; ++y)
                    std::memcpy(tile.data() + size_t(y) * 128 * 3,
                                px.data() + (size_t(ty * 128 + y) * 256 + size_t(tx) * 128) * 3, 128 * 3);
                ASSERT_GE(TIFFWriteEncodedTile(t, std::uint32_t(ty * 2 + tx), tile.data(), tmsize_t(tile.size())), 0);
            }
        TIFFClose(t);
    }
    const std::vector<std::uint8_t> foreign = rawTile(dir / "libtiff.tif", 1);
    ASSERT_FALSE(foreign.empty());
    EXPECT_EQ(verifyTileChecksum(foreign.data(), foreign.size()), TileChecksum::Absent);
    {
        ZstdTileCheck check;
        EXPECT_TRUE(check.check(dir / "libtiff.tif", 0, 0, 256, 256).ok());
    }
    const auto [offset1, size1] = tileBytes(dir / "libtiff.tif", 1);
    ASSERT_GT(size1, 4u);
    flipByte(dir / "libtiff.tif", offset1); // the frame's magic number
    ZstdTileCheck check;
    const Status st = check.check(dir / "libtiff.tif", 0, 0, 256, 256);
    ASSERT_FALSE(st.ok());
    EXPECT_NE(st.message().find("tile 1 (column 1, row 0) does not decode"), std::string::npos) << st.message();
}

TEST(IntegrityTest, FilesCutShortAreErrorsNamingTheFile) {
    // Every kind of file seasonview writes or reads imagery from, cut at 12 offsets: one line naming the file,
    // never pixels.
    TempDir dir("integrity-cut");
    const std::vector<std::uint8_t> px = noiseRgb(512, 384, 3);
    struct Kind {
        const char* name;
        TiffCompression compression;
    } kinds[] = {{"zstd.tif", TiffCompression::Zstd}, {"deflate.tif", TiffCompression::Deflate},
                 {"jpeg.tif", TiffCompression::Jpeg}};
    for (const Kind& k : kinds) {
        GeoTiffWriteOptions o;
        o.compression = k.compression;
        ASSERT_TRUE(writeGeoTiff(dir / k.name, px.data(), SampleType::U8, 512, 384, 3, testGeoref(), o).ok());
    }
    GdalRasterSpec lzw;
    lzw.creationOptions = {"COMPRESS=LZW", "TILED=YES"};
    lzw.geotransform = geotransformOf(testGeoref());
    lzw.crs = "EPSG:32632";
    writeGdalRaster(dir / "lzw.tif", px.data(), SampleType::U8, 512, 384, 3, lzw);
    ASSERT_TRUE(writeImageAtomic(dir / "image.png", px.data(), 512, 384, 3).ok());
    for (const char* name : {"zstd.tif", "deflate.tif", "jpeg.tif", "lzw.tif", "image.png"}) {
        const auto full = fs::file_size(dir / name);
        for (int cut = 1; cut <= 12; ++cut) {
            SCOPED_TRACE(std::string(name) + " cut to " + std::to_string(cut) + "/13");
            const fs::path p = dir / ("cut_" + std::to_string(cut) + "_" + name);
            fs::copy_file(dir / name, p, fs::copy_options::overwrite_existing);
            fs::resize_file(p, full * std::uintmax_t(cut) / 13);
            std::string why;
            EXPECT_TRUE(everyReaderRefuses(p, &why)) << why;
        }
    }
}

// fuzz_raster: a tile whose byte count claims 3.7 GB made the own decoder allocate that much before reading; a block
// that runs past the end of the file is refused first, naming it. The finding's shape, rebuilt from a test image: its
// one tile's byte count in the TIFF directory overwritten.
TEST(IntegrityTest, BlockIndexPastTheEndOfTheFileIsRefusedBeforeAllocating) {
    TempDir dir("integrity-index");
    const std::filesystem::path file = dir / "claims.tif";
    writeTestImage(file, 40, 40, testGeoref(1.0), false, 3);
    std::string bytes = readBytes(file);
    auto u16 = [&](size_t at) { return std::uint16_t(std::uint8_t(bytes[at]) | std::uint8_t(bytes[at + 1]) << 8); };
    auto u32 = [&](size_t at) { return std::uint32_t(u16(at)) | std::uint32_t(u16(at + 2)) << 16; };
    ASSERT_EQ(bytes.substr(0, 4), std::string("II*\0", 4)) << "a classic little-endian TIFF";
    const size_t ifd = u32(4);
    bool patched = false;
    for (size_t i = 0; i < u16(ifd); ++i) {
        const size_t entry = ifd + 2 + 12 * i;
        if (u16(entry) == TIFFTAG_TILEBYTECOUNTS && u16(entry + 2) == TIFF_LONG && u32(entry + 4) == 1) {
            const std::uint32_t claim = 3705461980u;
            for (int b = 0; b < 4; ++b) bytes[entry + 8 + size_t(b)] = char((claim >> (8 * b)) & 0xff);
            patched = true;
        }
    }
    ASSERT_TRUE(patched) << "one tile, its byte count a LONG in the directory";
    std::ofstream(file, std::ios::binary | std::ios::trunc) << bytes;

    auto r = BandReader::open(file, 64);
    ASSERT_TRUE(r.ok()) << r.message();
    std::vector<std::uint8_t> band(size_t(r->width()) * size_t(r->bandRows()) * 4);
    Status st = Ok{};
    for (int y = 0; y < r->height() && st.ok(); y += r->bandRows())
        st = r->read(y, std::min(r->height(), y + r->bandRows()), 3, SampleType::U8, band.data());
    ASSERT_FALSE(st.ok());
    EXPECT_NE(st.message().find("claims.tif: truncated or corrupt image data"), std::string::npos) << st.message();
    EXPECT_NE(st.message().find("tile 0: 3705461980 bytes at offset"), std::string::npos) << st.message();
    EXPECT_NE(st.message().find("run past the end of the file"), std::string::npos) << st.message();
}
