// Declared sizes past the limits are refused before anything is allocated for them, the limit named: raster sides,
// bands, tile counts, whole-image reads, polygons per face and per city model.
#include "CityModel.h"
#include "GdalSupport.h"
#include "Raster.h"
#include "TestUtil.h"

#include <gtest/gtest.h>

#include <fstream>

using namespace seasonview;
using namespace seasonview::test;

namespace {

namespace fs = std::filesystem;

/// A sparse tiled GeoTIFF of width×height×bands bytes (only its header and tile index on disk).
void sparseTiff(const fs::path& p, int width, int height, int bands) {
    gdal::init();
    GDALDriver* gtiff = GetGDALDriverManager()->GetDriverByName("GTiff");
    const char* options[] = {"TILED=YES", "SPARSE_OK=TRUE", "BIGTIFF=YES", nullptr};
    GDALDataset* ds = gtiff->Create(p.c_str(), width, height, bands, GDT_Byte, const_cast<char**>(options));
    ASSERT_NE(ds, nullptr);
    GDALClose(ds);
}

/// A classic TIFF header alone: width×height in tileSize² tiles whose index lies past the end of the file (GDAL reads
/// the index lazily, so the header opens).
void headerOnlyTiff(const fs::path& p, std::uint32_t width, std::uint32_t height, std::uint32_t tileSize) {
    const std::uint32_t tiles = ((width + tileSize - 1) / tileSize) * ((height + tileSize - 1) / tileSize);
    struct Entry {
        std::uint16_t tag, type;
        std::uint32_t count, value;
    };
    const Entry entries[] = {{256, 4, 1, width}, {257, 4, 1, height}, {258, 3, 1, 8},        {259, 3, 1, 1},
                             {262, 3, 1, 1},     {277, 3, 1, 1},      {284, 3, 1, 1},        {322, 4, 1, tileSize},
                             {323, 4, 1, tileSize}, {324, 4, tiles, 4096}, {325, 4, tiles, 4096}};
    std::string b = "II";
    auto put = [&](auto v) { b.append(reinterpret_cast<const char*>(&v), sizeof v); };
    put(std::uint16_t(42));
    put(std::uint32_t(8));
    put(std::uint16_t(std::size(entries)));
    for (const Entry& e : entries) {
        put(e.tag);
        put(e.type);
        put(e.count);
        if (e.type == 3 && e.count == 1) {
            put(std::uint16_t(e.value));
            put(std::uint16_t(0));
        } else {
            put(e.value);
        }
    }
    put(std::uint32_t(0));
    std::ofstream(p, std::ios::binary) << b;
}

} // namespace

TEST(ResourceLimitsTest, RasterSidesOverTheLimitAreRefused) {
    TempDir dir("limits-side");
    sparseTiff(dir / "wide.tif", int(gdal::kMaxRasterSide) + 1, 16, 3);
    auto r = readRasterInfo(dir / "wide.tif");
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.message().find("wide.tif: declared size 1048577x16 is over the limit of 1048576 pixels a side"),
              std::string::npos)
        << r.message();
    sparseTiff(dir / "edge.tif", int(gdal::kMaxRasterSide), 16, 3); // at the limit: fine
    EXPECT_TRUE(readRasterInfo(dir / "edge.tif").ok());
}

TEST(ResourceLimitsTest, TileCountsOverTheLimitAreRefused) {
    TempDir dir("limits-tiles");
    // 2^20 x 2^20 in 128² tiles: 2^26 tiles, whose offsets alone would take 512 MiB.
    headerOnlyTiff(dir / "tiles.tif", 1u << 20, 1u << 20, 128);
    auto r = readRasterInfo(dir / "tiles.tif");
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.message().find("declares 67108864 tiles or strips of 128x128, over the limit of 16777216"),
              std::string::npos)
        << r.message();
}

TEST(ResourceLimitsTest, WholeImageReadsOverTheLimitAreRefusedBeforeAllocating) {
    TempDir dir("limits-whole");
    // 40000² RGB: 4.5 GiB held whole. Streaming readers take it; a whole-image read (a truth mask) does not.
    sparseTiff(dir / "big.tif", 40000, 40000, 3);
    EXPECT_TRUE(readRasterInfo(dir / "big.tif").ok());
    auto r = readImageU8(dir / "big.tif", 3);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.message().find("40000x40000 pixels are too many to hold whole (4577 MiB; the limit is 4096 MiB)"),
              std::string::npos)
        << r.message();
}

TEST(ResourceLimitsTest, BandsOverTheLimitAreRefused) {
    TempDir dir("limits-bands");
    writeTestImage(dir / "one.tif", 8, 8, testGeoref(1.0));
    std::ofstream vrt(dir / "bands.vrt");
    vrt << "<VRTDataset rasterXSize=\"8\" rasterYSize=\"8\">\n";
    for (int b = 1; b <= 300; ++b)
        vrt << "<VRTRasterBand dataType=\"Byte\" band=\"" << b << "\"><SimpleSource><SourceFilename relativeToVRT=\"1\">"
            << "one.tif</SourceFilename><SourceBand>1</SourceBand></SimpleSource></VRTRasterBand>\n";
    vrt << "</VRTDataset>\n";
    vrt.close();
    auto r = readRasterInfo(dir / "bands.vrt");
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.message().find("declares 300 bands, over the limit of 256"), std::string::npos) << r.message();
}

