// City model input: CityGML (libcitygml) and OBJ, CRS handling, bad input, placing buildings on the terrain.
#include "AtlasLayout.h"
#include "CityLoaders.h"
#include "CityModel.h"
#include "GeoFrame.h"
#include "Scene.h"
#include "SyntheticScene.h"
#include "TestUtil.h"

#include <OpenImageIO/imageio.h>
#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <iostream>
#include <fstream>
#include <set>
#include <sstream>

using namespace seasonview;
using namespace seasonview::city;

namespace {

void writeText(const std::filesystem::path& p, const std::string& s) { std::ofstream(p) << s; }

void writePng(const std::filesystem::path& p, int w, int h) {
    std::vector<std::uint8_t> px(std::size_t(w * h * 3), 128);
    auto out = OIIO::ImageOutput::create(p.string());
    ASSERT_TRUE(out);
    ASSERT_TRUE(out->open(p.string(), OIIO::ImageSpec(w, h, 3, OIIO::TypeDesc::UINT8)));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px.data()));
    out->close();
}

std::string polygon(const std::string& id, const std::string& posList) {
    return "<gml:surfaceMember><gml:Polygon gml:id=\"" + id + "\"><gml:exterior><gml:LinearRing gml:id=\"" + id +
           "_r\"><gml:posList srsDimension=\"3\">" + posList +
           "</gml:posList></gml:LinearRing></gml:exterior></gml:Polygon></gml:surfaceMember>";
}

std::string surface(const std::string& kind, const std::string& id, const std::string& polygons) {
    return "<bldg:boundedBy><bldg:" + kind + " gml:id=\"" + id + "\"><bldg:lod2MultiSurface><gml:MultiSurface>" +
           polygons + "</gml:MultiSurface></bldg:lod2MultiSurface></bldg:" + kind + "></bldg:boundedBy>";
}

/// One LoD2 building: a 10 m × 6 m box, 8 m high, on the south side a wall textured with `texture` (0..1 across
/// the wall); `extra` polygons are added to the roof surface. srsName empty = none.
std::string cityGml(const std::string& srsName, const std::string& texture, const std::string& extra = "",
                    double e = 390000.0, double n = 5819000.0, double z = 34.0) {
    auto p = [&](double x, double y, double h) {
        return std::to_string(e + x) + " " + std::to_string(n + y) + " " + std::to_string(z + h) + " ";
    };
    const std::string south = p(0, 0, 0) + p(10, 0, 0) + p(10, 0, 8) + p(0, 0, 8) + p(0, 0, 0);
    const std::string roof = p(0, 0, 8) + p(10, 0, 8) + p(10, 6, 8) + p(0, 6, 8) + p(0, 0, 8);
    const std::string env = srsName.empty() ? "" : " srsName=\"" + srsName + "\"";
    return R"(<?xml version="1.0" encoding="UTF-8"?>
<CityModel xmlns="http://www.opengis.net/citygml/2.0" xmlns:gml="http://www.opengis.net/gml"
 xmlns:bldg="http://www.opengis.net/citygml/building/2.0" xmlns:app="http://www.opengis.net/citygml/appearance/2.0">
<gml:boundedBy><gml:Envelope)" + env + R"( srsDimension="3"><gml:lowerCorner>)" + p(0, 0, 0) +
           "</gml:lowerCorner><gml:upperCorner>" + p(10, 6, 8) + R"(</gml:upperCorner></gml:Envelope></gml:boundedBy>
<cityObjectMember><bldg:Building gml:id="B1">)" +
           surface("WallSurface", "W1", polygon("P1", south)) + surface("RoofSurface", "R1", polygon("P2", roof) + extra) +
           R"(<app:appearance><app:Appearance><app:theme>rgbTexture</app:theme><app:surfaceDataMember>
<app:ParameterizedTexture><app:imageURI>)" + texture + R"(</app:imageURI><app:wrapMode>wrap</app:wrapMode>
<app:target uri="#P1"><app:TexCoordList><app:textureCoordinates ring="#P1_r">0 0 1 0 1 1 0 1 0 0</app:textureCoordinates>
</app:TexCoordList></app:target></app:ParameterizedTexture></app:surfaceDataMember></app:Appearance></app:appearance>
</bldg:Building></cityObjectMember></CityModel>
)";
}

std::size_t count(const CityModel& m, Surface s) {
    return std::size_t(std::count(m.surface.begin(), m.surface.end(), s));
}

} // namespace

TEST(CityModelTest, EpsgFromSrsNameForms) {
    EXPECT_EQ(epsgFromSrsName("EPSG:25833"), 25833);
    EXPECT_EQ(epsgFromSrsName("urn:ogc:def:crs:EPSG::25833"), 25833);
    EXPECT_EQ(epsgFromSrsName("urn:ogc:def:crs:EPSG:6.12:32632"), 32632);
    EXPECT_EQ(epsgFromSrsName("http://www.opengis.net/def/crs/EPSG/0/6697"), 6697);
    EXPECT_EQ(epsgFromSrsName("urn:ogc:def:crs,crs:EPSG::25832,crs:EPSG::7837"), 25832);
    EXPECT_EQ(epsgFromSrsName("urn:adv:crs:ETRS89_UTM33*DE_DHHN2016_NH"), 25833);
    EXPECT_FALSE(epsgFromSrsName("urn:ogc:def:crs:OGC:1.3:CRS84-ish"));
    EXPECT_FALSE(epsgFromSrsName(""));
}

