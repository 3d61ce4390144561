// Settlement step of the synthetic scene: houses, farmsteads, a sports ground, a park, a parking lot, traffic.
#include "SynthObjects.h"
#include "SynthRandom.h"

#include <glm/geometric.hpp>

#include <cmath>
#include <vector>

namespace seasonview::synth {

namespace {

constexpr float kPi = 3.14159265358979f;

struct RoadEdge {
    int edge = -1;
    glm::vec2 a{0.0f}, t{1.0f, 0.0f}, in{0.0f, 1.0f}; // start, unit direction, inward normal
    float length = 0.0f, roadHalf = 0.0f, verge = 0.0f;
};

// The parcel's longest edge lying on a road of one of the given kinds.
RoadEdge longestRoadEdge(const Layout& l, const Parcel& p, bool tracksToo) {
    RoadEdge best;
    for (size_t i = 0; i < p.poly.size(); ++i) {
        if (p.edgeCut[i] < 0) continue;
        const Cut& c = l.cuts[size_t(p.edgeCut[i])];
        const bool ok = c.kind == CutKind::Street || c.kind == CutKind::MainRoad || (tracksToo && c.kind == CutKind::Track);
        const glm::vec2 a = p.poly[i], b = p.poly[(i + 1) % p.poly.size()];
        const float len = glm::length(b - a);
        if (!ok || len <= best.length) continue;
        best.edge = int(i);
        best.a = a;
        best.t = (b - a) / len;
        best.in = perpLeft(best.t);
        best.length = len;
        best.roadHalf = c.roadHalf;
        best.verge = std::max(0.0f, c.marginHalf - c.roadHalf);
    }
    return best;
}

// Whether an oriented rectangle keeps clear of the river and its bank.
bool clearOfWater(const Layout& l, glm::vec2 c, glm::vec2 axis, glm::vec2 half) {
    const glm::vec2 across = perpLeft(axis);
    const float limit = l.river.halfWidth + l.river.bankWidth + 1.0f;
    for (int i = -1; i <= 1; ++i)
        for (int j = -1; j <= 1; ++j)
            if (l.river.distance(c + axis * (half.x * float(i)) + across * (half.y * float(j)), limit) < limit) return false;
    return true;
}

bool fits(const Layout& l, const Parcel& p, glm::vec2 c, glm::vec2 axis, glm::vec2 half, float inset) {
    return rectInside(p.poly, c, axis, half, inset) && clearOfWater(l, c, axis, half);
}

void addFeature(Layout& l, Parcel& p, Feature::Shape shape, glm::vec2 c, glm::vec2 axis, glm::vec2 half, Ground cls,
                std::uint8_t variant, std::uint32_t seed) {
    Feature f;
    f.shape = shape;
    f.centre = c;
    f.axis = axis;
    f.half = half;
    f.record = l.addRecord({cls, variant, c, axis, half, seed});
    p.features.push_back(f);
}

CarColour randomCarColour(Rng& rng, bool oneSeason) {
    // Green cars only among the cars present in one season: Ropinski 2007 §4.1's "green cars ... present in the
    // summer texture but not in the winter texture".
    if (oneSeason && rng.chance(0.14)) return rng.chance(0.5) ? CarColour::DarkGreen : CarColour::BrightGreen;
    static constexpr CarColour common[] = {CarColour::White, CarColour::White, CarColour::Black, CarColour::Black,
                                           CarColour::Silver, CarColour::Silver, CarColour::Grey, CarColour::Grey,
                                           CarColour::Blue, CarColour::Red, CarColour::Beige};
    return common[rng.index(int(std::size(common)))];
}

void addCar(Objects& o, Rng& rng, glm::vec2 c, glm::vec2 axis, double pBoth) {
    Car car;
    car.centre = c;
    car.axis = rng.chance(0.5) ? axis : -axis;
    const double r = rng.uniform();
    car.seasons = r < pBoth ? 3 : (r < pBoth + (1.0 - pBoth) * 0.5 ? 1 : 2);
    car.colour = randomCarColour(rng, car.seasons != 3);
    car.seed = static_cast<std::uint32_t>(rng.next());
    o.cars.push_back(car);
}

Building makeBuilding(Rng& rng, glm::vec2 c, glm::vec2 axis, glm::vec2 half, Roof roof, float eave, float pitchDeg) {
    Building b;
    b.centre = c;
    b.axis = axis;
    b.half = half;
    b.roof = roof;
    b.eave = eave;
    b.ridge = roof == Roof::Flat ? eave : eave + half.y * std::tan(pitchDeg * kPi / 180.0f);
    b.seed = static_cast<std::uint32_t>(rng.next());
    return b;
}

RoofMaterial houseRoofMaterial(Rng& rng) {
    const double r = rng.uniform();
    return r < 0.38 ? RoofMaterial::RedTile : r < 0.58 ? RoofMaterial::BrownTile : r < 0.88 ? RoofMaterial::Anthracite
                                                                                             : RoofMaterial::GreyTile;
}

void placeHouse(Layout& l, Parcel& p, Objects& o, Rng& rng) {
    const RoadEdge e = longestRoadEdge(l, p, false);
    if (e.edge < 0 || e.length < 12.0f) return;
    const float setback = e.roadHalf + e.verge + rng.uniformf(3.0f, 7.0f);
    const float len0 = rng.uniformf(9.0f, 15.0f), depth0 = rng.uniformf(8.0f, 11.5f);
    const float along = rng.uniformf(0.3f, 0.7f) * e.length;
    const float side = rng.chance(0.5) ? 1.0f : -1.0f;
    for (int attempt = 0; attempt < 4; ++attempt) {
        const float s = 1.0f - 0.14f * float(attempt);
        const float len = len0 * s, depth = depth0 * s;
        const glm::vec2 c = e.a + e.t * along + e.in * (setback + 0.5f * depth);
        if (!fits(l, p, c, e.t, glm::vec2(0.5f * len, 0.5f * depth), 1.0f)) continue;

        const double kind = rng.uniform();
        const Roof roof = kind < 0.64 ? Roof::Gable : kind < 0.9 ? Roof::Hip : Roof::Flat;
        const bool gableToStreet = roof == Roof::Gable && rng.chance(0.25);
        const glm::vec2 axis = gableToStreet ? e.in : e.t;
        const glm::vec2 half = gableToStreet ? glm::vec2(0.5f * depth, 0.5f * len) : glm::vec2(0.5f * len, 0.5f * depth);
        Building b = makeBuilding(rng, c, axis, half, roof, rng.uniformf(3.0f, 6.2f), rng.uniformf(32.0f, 48.0f));
        b.material = roof == Roof::Flat ? (rng.chance(0.5) ? RoofMaterial::Gravel : RoofMaterial::Bitumen)
                                        : houseRoofMaterial(rng);
        b.greenLeafOnOnly = rng.chance(0.04);
        b.solar = roof != Roof::Flat && rng.chance(0.22);
        o.buildings.push_back(b);

        // Garage beside the house and a driveway from the street to it (or to the house front).
        const glm::vec2 sideC = c + e.t * (side * (0.5f * len + 2.2f));
        const float streetEdge = e.roadHalf;
        float driveEnd = setback + 1.5f;
        const glm::vec2 garageC = sideC + e.in * (3.2f - 0.5f * depth); // front aligned with the house front
        if (rng.chance(0.45) && fits(l, p, garageC, e.in, glm::vec2(3.2f, 1.6f), 0.3f)) {
            Building g = makeBuilding(rng, garageC, e.in, glm::vec2(3.2f, 1.6f), Roof::Flat, 2.6f, 0.0f);
            g.material = rng.chance(0.5) ? RoofMaterial::Bitumen : RoofMaterial::Gravel;
            o.buildings.push_back(g);
        } else {
            driveEnd = setback + 0.5f * depth;
        }
        const float dLen = 0.5f * (driveEnd - streetEdge);
        const glm::vec2 dC = e.a + e.t * glm::dot(sideC - e.a, e.t) + e.in * (streetEdge + dLen);
        if (dLen > 1.0f && rectInside(p.poly, dC, e.in, glm::vec2(dLen, 1.5f), 0.2f)) {
            addFeature(l, p, Feature::Shape::Rect, dC, e.in, glm::vec2(dLen, 1.5f), Ground::Paving,
                       static_cast<std::uint8_t>(rng.index(2)), static_cast<std::uint32_t>(rng.next()));
            if (dLen > 3.0f && rng.chance(0.75)) addCar(o, rng, dC - e.in * (dLen - 2.6f), e.in, 0.45);
        }
        // Terrace behind the house.
        const glm::vec2 tC = c + e.in * (0.5f * depth + 2.0f);
        if (rng.chance(0.6) && rectInside(p.poly, tC, e.t, glm::vec2(0.3f * len, 2.0f), 0.5f))
            addFeature(l, p, Feature::Shape::Rect, tC, e.t, glm::vec2(0.3f * len, 2.0f), Ground::Paving, 1,
                       static_cast<std::uint32_t>(rng.next()));
        p.role = ParcelRole::House;
        return;
    }
}

// Courts in a row across `ax`, starting next to `from` on side `sgn`, as many as fit (up to 4).
std::vector<glm::vec2> courtRow(const Layout& l, const Parcel& p, glm::vec2 from, glm::vec2 ax, float sgn, glm::vec2 court) {
    std::vector<glm::vec2> row;
    for (int k = 0; k < 4; ++k) {
        const glm::vec2 c = from + perpLeft(ax) * (sgn * court.y * (2.0f * float(k) + 1.0f));
        if (!fits(l, p, c, ax, court, 0.8f)) break;
        row.push_back(c);
    }
    return row;
}

bool placeSports(Layout& l, Parcel& p, Objects& o, Rng& rng) {
    const glm::vec2 ax = p.grain, across = perpLeft(ax);
    const glm::vec2 court(18.3f, 9.15f); // tennis court with run-off, 36.6 x 18.3 m
    const glm::vec2 pitches[] = {{52.5f, 34.0f}, {45.0f, 30.0f}, {32.0f, 21.0f}};
    bool found = false;
    glm::vec2 half(0.0f), pitchC(0.0f);
    std::vector<glm::vec2> courts;
    // A football pitch (shifted across the block to make room) with a row of courts beside it.
    for (const glm::vec2 h : pitches) {
        for (float shift : {0.0f, 12.0f, -12.0f, 24.0f, -24.0f}) {
            const glm::vec2 c = p.centroid + across * shift;
            if (!fits(l, p, c, ax, h + glm::vec2(4.0f), 1.0f)) continue;
            for (float sgn : {1.0f, -1.0f}) {
                std::vector<glm::vec2> row = courtRow(l, p, c + across * (sgn * (h.y + 6.0f)), ax, sgn, court);
                if (!found || row.size() > courts.size()) {
                    found = true;
                    half = h;
                    pitchC = c;
                    courts = std::move(row);
                }
            }
            if (courts.size() >= 2) break;
        }
        if (found) break;
    }
    if (found)
        addFeature(l, p, Feature::Shape::Rect, pitchC, ax, half, Ground::Pitch, 0, static_cast<std::uint32_t>(rng.next()));
    else {
        // No room for a pitch: a tennis club.
        pitchC = p.centroid;
        courts = courtRow(l, p, p.centroid - across * (2.0f * court.y), ax, 1.0f, court);
        if (courts.size() < 2) return false;
    }
    // The first court is the paper's false positive (green in leaf-on only).
    for (size_t k = 0; k < courts.size(); ++k) {
        const double r = rng.uniform();
        const CourtSurface s = k == 0     ? CourtSurface::LeafOnOnlyGreen
                               : r < 0.35 ? CourtSurface::Clay
                               : r < 0.55 ? CourtSurface::Green
                               : r < 0.8  ? CourtSurface::LeafOnOnlyGreen
                                          : CourtSurface::LeafOffOnlyGreen;
        addFeature(l, p, Feature::Shape::Rect, courts[k], ax, court, Ground::Court, static_cast<std::uint8_t>(s),
                   static_cast<std::uint32_t>(rng.next()));
    }
    // Clubhouse at one end of the pitch (or of the courts).
    const float endX = found ? half.x : court.x;
    for (float sgn : {1.0f, -1.0f}) {
        const glm::vec2 hc = pitchC + ax * (sgn * (endX + 9.0f));
        if (fits(l, p, hc, across, glm::vec2(9.0f, 5.0f), 1.0f)) {
            Building b = makeBuilding(rng, hc, across, glm::vec2(9.0f, 5.0f), Roof::Gable, 3.2f, 25.0f);
            b.material = RoofMaterial::Anthracite;
            o.buildings.push_back(b);
            break;
        }
    }
    p.role = ParcelRole::Sports;
    return true;
}

bool placeParking(Layout& l, Parcel& p, Objects& o, Rng& rng) {
    const RoadEdge e = longestRoadEdge(l, p, false);
    if (e.edge < 0 || e.length < 40.0f) return false;
    const float lotLen = std::min(e.length - 12.0f, 70.0f), lotDepth = 33.0f, storeDepth = rng.uniformf(22.0f, 32.0f);
    const float start = e.roadHalf + e.verge + 1.0f;
    const glm::vec2 mid = e.a + e.t * (0.5f * e.length);
    const glm::vec2 lotC = mid + e.in * (start + 0.5f * lotDepth);
    const glm::vec2 storeC = mid + e.in * (start + lotDepth + 1.5f + 0.5f * storeDepth);
    const glm::vec2 storeHalf(0.45f * lotLen, 0.5f * storeDepth);
    if (!fits(l, p, lotC, e.t, glm::vec2(0.5f * lotLen, 0.5f * lotDepth), 0.5f) || !fits(l, p, storeC, e.t, storeHalf, 1.0f))
        return false;
    addFeature(l, p, Feature::Shape::Rect, lotC, e.t, glm::vec2(0.5f * lotLen, 0.5f * lotDepth), Ground::Paving, 2,
               static_cast<std::uint32_t>(rng.next()));
    Building store = makeBuilding(rng, storeC, e.t, storeHalf, Roof::Flat, rng.uniformf(5.0f, 8.0f), 0.0f);
    store.material = rng.chance(0.45) ? RoofMaterial::Sedum : RoofMaterial::Bitumen;
    store.greenLeafOnOnly = store.material == RoofMaterial::Sedum;
    o.buildings.push_back(store);
    // Two double rows of 2.5 m slots (5 m deep) around 6 m aisles; each slot is occupied per season at random.
    for (float rowOff : {2.5f, 7.5f, 19.5f, 24.5f})
        for (float u = -0.5f * lotLen + 1.25f; u < 0.5f * lotLen - 1.0f; u += 2.5f)
            if (rng.chance(0.62))
                addCar(o, rng, mid + e.t * u + e.in * (start + 1.0f + rowOff), e.in, 0.3);
    p.role = ParcelRole::Parking;
    return true;
}

void placePark(Layout& l, Parcel& p, Rng& rng) {
    p.role = ParcelRole::Park;
    const float r = std::min(0.22f * std::sqrt(p.area), 30.0f);
    const glm::vec2 half(r * rng.uniformf(1.0f, 1.5f), r);
    if (fits(l, p, p.centroid, p.grain, half * 1.25f + glm::vec2(3.0f), 1.0f))
        addFeature(l, p, Feature::Shape::Blob, p.centroid, p.grain, half, Ground::Water, 1,
                   static_cast<std::uint32_t>(rng.next()));
}

void placeFarmstead(Layout& l, Parcel& p, Objects& o, Rng& rng) {
    const RoadEdge e = longestRoadEdge(l, p, true);
    if (e.edge < 0 || e.length < 70.0f) return;
    const float yardLen = rng.uniformf(45.0f, 60.0f), yardDepth = rng.uniformf(38.0f, 50.0f);
    const float start = e.roadHalf + e.verge + 6.0f;
    const glm::vec2 base = e.a + e.t * (rng.uniformf(0.3f, 0.7f) * e.length);
    const glm::vec2 yardC = base + e.in * (start + 0.5f * yardDepth);
    if (!fits(l, p, yardC + e.in * 6.0f, e.t, glm::vec2(0.5f * yardLen + 10.0f, 0.5f * yardDepth + 6.0f), 1.0f)) return;
    addFeature(l, p, Feature::Shape::Rect, yardC, e.t, glm::vec2(0.5f * yardLen, 0.5f * yardDepth), Ground::Yard, 0,
               static_cast<std::uint32_t>(rng.next()));
    // Barn along the back of the yard, house at the front corner, a shed on one side.
    const glm::vec2 barnHalf(0.5f * yardLen - 4.0f, rng.uniformf(7.0f, 9.0f));
    Building barn = makeBuilding(rng, base + e.in * (start + yardDepth - barnHalf.y - 1.0f), e.t, barnHalf, Roof::Gable,
                                 rng.uniformf(4.5f, 6.5f), rng.uniformf(17.0f, 26.0f));
    const double m = rng.uniform();
    barn.material = m < 0.4 ? RoofMaterial::FibreCement : m < 0.7 ? RoofMaterial::Anthracite : RoofMaterial::RedTile;
    barn.solar = rng.chance(0.35);
    o.buildings.push_back(barn);
    const glm::vec2 houseHalf(rng.uniformf(6.0f, 8.0f), rng.uniformf(4.5f, 5.5f));
    Building house = makeBuilding(rng, base + e.t * (-0.5f * yardLen + houseHalf.y + 1.0f) + e.in * (start + houseHalf.x + 1.0f),
                                  e.in, houseHalf, Roof::Gable, rng.uniformf(3.5f, 5.0f), rng.uniformf(38.0f, 48.0f));
    house.material = houseRoofMaterial(rng);
    o.buildings.push_back(house);
    const glm::vec2 shedHalf(rng.uniformf(7.0f, 10.0f), rng.uniformf(4.0f, 5.5f));
    Building shed = makeBuilding(rng, base + e.t * (0.5f * yardLen - shedHalf.y - 1.0f) + e.in * (start + shedHalf.x + 2.0f),
                                 e.in, shedHalf, Roof::Gable, 3.5f, rng.uniformf(15.0f, 22.0f));
    shed.material = RoofMaterial::FibreCement;
    o.buildings.push_back(shed);
    for (int i = 0, n = 1 + rng.index(3); i < n; ++i)
        addCar(o, rng, yardC + e.t * rng.uniformf(-6.0f, 6.0f) + e.in * (float(i) * 3.0f - 8.0f), e.t, 0.5);
    l.records[p.record].cls = Ground::Meadow; // pasture around the farm
    p.role = ParcelRole::Farmstead;
}

// Parked cars along village streets and moving traffic on main roads (different cars in each season).
void placeTraffic(const Layout& l, Objects& o, Rng& rng) {
    for (size_t ci = 0; ci < l.cuts.size(); ++ci) {
        const Cut& c = l.cuts[ci];
        if (c.kind != CutKind::Street && c.kind != CutKind::MainRoad) continue;
        const glm::vec2 d = c.b - c.a;
        const float len = glm::length(d);
        if (len < 10.0f) continue;
        const glm::vec2 t = d / len, n = perpLeft(t);
        const bool street = c.kind == CutKind::Street;
        for (float sgn : {-1.0f, 1.0f}) {
            float u = rng.uniformf(3.0f, street ? 25.0f : 120.0f);
            while (u < len - 3.0f) {
                const glm::vec2 p = c.a + t * u + n * (sgn * (street ? 2.0f : 1.7f));
                if (l.groundAtLayout(p) == c.roadRecord) {
                    Car car;
                    car.centre = p;
                    car.axis = sgn > 0.0f ? -t : t;
                    car.seasons = static_cast<std::uint8_t>(street && rng.chance(0.3) ? 3 : (rng.chance(0.5) ? 1 : 2));
                    car.colour = randomCarColour(rng, car.seasons != 3);
                    car.seed = static_cast<std::uint32_t>(rng.next());
                    o.cars.push_back(car);
                }
                u += street ? rng.uniformf(6.0f, 40.0f) : rng.uniformf(25.0f, 220.0f);
            }
        }
    }
}

} // namespace

void placeSettlement(Layout& l, Objects& o) {
    Rng rng(mixSeed(l.seed, 2));
    const size_t nv = l.villages.size();
    std::vector<bool> sports(nv, false), park(nv, false), parking(nv, false);
    for (Parcel& p : l.parcels) {
        if (p.use == LandUse::Village) {
            size_t v = 0;
            for (size_t i = 1; i < nv; ++i)
                if (glm::length(p.centroid - l.villages[i]) < glm::length(p.centroid - l.villages[v])) v = i;
            if (p.area > 4000.0f) { // a block kept whole by the partition
                if (!sports[v] && placeSports(l, p, o, rng)) sports[v] = true;
                else if (!parking[v] && placeParking(l, p, o, rng)) parking[v] = true;
                else if (!park[v] || rng.chance(0.5)) {
                    placePark(l, p, rng);
                    park[v] = true;
                } else placeHouse(l, p, o, rng);
            } else if (rng.chance(0.93)) placeHouse(l, p, o, rng);
        } else if (p.use == LandUse::Farm && p.area > 9000.0f && rng.chance(0.07)) {
            placeFarmstead(l, p, o, rng);
        }
    }
    placeTraffic(l, o, rng);
}

} // namespace seasonview::synth