TEST(ResourceLimitsTest, ObjFacesOverTheLimitOrNamingMissingVerticesAreRefused) {
    TempDir dir("limits-obj");
    city::CityLoadOptions local;
    local.localFrame = true;
    {
        std::ofstream f(dir / "ring.obj");
        const int n = int(city::kMaxPolygonVertices) + 1;
        for (int i = 0; i < n; ++i)
            f << "v " << 10.0 * std::cos(6.283185 * i / n) << " 0 " << 10.0 * std::sin(6.283185 * i / n) << "\n";
        f << "f";
        for (int i = 1; i <= n; ++i) f << " " << i;
        f << "\n";
    }
    auto r = city::loadCityModel((dir / "ring.obj").string(), local);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.message().find("a face of more than 255 vertices, over the limit of 255"), std::string::npos)
        << r.message();

    std::ofstream(dir / "missing.obj") << "v 0 0 0\nv 1 0 0\nv 1 0 1\nf 1 2 9\n";
    auto m = city::loadCityModel((dir / "missing.obj").string(), local);
    ASSERT_FALSE(m.ok());
    EXPECT_NE(m.message().find("a face refers to vertex 9, which does not exist (3 vertices)"), std::string::npos)
        << m.message();
}

namespace {
/// A CityGML building of `n` square roof polygons (one of them written as `<Polygon>` without a prefix, as files
/// with a default GML namespace do), plus a `gml:PolygonPatch` that is not a polygon.
std::string cityGmlOfPolygons(int n) {
    std::string polygons;
    for (int i = 0; i < n; ++i) {
        const std::string x0 = std::to_string(500000 + 20 * i), x1 = std::to_string(500010 + 20 * i);
        const std::string tag = i == 0 ? "Polygon xmlns=\"http://www.opengis.net/gml\"" : "gml:Polygon";
        const std::string close = i == 0 ? "Polygon" : "gml:Polygon";
        polygons += "<gml:surfaceMember><" + tag + "><gml:exterior><gml:LinearRing><gml:posList srsDimension=\"3\">" +
                    x0 + " 5400000 8 " + x1 + " 5400000 8 " + x1 + " 5400010 8 " + x0 + " 5400010 8 " + x0 +
                    " 5400000 8</gml:posList></gml:LinearRing></gml:exterior></" + close + "></gml:surfaceMember>";
    }
    return R"(<?xml version="1.0" encoding="UTF-8"?>
<CityModel xmlns="http://www.opengis.net/citygml/2.0" xmlns:gml="http://www.opengis.net/gml"
 xmlns:bldg="http://www.opengis.net/citygml/building/2.0">
<gml:boundedBy><gml:Envelope srsName="EPSG:32632" srsDimension="3"><gml:lowerCorner>500000 5400000 0</gml:lowerCorner>
<gml:upperCorner>510000 5400010 8</gml:upperCorner></gml:Envelope></gml:boundedBy>
<!-- gml:PolygonPatch and a comment naming <Polygons> are not polygons -->
<cityObjectMember><bldg:Building gml:id="B1"><bldg:boundedBy><bldg:RoofSurface gml:id="R1"><bldg:lod2MultiSurface>
<gml:MultiSurface>)" + polygons + R"(</gml:MultiSurface></bldg:lod2MultiSurface></bldg:RoofSurface></bldg:boundedBy>
</bldg:Building></cityObjectMember></CityModel>
)";
}
} // namespace

TEST(ResourceLimitsTest, CityPolygonsOverTheLimitAreRefused) {
    TempDir dir("limits-city");
    {
        std::ofstream(dir / "three.gml") << cityGmlOfPolygons(3);
    }
    city::CityLoadOptions at3, at2;
    at3.maxPolygons = 3;
    at2.maxPolygons = 2;
    auto ok = city::loadCityModel((dir / "three.gml").string(), at3);
    ASSERT_TRUE(ok.ok()) << ok.message();
    EXPECT_EQ(ok->triangles.size(), 6u); // three squares: the count read from the text is what libcitygml builds
    auto r = city::loadCityModel((dir / "three.gml").string(), at2);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.message().find("three.gml: more than 2 polygons, over the limit of 2"), std::string::npos) << r.message();
    // The count reads the file in chunks of 1 MiB: with the second polygon's tag moved across the first chunk's end
    // (and the part of it read again with the next chunk), all three are still counted.
    const std::string text = cityGmlOfPolygons(3);
    const std::size_t second = text.find("<gml:Polygon", text.find("<gml:Polygon") + 1);
    for (int shift = -300; shift <= 20; shift += 3) {
        std::string padded = text;
        padded.insert(text.find("<cityObjectMember>"), std::size_t((1 << 20) - int(second) + shift), ' ');
        std::ofstream(dir / "padded.gml") << padded;
        auto p = city::loadCityModel((dir / "padded.gml").string(), at2);
        EXPECT_FALSE(p.ok()) << "shift " << shift;
    }
    EXPECT_TRUE(city::loadCityModel((dir / "padded.gml").string(), at3).ok());

    city::CityLoadOptions local;
    local.localFrame = true;
    local.maxPolygons = 2;
    std::ofstream(dir / "three.obj") << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\nf 2 3 4\n";
    auto o = city::loadCityModel((dir / "three.obj").string(), local);
    ASSERT_FALSE(o.ok());
    EXPECT_NE(o.message().find("3 faces, over the limit of 2"), std::string::npos) << o.message();
}