TEST(CityModelTest, TexturedLod2BuildingInUtm) {
    test::TempDir dir("city_gml_ok");
    writePng(dir / "wall.png", 16, 16);
    writeText(dir / "b.gml", cityGml("urn:ogc:def:crs:EPSG::25833", "wall.png"));
    auto m = loadCityModel((dir / "b.gml").string());
    ASSERT_TRUE(m) << m.error().message;
    EXPECT_TRUE(m->warnings.empty()) << m->warnings.front();
    EXPECT_EQ(m->crs.epsg(), 25833);
    EXPECT_EQ(m->buildingIds, std::vector<std::string>{"B1"});
    ASSERT_EQ(m->triangles.size(), 4u);
    EXPECT_EQ(count(*m, Surface::Wall), 2u);
    EXPECT_EQ(count(*m, Surface::Roof), 2u);
    ASSERT_EQ(m->textures.size(), 1u);
    EXPECT_EQ(std::filesystem::path(m->textures[0].path), dir / "wall.png");
    EXPECT_TRUE(m->textures[0].repeat);
    // The frame is centred on the building: x in [-5, 5], y in [-3, 3], heights as in the file.
    EXPECT_NEAR(m->boundsMin().x, -5.0, 1e-6);
    EXPECT_NEAR(m->boundsMax().y, 3.0, 1e-6);
    EXPECT_NEAR(m->boundsMin().z, 34.0, 1e-6);
    EXPECT_NEAR(m->boundsMax().z, 42.0, 1e-6);
    EXPECT_NEAR(m->origin.x, 390005.0, 1e-6);
    // Wall texture coordinates follow the position: u along east, v up.
    for (std::size_t i = 0; i < m->triangles.size(); ++i) {
        const auto& t = m->triangles[i];
        if (m->surface[i] != Surface::Wall) {
            EXPECT_EQ(t.texture, -1);
            continue;
        }
        EXPECT_EQ(t.texture, 0);
        for (int k = 0; k < 3; ++k) {
            EXPECT_NEAR(t.t[std::size_t(k)].x, (t.v[std::size_t(k)].x + 5.0) / 10.0, 1e-5);
            EXPECT_NEAR(t.t[std::size_t(k)].y, (t.v[std::size_t(k)].z - 34.0) / 8.0, 1e-5);
        }
    }
}

// CityGML 1.0 with an LoD1 solid (no thematic surfaces): the box's six faces, walls told from roof and ground by
// their normals, the textured one carrying its appearance.
TEST(CityModelTest, CityGml1Lod1SolidWithAppearance) {
    test::TempDir dir("city_gml1_lod1");
    writePng(dir / "wall.png", 16, 16);
    auto p = [](double x, double y, double h) {
        return std::to_string(390000.0 + x) + " " + std::to_string(5819000.0 + y) + " " + std::to_string(34.0 + h) + " ";
    };
    auto ring = [&](std::initializer_list<std::array<double, 3>> pts) {
        std::string s;
        for (const auto& q : pts) s += p(q[0], q[1], q[2]);
        return s + p(pts.begin()->at(0), pts.begin()->at(1), pts.begin()->at(2));
    };
    const std::string faces =
        polygon("P1", ring({{0, 0, 0}, {10, 0, 0}, {10, 0, 8}, {0, 0, 8}})) +  // south wall (textured)
        polygon("P2", ring({{10, 6, 0}, {0, 6, 0}, {0, 6, 8}, {10, 6, 8}})) +  // north wall
        polygon("P3", ring({{0, 6, 0}, {0, 0, 0}, {0, 0, 8}, {0, 6, 8}})) +    // west wall
        polygon("P4", ring({{10, 0, 0}, {10, 6, 0}, {10, 6, 8}, {10, 0, 8}})) + // east wall
        polygon("P5", ring({{0, 0, 8}, {10, 0, 8}, {10, 6, 8}, {0, 6, 8}})) +  // roof
        polygon("P6", ring({{0, 0, 0}, {0, 6, 0}, {10, 6, 0}, {10, 0, 0}}));   // ground
    writeText(dir / "b.gml", R"(<?xml version="1.0" encoding="UTF-8"?>
<CityModel xmlns="http://www.opengis.net/citygml/1.0" xmlns:gml="http://www.opengis.net/gml"
 xmlns:bldg="http://www.opengis.net/citygml/building/1.0" xmlns:app="http://www.opengis.net/citygml/appearance/1.0">
<gml:boundedBy><gml:Envelope srsName="EPSG:25833" srsDimension="3"><gml:lowerCorner>)" + p(0, 0, 0) +
                                 "</gml:lowerCorner><gml:upperCorner>" + p(10, 6, 8) + R"(</gml:upperCorner></gml:Envelope></gml:boundedBy>
<cityObjectMember><bldg:Building gml:id="B1"><bldg:measuredHeight>8</bldg:measuredHeight>
<bldg:lod1Solid><gml:Solid><gml:exterior><gml:CompositeSurface>)" + faces +
                                 R"(</gml:CompositeSurface></gml:exterior></gml:Solid></bldg:lod1Solid>
