#include "Crs.h"
#include "GeoFrame.h"

#include <gtest/gtest.h>
#include <ogr_spatialref.h>

#include <cmath>
#include <vector>

using namespace seasonview;

TEST(GeoTest, MuensterToUtm32NMatchesKnownValue) {
    // Known value measured with GeographicLib (shared/PLATFORM.md): 51.96 N, 7.62 E.
    const glm::dvec2 utm = convert(Crs::geographic(), Crs::utm(32, true), {7.62, 51.96});
    EXPECT_NEAR(utm.x, 405180.030, 1e-3);
    EXPECT_NEAR(utm.y, 5757488.725, 1e-3);
    const glm::dvec2 back = convert(Crs::utm(32, true), Crs::geographic(), utm);
    EXPECT_NEAR(back.x, 7.62, 1e-9);
    EXPECT_NEAR(back.y, 51.96, 1e-9);
}

TEST(GeoTest, ForcedZoneAcrossZones) {
    // A point of zone 33 expressed in zone 32 (scenes straddling a zone edge stay in the scene's zone).
    const glm::dvec2 p33 = convert(Crs::geographic(), Crs::utm(33, true), {12.5, 52.5});
    const glm::dvec2 p32 = convert(Crs::utm(33, true), Crs::utm(32, true), p33);
    EXPECT_GT(p32.x, 700000.0);
    const glm::dvec2 lonlat = convert(Crs::utm(32, true), Crs::geographic(), p32);
    EXPECT_NEAR(lonlat.x, 12.5, 1e-8);
    EXPECT_NEAR(lonlat.y, 52.5, 1e-8);
}

TEST(GeoTest, AnyCrsProjKnows) {
    EXPECT_TRUE(Crs::fromEpsg(4326)->isGeographic());
    EXPECT_TRUE(Crs::fromEpsg(6697)->isGeographic()); // JGD2011 + height: the horizontal part
    EXPECT_EQ(Crs::utm(17, true).epsg(), 32617);
    EXPECT_EQ(Crs::utm(33, false).epsg(), 32733);
    // National grids and Web Mercator, by every spelling users and files have.
    for (const char* text : {"EPSG:2154", "epsg:2154", "urn:ogc:def:crs:EPSG::2154",
                             "http://www.opengis.net/def/crs/EPSG/0/2154"}) {
        auto c = Crs::fromUserInput(text);
        ASSERT_TRUE(c.ok()) << text << ": " << c.message();
        EXPECT_EQ(c->epsg(), 2154) << text;
        EXPECT_EQ(*c, *Crs::fromEpsg(2154)) << text;
        EXPECT_FALSE(c->isGeographic());
    }
    for (int code : {3857, 28992, 2056, 27700, 25833, 2263}) {
        auto c = Crs::fromEpsg(code);
        ASSERT_TRUE(c.ok()) << code << ": " << c.message();
        EXPECT_EQ(c->epsg(), code);
        EXPECT_NE(c->name().find("EPSG:" + std::to_string(code)), std::string::npos) << c->name();
    }
    EXPECT_NEAR(Crs::fromEpsg(2263)->metresPerUnit(), 0.3048006, 1e-6); // New York Long Island, US survey feet
    // A WKT without its authority (as many GeoTIFFs carry it) is the same CRS.
    OGRSpatialReference l93;
    l93.importFromEPSG(2154);
    l93.StripTOWGS84IfKnownDatumAndAllowed();
    char* wkt = nullptr;
    l93.exportToWkt(&wkt);
    std::string text(wkt);
    CPLFree(wkt);
    text = text.substr(0, text.rfind(",AUTHORITY")) + "]";
    auto fromWkt = Crs::fromWkt(text);
    ASSERT_TRUE(fromWkt.ok()) << fromWkt.message();
    EXPECT_EQ(*fromWkt, *Crs::fromEpsg(2154));
    auto bad = Crs::fromUserInput("EPSG:999999");
    ASSERT_FALSE(bad.ok());
    EXPECT_NE(bad.message().find("EPSG:999999"), std::string::npos) << bad.message();
    EXPECT_FALSE(Crs::fromUserInput("not a crs").ok());
}

TEST(GeoTest, NationalGridsAgreeWithKnownCoordinates) {
    // Points whose coordinates the national agencies publish (to the centimetre).
    // Amersfoort, the RD New origin: 155000, 463000 at 52.15517440 N, 5.38720621 E.
    glm::dvec2 rd = convert(Crs::geographic(), *Crs::fromEpsg(28992), {5.38720621, 52.15517440});
    EXPECT_NEAR(rd.x, 155000.0, 1.5); // WGS 84 vs Bessel/Amersfoort: PROJ's datum shift, about a metre
    EXPECT_NEAR(rd.y, 463000.0, 1.5);
    // Lambert-93's false origin: 3° E, 46.5° N -> 700000, 6600000 (RGF93 = WGS 84 here).
    glm::dvec2 l93 = convert(Crs::geographic(), *Crs::fromEpsg(2154), {3.0, 46.5});
    EXPECT_NEAR(l93.x, 700000.0, 0.01);
    EXPECT_NEAR(l93.y, 6600000.0, 0.01);
    // LV95's origin, the old observatory of Bern: 2600000, 1200000 at 7.43863263 E, 46.95108028 N (CH1903+).
    glm::dvec2 ch = convert(Crs::geographic(), *Crs::fromEpsg(2056), {7.43863263, 46.95108028});
    EXPECT_NEAR(ch.x, 2600000.0, 3.0); // CH1903+ vs WGS 84: PROJ's datum shift, a few metres
    EXPECT_NEAR(ch.y, 1200000.0, 3.0);
    // Web Mercator: the equator and Greenwich at 0, 0; scale 1 / cos(latitude).
    const Crs merc = *Crs::fromEpsg(3857);
    const glm::dvec2 m = convert(Crs::geographic(), merc, {2.18, 48.70});
    const glm::dvec2 k = pointScale(merc, m);
    EXPECT_NEAR(k.x, 1.0 / std::cos(48.70 * 3.14159265358979 / 180.0), 0.01);
    EXPECT_FALSE(isMetricAt(merc, m));
    EXPECT_TRUE(isMetricAt(*Crs::fromEpsg(2154), l93));
    EXPECT_TRUE(isMetricAt(Crs::utm(32, true), {405000, 5757000}));
}

