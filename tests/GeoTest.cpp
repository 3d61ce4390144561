#include "Crs.h"
#include "GeoFrame.h"

#include <gtest/gtest.h>

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

TEST(GeoTest, EpsgCodes) {
    EXPECT_TRUE(Crs::fromEpsg(4326)->isGeographic());
    EXPECT_TRUE(Crs::fromEpsg(6697)->isGeographic());
    auto u = Crs::fromEpsg(32617);
    ASSERT_TRUE(u.ok());
    EXPECT_EQ(u->zone, 17);
    EXPECT_TRUE(u->north);
    auto s = Crs::fromEpsg(32733);
    ASSERT_TRUE(s.ok());
    EXPECT_FALSE(s->north);
    auto e = Crs::fromEpsg(25833);
    ASSERT_TRUE(e.ok());
    EXPECT_EQ(e->zone, 33);
    EXPECT_EQ(e->epsg, 25833);
    auto bad = Crs::fromEpsg(3857);
    ASSERT_FALSE(bad.ok());
    EXPECT_NE(bad.message().find("EPSG:3857"), std::string::npos);
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