<app:appearance><app:Appearance><app:theme>rgbTexture</app:theme><app:surfaceDataMember>
<app:ParameterizedTexture><app:imageURI>wall.png</app:imageURI>
<app:target uri="#P1"><app:TexCoordList><app:textureCoordinates ring="#P1_r">0 0 1 0 1 1 0 1 0 0</app:textureCoordinates>
</app:TexCoordList></app:target></app:ParameterizedTexture></app:surfaceDataMember></app:Appearance></app:appearance>
</bldg:Building></cityObjectMember></CityModel>
)");
    auto m = loadCityModel((dir / "b.gml").string());
    ASSERT_TRUE(m) << m.error().message;
    EXPECT_EQ(m->crs.epsg(), 25833);
    EXPECT_EQ(m->buildingIds, std::vector<std::string>{"B1"});
    EXPECT_EQ(count(*m, Surface::Wall), 8u);
    EXPECT_GE(count(*m, Surface::Roof), 2u);
    ASSERT_EQ(m->textures.size(), 1u);
    std::size_t textured = 0;
    for (std::size_t i = 0; i < m->triangles.size(); ++i) {
        const auto& t = m->triangles[i];
        if (t.texture < 0) continue;
        ++textured;
        EXPECT_EQ(m->surface[i], Surface::Wall);
        for (int k = 0; k < 3; ++k) {
            EXPECT_NEAR(t.t[std::size_t(k)].x, (t.v[std::size_t(k)].x + 5.0) / 10.0, 1e-5); // u along east
            EXPECT_NEAR(t.t[std::size_t(k)].y, (t.v[std::size_t(k)].z - 34.0) / 8.0, 1e-5);  // v up
        }
    }
    EXPECT_EQ(textured, 2u) << "the south wall's two triangles";
}

TEST(CityModelTest, MissingTextureIsAWarningAndTheWallUntextured) {
    test::TempDir dir("city_gml_missing_tex");
    writeText(dir / "b.gml", cityGml("EPSG:25833", "nowhere/wall.jpg"));
    auto m = loadCityModel((dir / "b.gml").string());
    ASSERT_TRUE(m) << m.error().message;
    ASSERT_EQ(m->warnings.size(), 1u);
    EXPECT_NE(m->warnings[0].find("b.gml"), std::string::npos) << m->warnings[0];
    EXPECT_NE(m->warnings[0].find("nowhere/wall.jpg"), std::string::npos) << m->warnings[0];
    EXPECT_TRUE(m->textures.empty());
    EXPECT_EQ(m->texturedTriangles(), 0u);
    EXPECT_EQ(m->triangles.size(), 4u);
}

// A texture that is there but does not read as an image (cut short, or another kind of file under its name) is
// lost data, not a texture the model forgot to ship: the model is refused, naming the texture, in CityGML and OBJ.
TEST(CityModelTest, UnreadableTextureIsAnErrorNamingIt) {
    test::TempDir dir("city_gml_bad_tex");
    writePng(dir / "wall.png", 16, 16);
    const std::string bytes = test::readBytes(dir / "wall.png");
    writeText(dir / "wall.png", bytes.substr(0, 10));
    writeText(dir / "b.gml", cityGml("EPSG:25833", "wall.png"));
    auto m = loadCityModel((dir / "b.gml").string());
    ASSERT_FALSE(m);
    EXPECT_NE(m.error().message.find("wall.png: texture does not read as an image"), std::string::npos)
        << m.error().message;
    EXPECT_EQ(m.error().message.find('\n'), std::string::npos) << m.error().message;
    // The same with an OBJ whose material names a text file as its texture.
    writeText(dir / "notes.png", "not an image at all\n");
    writeText(dir / "c.mtl", "newmtl brick\nmap_Kd notes.png\n");
    writeText(dir / "c.obj", "mtllib c.mtl\nv 0 0 0\nv 4 0 0\nv 4 4 0\nvt 0 0\nvt 1 0\nvt 1 1\nusemtl brick\nf 1/1 2/2 3/3\n");
    CityLoadOptions opts;
    opts.localFrame = true;
    auto o = loadCityModel((dir / "c.obj").string(), opts);
    ASSERT_FALSE(o);
    EXPECT_NE(o.error().message.find("notes.png: texture does not read as an image"), std::string::npos)
        << o.error().message;
}