TEST(GeoTest, BatchConversionMatchesSinglePoints) {
    const Crs utm = Crs::utm(31, true), l93 = *Crs::fromEpsg(2154);
    std::vector<glm::dvec2> pts;
    for (int i = 0; i < 50; ++i) pts.push_back({430000.0 + 100.0 * i, 5395000.0 - 70.0 * i});
    std::vector<glm::dvec2> batch = pts;
    convert(utm, l93, std::span<glm::dvec2>(batch));
    for (size_t i = 0; i < pts.size(); ++i) {
        const glm::dvec2 one = convert(utm, l93, pts[i]);
        EXPECT_EQ(one, batch[i]);
        const glm::dvec2 back = convert(l93, utm, one);
        EXPECT_NEAR(back.x, pts[i].x, 1e-6);
        EXPECT_NEAR(back.y, pts[i].y, 1e-6);
    }
}

TEST(GeoTest, WebMercatorFrameIsATangentPlane) {
    // Web Mercator metres are 1.51 ground metres apart at Saclay: the frame goes through geographic coordinates.
    const Crs merc = *Crs::fromEpsg(3857);
    const glm::dvec2 c = convert(Crs::geographic(), merc, {2.18, 48.70});
    GeoFrame f(merc, c);
    EXPECT_FALSE(f.isTranslation());
    const glm::dvec3 p = f.toLocal(merc, c + glm::dvec2(151.0, 0.0));
    EXPECT_NEAR(p.x, 151.0 * std::cos(48.70 * 3.14159265358979 / 180.0), 0.3);
    const glm::dvec2 back = f.fromLocal(merc, glm::dvec2(p));
    EXPECT_NEAR(back.x, c.x + 151.0, 1e-6);
    EXPECT_NEAR(back.y, c.y, 1e-6);
    GeoFrame l(*Crs::fromEpsg(2154), convert(Crs::geographic(), *Crs::fromEpsg(2154), {2.18, 48.70}));
    EXPECT_TRUE(l.isTranslation());
}

TEST(GeoTest, UtmFrameIsATranslation) {
    const Crs utm = Crs::utm(32, true);
    GeoFrame f(utm, {405000, 5757000});
    const glm::dvec3 p = f.toLocal(utm, {405010, 5756990}, 55);
    EXPECT_DOUBLE_EQ(p.x, 10);
    EXPECT_DOUBLE_EQ(p.y, -10);
    EXPECT_DOUBLE_EQ(p.z, 55);
    const glm::dvec2 q = f.fromLocal(utm, {10, -10});
    EXPECT_DOUBLE_EQ(q.x, 405010);
    EXPECT_DOUBLE_EQ(q.y, 5756990);
    // A geographic point lands where GeographicLib's UTM puts it.
    const glm::dvec3 m = f.toLocal(Crs::geographic(), {7.62, 51.96});
    EXPECT_NEAR(m.x, 180.030, 1e-3);
    EXPECT_NEAR(m.y, 488.725, 1e-3);
}

TEST(GeoTest, LocalCartesianFrameForGeographicData) {
    const Crs geo = Crs::geographic();
    GeoFrame f(geo, {2.15, 48.72}); // Saclay
    const glm::dvec3 c = f.toLocal(geo, {2.15, 48.72});
    EXPECT_NEAR(c.x, 0, 1e-6);
    EXPECT_NEAR(c.y, 0, 1e-6);
    // 0.001 degrees of latitude is about 111 m north.
    const glm::dvec3 n = f.toLocal(geo, {2.15, 48.721});
    EXPECT_NEAR(n.x, 0, 1e-6);
    EXPECT_NEAR(n.y, 111.2, 0.3);
    const glm::dvec3 e = f.toLocal(geo, {2.151, 48.72});
    EXPECT_NEAR(e.x, 73.6, 0.3); // 111.3 km * cos(48.72)
    const glm::dvec2 back = f.fromLocal(geo, {e.x, e.y});
    EXPECT_NEAR(back.x, 2.151, 1e-9);
    EXPECT_NEAR(back.y, 48.72, 1e-9);
    EXPECT_NEAR(f.centreLatLon().x, 48.72, 1e-12);
}