namespace seasonview::synth {

void placeBlockCity(Layout& l, Objects& o, int count, std::uint64_t seed) {
    if (count <= 0) return;
    constexpr float kW = 16.0f, kD = 12.0f, kGap = 1.0f, kStreet = 12.0f;
    constexpr int kAcross = 4, kDeep = 2; // buildings per block
    const float blockW = kAcross * (kW + kGap) + kStreet, blockD = kDeep * (kD + kGap) + kStreet;
    const int blocks = (count + kAcross * kDeep - 1) / (kAcross * kDeep);
    // A grid of about equal extent both ways.
    const int nx = std::max(1, int(std::ceil(std::sqrt(double(blocks) * blockD / blockW))));
    const int ny = (blocks + nx - 1) / nx;
    const glm::vec2 size(float(nx) * blockW, float(ny) * blockD);
    l.hasCity = true;
    l.cityMin = -0.5f * size;
    l.cityMax = 0.5f * size;
    l.cityRecord = l.addRecord({Ground::Paving, 0, glm::vec2(0.0f), glm::vec2(1.0f, 0.0f), 0.5f * size, 0xC17Cu});
    auto inside = [&](glm::vec2 layoutPoint, float margin) {
        return layoutPoint.x > l.cityMin.x - margin && layoutPoint.x < l.cityMax.x + margin &&
               layoutPoint.y > l.cityMin.y - margin && layoutPoint.y < l.cityMax.y + margin;
    };
    std::erase_if(o.buildings, [&](const Building& b) { return inside(b.centre, 20.0f); });
    std::erase_if(o.cars, [&](const Car& c) { return inside(c.centre, 3.0f); });
    std::erase_if(o.trees, [&](const Tree& t) { return inside(l.warp.toLayout(t.centre), t.radius + 2.0f); });
    Rng rng(mixSeed(seed, 0xB10CC17Eull));
    int placed = 0;
    for (int by = 0; by < ny && placed < count; ++by)
        for (int bx = 0; bx < nx && placed < count; ++bx)
            for (int j = 0; j < kDeep && placed < count; ++j)
                for (int i = 0; i < kAcross && placed < count; ++i) {
                    const glm::vec2 c = l.cityMin + glm::vec2(float(bx) * blockW + 0.5f * kStreet + (float(i) + 0.5f) * (kW + kGap),
                                                              float(by) * blockD + 0.5f * kStreet + (float(j) + 0.5f) * (kD + kGap));
                    const int storeys = 3 + int(rng.next() % 8);
                    const Roof roof = rng.chance(0.8) ? Roof::Flat : Roof::Gable;
                    Building b = makeBuilding(rng, c, glm::vec2(1.0f, 0.0f), glm::vec2(0.5f * kW, 0.5f * kD), roof,
                                              3.0f * float(storeys), roof == Roof::Flat ? 0.0f : 35.0f);
                    b.material = roof == Roof::Flat ? (rng.chance(0.5) ? RoofMaterial::Gravel : RoofMaterial::Bitumen)
                                                    : RoofMaterial(rng.next() % 5);
                    o.buildings.push_back(b);
                    ++placed;
                }
}

} // namespace seasonview::synth