TEST(CityModelTest, DegenerateAndNonPlanarPolygonsAreWarnedAbout) {
    test::TempDir dir("city_gml_bad_polys");
    writePng(dir / "wall.png", 8, 8);
    const double e = 390000.0, n = 5819000.0;
    auto p = [&](double x, double y, double h) {
        return std::to_string(e + x) + " " + std::to_string(n + y) + " " + std::to_string(34.0 + h) + " ";
    };
    // Three collinear points (no area), and a roof quad with one corner lifted by 1 m.
    const std::string extra = polygon("D1", p(0, 0, 8) + p(5, 0, 8) + p(10, 0, 8) + p(0, 0, 8)) +
                              polygon("N1", p(0, 6, 8) + p(10, 6, 8) + p(10, 12, 9) + p(0, 12, 8) + p(0, 6, 8));
    writeText(dir / "b.gml", cityGml("EPSG:25833", "wall.png", extra));
    auto m = loadCityModel((dir / "b.gml").string());
    ASSERT_TRUE(m) << m.error().message;
    std::string all;
    for (const auto& w : m->warnings) all += w + "\n";
    EXPECT_NE(all.find("1 degenerate polygon"), std::string::npos) << all;
    EXPECT_NE(all.find("1 non-planar polygon"), std::string::npos) << all;
    EXPECT_EQ(m->triangles.size(), 6u); // the non-planar quad is still drawn
}

TEST(CityModelTest, CrsProblemsAreErrors) {
    test::TempDir dir("city_gml_crs");
    writePng(dir / "wall.png", 8, 8);
    // Swiss LV95 (EPSG:2056), which no hand-written table held: PROJ knows it.
    writeText(dir / "swiss.gml", cityGml("urn:ogc:def:crs:EPSG::2056", "wall.png"));
    auto swiss = loadCityModel((dir / "swiss.gml").string());
    ASSERT_TRUE(swiss) << swiss.error().message;
    EXPECT_EQ(swiss->crs.epsg(), 2056);

    writeText(dir / "local.gml", cityGml("urn:x-local:crs", "wall.png"));
    auto local = loadCityModel((dir / "local.gml").string());
    ASSERT_FALSE(local);
    EXPECT_NE(local.error().message.find("unsupported CRS"), std::string::npos) << local.error().message;

    writeText(dir / "none.gml", cityGml("", "wall.png"));
    auto none = loadCityModel((dir / "none.gml").string());
    ASSERT_FALSE(none);
    EXPECT_NE(none.error().message.find("names no CRS"), std::string::npos) << none.error().message;
    CityLoadOptions given;
    given.crs = Crs::utm(33, true);
    auto withCrs = loadCityModel((dir / "none.gml").string(), given);
    ASSERT_TRUE(withCrs) << withCrs.error().message;
    EXPECT_EQ(withCrs->triangles.size(), 4u);
}

TEST(CityModelTest, BrokenFilesAreOneLineErrors) {
    test::TempDir dir("city_gml_broken");
    writePng(dir / "wall.png", 8, 8);
    const std::string full = cityGml("EPSG:25833", "wall.png");
    writeText(dir / "cut.gml", full.substr(0, full.size() / 2));
    writeText(dir / "empty.gml", "");
    writeText(dir / "none.gml", R"(<?xml version="1.0"?><CityModel xmlns="http://www.opengis.net/citygml/2.0"/>)");
    for (const char* f : {"cut.gml", "empty.gml", "none.gml", "missing.gml", "wall.png"}) {
        auto m = loadCityModel((dir / f).string());
        ASSERT_FALSE(m) << f;
        EXPECT_NE(m.error().message.find(f), std::string::npos) << m.error().message;
        EXPECT_EQ(m.error().message.find('\n'), std::string::npos) << m.error().message;
    }
}

TEST(CityModelTest, GeographicCrsIsReadLatitudeFirst) {
    test::TempDir dir("city_gml_geo");
    writePng(dir / "wall.png", 8, 8);
    // PLATEAU style: EPSG:6697, "lat lon h"; a building 10 m (east) × 6 m (north) at 35.5° N.
    const double lat = 35.5, lon = 139.7;
    const Crs geo = *Crs::fromEpsg(6697);
    const GeoFrame metres(geo, glm::dvec2(lon, lat)); // writes the file: metres around (lon, lat) -> lon, lat
    std::string s = cityGml("http://www.opengis.net/def/crs/EPSG/0/6697", "wall.png", "", 0, 0, 3.0);
    // Rewrite "x y" = metres into "lat lon".
    std::string out;
    std::istringstream in(s);
    for (std::string line; std::getline(in, line);) out += line + "\n";
    auto swap = [&](std::string text) {
        std::string r;
        std::size_t pos = 0;
        while (true) {
            const auto a = text.find("<gml:posList srsDimension=\"3\">", pos);
            if (a == std::string::npos) break;
            const auto b = text.find("</gml:posList>", a);
            const auto start = a + std::string("<gml:posList srsDimension=\"3\">").size();
            std::istringstream nums(text.substr(start, b - start));
            std::string conv;
            for (double x, y, h; nums >> x >> y >> h;)
            {
                const glm::dvec2 ll = metres.fromLocal(geo, glm::dvec2(x, y));
                char buf[96];
                std::snprintf(buf, sizeof buf, "%.10f %.10f %.4f ", ll.y, ll.x, h);
                conv += buf;
            }
            r += text.substr(pos, start - pos) + conv;
            pos = b;
        }
        return r + text.substr(pos);
    };
    writeText(dir / "geo.gml", swap(out));
    auto m = loadCityModel((dir / "geo.gml").string());
    ASSERT_TRUE(m) << m.error().message;
    EXPECT_TRUE(m->crs.isGeographic());
    EXPECT_NEAR(m->origin.y, metres.fromLocal(geo, glm::dvec2(5.0, 3.0)).y, 1e-7); // origin is (lon, lat)
    EXPECT_NEAR(m->origin.x, metres.fromLocal(geo, glm::dvec2(5.0, 3.0)).x, 1e-7);
    const glm::dvec3 size = m->boundsMax() - m->boundsMin();
    EXPECT_NEAR(size.x, 10.0, 0.05);
    EXPECT_NEAR(size.y, 6.0, 0.05);
    EXPECT_NEAR(size.z, 8.0, 0.05);
}

TEST(CityModelTest, ObjWithMaterialTextures) {
    test::TempDir dir("city_obj");
    writePng(dir / "brick.png", 8, 8);
    // A 4 m cube, y up, two objects: the first textured on its south face (-z in OBJ = south... +z is south).
    writeText(dir / "c.mtl", "newmtl brick\nmap_Kd brick.png\nnewmtl gone\nmap_Kd gone.png\n");
    writeText(dir / "c.obj", R"(mtllib c.mtl
v 0 0 0
v 4 0 0
v 4 4 0
v 0 4 0
v 0 4 -4
v 4 4 -4
vt 0 0
vt 1 0
vt 1 1
vt 0 1
o house
usemtl brick
f 1/1 2/2 3/3 4/4
usemtl gone
f 4/1 3/2 6/3 5/4
o shed
f 1 2 1
)");
    CityLoadOptions opts;
    opts.localFrame = true;
    auto m = loadCityModel((dir / "c.obj").string(), opts);
    ASSERT_TRUE(m) << m.error().message;
    EXPECT_EQ(m->buildingIds.size(), 2u);
    ASSERT_EQ(m->triangles.size(), 4u);
    EXPECT_EQ(count(*m, Surface::Wall), 2u); // the quad at OBJ z = 0 (y up) faces +z = south
    EXPECT_EQ(count(*m, Surface::Roof), 2u); // the quad at y = 4 faces up
    EXPECT_EQ(m->texturedTriangles(), 2u);
    std::string all;
    for (const auto& w : m->warnings) all += w + "\n";
    EXPECT_NE(all.find("gone.png"), std::string::npos) << all;
    EXPECT_NE(all.find("1 degenerate polygon"), std::string::npos) << all;
    EXPECT_NEAR(m->boundsMax().z, 4.0, 1e-9);
    EXPECT_NEAR(m->boundsMin().y, 0.0, 1e-9);  // OBJ z = 0 .. -4 -> north 0 .. 4
    EXPECT_NEAR(m->boundsMax().y, 4.0, 1e-9);

    auto noCrs = loadCityModel((dir / "c.obj").string());
    ASSERT_FALSE(noCrs);
    EXPECT_NE(noCrs.error().message.find("no CRS"), std::string::npos);
}

TEST(CityModelTest, PlaceOnTerrainAndReframe) {
    test::TempDir dir("city_place");
    writePng(dir / "wall.png", 8, 8);
    writeText(dir / "b.gml", cityGml("EPSG:25833", "wall.png"));
    auto m = loadCityModel((dir / "b.gml").string());
    ASSERT_TRUE(m) << m.error().message;
    // Terrain rising 1 m per metre eastwards from 100 m: the lowest ground under the building is at x = -5.
    const double shift = placeOnTerrain(*m, [](double x, double) { return 100.0 + x; });
    EXPECT_NEAR(m->boundsMin().z, 95.0, 1e-9);
    EXPECT_NEAR(shift, 61.0, 1e-9);
    const glm::dvec3 before = m->triangles[0].v[0];
    reframe(*m, m->crs, m->origin + glm::dvec2(100.0, -50.0));
    EXPECT_NEAR(m->triangles[0].v[0].x, before.x - 100.0, 1e-9);
    EXPECT_NEAR(m->triangles[0].v[0].y, before.y + 50.0, 1e-9);
    // Into a neighbouring UTM zone and back: the same points to a millimetre.
    const Crs ownCrs = m->crs;
    const glm::dvec2 ownOrigin = m->origin;
    reframe(*m, Crs::utm(32, true), convert(ownCrs, Crs::utm(32, true), ownOrigin));
    reframe(*m, ownCrs, ownOrigin);
    EXPECT_NEAR(m->triangles[0].v[0].x, before.x - 100.0, 1e-3);
    EXPECT_NEAR(m->triangles[0].v[0].y, before.y + 50.0, 1e-3);
}

TEST(CityModelTest, RealBerlinAndTokyoModels) {
    const auto data = test::realDataDir();
    if (!data || !std::filesystem::exists(*data / "city/berlin_lod2/berlin_lod2.gml"))
        GTEST_SKIP() << "real data not found (../shared/data or SEASONVIEW_DATA): city/berlin_lod2";
    auto berlin = loadCityModel((*data / "city/berlin_lod2/berlin_lod2.gml").string());
    ASSERT_TRUE(berlin) << berlin.error().message;
    EXPECT_EQ(berlin->crs.epsg(), 25833);
    EXPECT_EQ(berlin->buildingIds.size(), 5u);
    EXPECT_EQ(berlin->textures.size(), 108u);
    // Every wall and roof has its photo (the ground surfaces have none).
    EXPECT_EQ(berlin->texturedTriangles(), count(*berlin, Surface::Wall) + count(*berlin, Surface::Roof));
    EXPECT_GT(count(*berlin, Surface::Roof), 0u);
    EXPECT_GT(count(*berlin, Surface::Wall), 0u);
    const glm::dvec3 size = berlin->boundsMax() - berlin->boundsMin();
    EXPECT_GT(size.x, 5.0);
    EXPECT_LT(size.x, 500.0);
    EXPECT_LT(size.z, 60.0);
    for (const auto& w : berlin->warnings) std::cout << "  berlin: " << w << "\n";

    auto tokyo = loadCityModel((*data / "city/plateau_ota/53392642_bldg_6697_op2.gml").string());
    ASSERT_TRUE(tokyo) << tokyo.error().message;
    EXPECT_TRUE(tokyo->crs.isGeographic());
    EXPECT_EQ(tokyo->buildingIds.size(), 8u);
    EXPECT_EQ(tokyo->textures.size(), 8u);
    EXPECT_GE(tokyo->texturedTriangles(), count(*tokyo, Surface::Wall) + count(*tokyo, Surface::Roof));
    const glm::dvec3 tsize = tokyo->boundsMax() - tokyo->boundsMin();
    EXPECT_GT(tsize.x, 10.0);
    EXPECT_LT(tsize.x, 2000.0);
    EXPECT_LT(tsize.z, 200.0);
    for (const auto& w : tokyo->warnings) std::cout << "  tokyo: " << w << "\n";
}

TEST(CityModelTest, SyntheticSceneCityMatchesItsBuildings) {
    test::TempDir dir("city_synth");
    SynthOptions o;
    o.sizeM = 512.0;
    o.gsd = 1.0;
    o.seed = 1;
    o.facadeSize = 64;
    auto report = generateSyntheticScene(o, dir.path());
    ASSERT_TRUE(report) << report.message();
    ASSERT_GT(report->buildings, 0u);
    auto sources = parseManifest(dir / "scene.json");
    ASSERT_TRUE(sources) << sources.message();
    EXPECT_EQ(sources->buildings, dir / "city/city.obj");
    CityLoadOptions opts;
    opts.localFrame = true;
    auto m = loadCityModel(sources->buildings.string(), opts);
    ASSERT_TRUE(m) << m.error().message;
    EXPECT_TRUE(m->warnings.empty()) << m->warnings.front();
    EXPECT_EQ(m->buildingIds.size(), report->buildings);
    EXPECT_EQ(m->textures.size(), report->buildings); // one unique facade texture per building
    for (std::size_t i = 0; i < m->triangles.size(); ++i) {
        if (m->surface[i] == Surface::Wall) {
            EXPECT_GE(m->triangles[i].texture, 0);
        }
        if (m->surface[i] == Surface::Roof) {
            EXPECT_EQ(m->triangles[i].texture, -1);
        }
    }
    EXPECT_GT(count(*m, Surface::Roof), 0u);
    // Every building stands on the DEM: its lowest vertex half a metre below the lowest ground under it.
    auto scene = loadScene(*sources, dir / "cache");
    ASSERT_TRUE(scene) << scene.message();
    std::vector<double> lowest(m->buildingIds.size(), 1e30), ground(m->buildingIds.size(), 1e30);
    for (std::size_t i = 0; i < m->triangles.size(); ++i)
        for (const auto& v : m->triangles[i].v) {
            lowest[m->building[i]] = std::min(lowest[m->building[i]], v.z);
            if (m->surface[i] == Surface::Wall) ground[m->building[i]] = std::min(ground[m->building[i]], scene->terrainHeight(v.x, v.y));
        }
    for (std::size_t b = 0; b < lowest.size(); ++b) EXPECT_NEAR(lowest[b], ground[b] - 0.5, 0.3) << "building " << b;

    // The footprints are where the imagery drew the roofs. Along each building's outline (its walls' bases) and
    // along copies of it moved inwards or outwards by up to 3 m, the mean leaf-off colour gradient peaks on the
    // outline itself (±0.5 m: a pixel, or an eave) for most buildings: the roof's edge is there. (The other peaks
    // are gable ridges, solar panels, shadows.) A model misplaced by 1 m keeps about a third of the peaks there.
    // A larger scene for more buildings: 1 km at 0.5 m (a village and farms; seed 3).
    test::TempDir big("city_synth_big");
    SynthOptions ob = o;
    ob.sizeM = 1024.0;
    ob.gsd = 0.5;
    ob.seed = 3;
    ob.facadeSize = 16;
    ASSERT_TRUE(generateSyntheticScene(ob, big.path()));
    CityLoadOptions lo;
    lo.localFrame = true;
    auto bm = loadCityModel((big / "city/city.obj").string(), lo);
    ASSERT_TRUE(bm) << bm.error().message;
    auto img = readImageU8(big / "leafoff.tif", 3);
    ASSERT_TRUE(img.ok());
    const double half = ob.sizeM / 2.0;
    auto colour = [&](glm::dvec2 p, glm::dvec3& c) {
        const int col = int(std::floor((p.x + half) / ob.gsd)), row = int(std::floor((half - p.y) / ob.gsd));
        if (col < 0 || row < 0 || col >= img->width || row >= img->height) return false;
        for (int k = 0; k < 3; ++k) c[k] = img->pixels[(std::size_t(row) * std::size_t(img->width) + std::size_t(col)) * 3 + std::size_t(k)];
        return true;
    };
    std::vector<std::vector<std::array<glm::dvec2, 2>>> outline(bm->buildingIds.size());
    std::vector<glm::dvec2> centre(bm->buildingIds.size(), glm::dvec2(0.0));
    std::vector<double> corners(bm->buildingIds.size(), 0.0);
    for (std::size_t i = 0; i < bm->triangles.size(); ++i) {
        const auto& v = bm->triangles[i].v;
        for (const auto& p : v) {
            centre[bm->building[i]] += glm::dvec2(p);
            corners[bm->building[i]] += 1.0;
        }
        if (bm->surface[i] != Surface::Wall) continue;
        std::vector<glm::dvec2> xy;
        for (const auto& p : v)
            if (std::none_of(xy.begin(), xy.end(), [&](glm::dvec2 q) { return glm::length(q - glm::dvec2(p)) < 1e-6; }))
                xy.push_back(glm::dvec2(p));
        if (xy.size() == 2) outline[bm->building[i]].push_back({xy[0], xy[1]});
    }
    auto gradient = [&](glm::dvec2 p, double& g) {
        glm::dvec3 e, w, n, so;
        const double d = ob.gsd;
        if (!colour(p + glm::dvec2(d, 0), e) || !colour(p - glm::dvec2(d, 0), w) || !colour(p + glm::dvec2(0, d), n) ||
            !colour(p - glm::dvec2(0, d), so))
            return false;
        const glm::dvec3 gx = glm::abs(e - w), gy = glm::abs(n - so);
        g = gx.r + gx.g + gx.b + gy.r + gy.g + gy.b;
        return true;
    };
    // Mean gradient along building b's outline moved `offset` metres outwards.
    auto edge = [&](std::size_t b, double offset) {
        const glm::dvec2 c = centre[b] / corners[b];
        double sum = 0.0;
        int n = 0;
        for (const auto& [a0, a1] : outline[b]) {
            const double len = glm::length(a1 - a0);
            const glm::dvec2 along = (a1 - a0) / len;
            glm::dvec2 normal(along.y, -along.x);
            if (glm::dot(normal, 0.5 * (a0 + a1) - c) < 0.0) normal = -normal;
            for (double t = 0.5; t < len - 0.5; t += 0.5) {
                double g = 0.0;
                if (gradient(a0 + along * t + normal * offset, g)) {
                    sum += g;
                    ++n;
                }
            }
        }
        return n > 0 ? sum / n : -1.0;
    };
    std::size_t measured = 0, onOutline = 0;
    for (std::size_t b = 0; b < outline.size(); ++b) {
        if (outline[b].empty() || edge(b, 0.0) < 0.0) continue;
        double best = -1.0, at = 0.0;
        for (int k = -12; k <= 12; ++k)
            if (const double e = edge(b, 0.25 * k); e > best) {
                best = e;
                at = 0.25 * k;
            }
        ++measured;
        onOutline += std::abs(at) <= 0.5;
    }
    ASSERT_GT(measured, 50u);
    std::cout << "  " << onOutline << " of " << measured << " buildings: the imagery's strongest edge on the outline\n";
    EXPECT_GE(double(onOutline), 0.75 * double(measured)); // 71 of 83 measured

    // Deterministic: the same options write the same model.
    test::TempDir again("city_synth_again");
    ASSERT_TRUE(generateSyntheticScene(o, again.path()));
    EXPECT_EQ(test::readBytes(dir / "city/city.obj"), test::readBytes(again / "city/city.obj"));
    EXPECT_EQ(test::readBytes(dir / "city/facades/b0.jpg"), test::readBytes(again / "city/facades/b0.jpg"));
}

TEST(CityModelTest, ObjPolygonsAreCheckedWholeAndEarClipped) {
    test::TempDir dir("city_obj_poly");
    // One L-shaped wall (concave, 6 vertices, listed from a vertex whose fan would leave the outline) and one
    // quad with a corner 0.5 m off its plane, z up.
    writeText(dir / "p.obj", R"(v 2 0 4
v 0 0 4
v 0 0 0
v 4 0 0
v 4 0 1
v 2 0 1
v 10 0 0
v 14 0 0
v 14 0 4
v 10 0.5 4
o l
f 1 2 3 4 5 6
o bent
f 7 8 9 10
)");
    CityLoadOptions opts;
    opts.localFrame = true;
    opts.objUp = 'z';
    auto m = loadCityModel((dir / "p.obj").string(), opts);
    ASSERT_TRUE(m) << m.error().message;
    double lArea = 0.0;
    std::size_t lTris = 0;
    for (std::size_t i = 0; i < m->triangles.size(); ++i)
        if (m->building[i] == 0) {
            lArea += triangleArea(m->triangles[i]);
            ++lTris;
            // Every triangle lies inside the L (its centroid is not in the notch x > 2, z > 1).
            const glm::dvec3 c = (m->triangles[i].v[0] + m->triangles[i].v[1] + m->triangles[i].v[2]) / 3.0;
            EXPECT_FALSE(c.x > 2.0 && c.z > 1.0) << "triangle " << i << " fills the notch";
        }
    EXPECT_EQ(lTris, 4u);
    EXPECT_NEAR(lArea, 2.0 * 4.0 + 2.0 * 1.0, 1e-9); // 8 + 2 m²
    std::string all;
    for (const auto& w : m->warnings) all += w + "\n";
    EXPECT_NE(all.find("1 non-planar polygon"), std::string::npos) << all;
}

TEST(CityModelTest, TriangulatePolygonHandlesConvexConcaveAndDegenerate) {
    using seasonview::city::detail::triangulatePolygon;
    EXPECT_TRUE(triangulatePolygon({glm::dvec3(0, 0, 0), glm::dvec3(1, 0, 0)}).empty());
    const auto quad = triangulatePolygon({glm::dvec3(0, 0, 0), glm::dvec3(1, 0, 0), glm::dvec3(1, 1, 0), glm::dvec3(0, 1, 0)});
    EXPECT_EQ(quad.size(), 6u);
    // Clockwise (seen from +z) concave arrow: still 3 triangles covering its area.
    const std::vector<glm::dvec3> arrow = {glm::dvec3(0, 0, 0), glm::dvec3(1, 3, 0), glm::dvec3(2, 0, 0), glm::dvec3(1, 1, 0)};
    const auto t = triangulatePolygon(arrow);
    ASSERT_EQ(t.size(), 6u);
    double area = 0.0;
    for (std::size_t i = 0; i < t.size(); i += 3) {
        TexturedTriangle tri;
        tri.v = {arrow[t[i]], arrow[t[i + 1]], arrow[t[i + 2]]};
        area += triangleArea(tri);
    }
    EXPECT_NEAR(area, 2.0, 1e-12); // 3 - 1
}

TEST(CityModelTest, ModelsInNationalGridsLandWhereTheyAreInAUtmScene) {
    // A building near Bern whose corner is at a known spot of a UTM 32N scene, written in Swiss LV95 (EPSG:2056,
    // which no hand-written table held) as CityGML and as an OBJ given that CRS: reframed into the scene, the corner
    // is where it was put, to a centimetre.
    test::TempDir dir("city_lv95");
    writePng(dir / "wall.png", 8, 8);
    const Crs utm = Crs::utm(32, true), lv95 = *Crs::fromEpsg(2056);
    const glm::dvec2 sceneCentre = glm::round(convert(Crs::geographic(), utm, {7.44, 46.95}));
    const glm::dvec2 corner = convert(utm, lv95, sceneCentre + glm::dvec2(30.0, -40.0)); // local (30, -40)
    writeText(dir / "b.gml", cityGml("urn:ogc:def:crs:EPSG::2056", "wall.png", "", corner.x, corner.y));
    auto gml = loadCityModel((dir / "b.gml").string());
    ASSERT_TRUE(gml) << gml.error().message;
    // The OBJ: the same corner and the building's far corner, y up (OBJ's convention): x = east, z = -north.
    writeText(dir / "b.obj", "v " + std::to_string(corner.x) + " 34 " + std::to_string(-corner.y) + "\nv " +
                                 std::to_string(corner.x + 10) + " 34 " + std::to_string(-corner.y) + "\nv " +
                                 std::to_string(corner.x + 10) + " 42 " + std::to_string(-corner.y) + "\nf 1 2 3\n");
    CityLoadOptions o;
    o.crs = *crsFromSrsName("EPSG:2056");
    auto obj = loadCityModel((dir / "b.obj").string(), o);
    ASSERT_TRUE(obj) << obj.error().message;
    for (CityModel* m : {&*gml, &*obj}) {
        reframe(*m, utm, sceneCentre);
        double best = 1e9;
        for (const auto& t : m->triangles)
            for (const auto& v : t.v) best = std::min(best, glm::length(glm::dvec2(v.x, v.y) - glm::dvec2(30.0, -40.0)));
        EXPECT_LT(best, 0.01) << m->source;
    }
}
