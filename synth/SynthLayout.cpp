#include "SynthLayout.h"

#include "SynthRandom.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>

namespace seasonview::synth {

namespace {

constexpr float kPi = 3.14159265358979f;

glm::vec2 rotate(glm::vec2 v, float a) {
    const float c = std::cos(a), s = std::sin(a);
    return glm::vec2(c * v.x - s * v.y, s * v.x + c * v.y);
}

std::uint32_t seed32(std::uint64_t seed, std::uint64_t key) { return static_cast<std::uint32_t>(mixSeed(seed, key)); }

// Land use by zone fields: villages (discs with noisy edges) win over forest (low-frequency fBm) over farmland.
LandUse zoneAt(const Layout& l, glm::vec2 q) {
    float v = -1.0f;
    for (size_t i = 0; i < l.villages.size(); ++i)
        v = std::max(v, 1.0f - glm::length(q - l.villages[i]) / l.villageRadius[i]);
    v += 0.2f * valueNoise(q.x / 110.0f, q.y / 110.0f, seed32(l.seed, 11));
    if (v > 0.0f) return LandUse::Village;
    if (fbm(q.x / 650.0f, q.y / 650.0f, seed32(l.seed, 12), 3) > 0.24f) return LandUse::Forest;
    return LandUse::Farm;
}

// Target parcel areas (square metres) per land use: fields ~2 ha, forest stands ~3 ha, village lots ~750 m².
float targetArea(LandUse u) {
    switch (u) {
    case LandUse::Farm: return 22000.0f;
    case LandUse::Forest: return 30000.0f;
    case LandUse::Village: return 750.0f;
    }
    return 22000.0f;
}

CutKind chooseCut(float area, LandUse use, Rng& rng) {
    const double r = rng.uniform();
    if (area > 1.4e6f) return CutKind::MainRoad;
    switch (use) {
    case LandUse::Village: return area > 11000.0f ? CutKind::Street : CutKind::None;
    case LandUse::Farm:
        if (area > 2.5e5f) return r < 0.55 ? CutKind::Track : r < 0.85 ? CutKind::Hedge : CutKind::Margin;
        return r < 0.25 ? CutKind::Hedge : CutKind::Margin;
    case LandUse::Forest: return area > 1.0e5f && r < 0.6 ? CutKind::ForestTrack : CutKind::None;
    }
    return CutKind::None;
}

struct Pending {
    std::vector<glm::vec2> poly;
    std::vector<std::int32_t> tags;
    std::int32_t node = 0;
    int depth = 0;
    glm::vec2 grain{1.0f, 0.0f};
};

} // namespace

bool Feature::contains(glm::vec2 q) const {
    const glm::vec2 d = q - centre;
    const float u = glm::dot(d, axis), v = glm::dot(d, perpLeft(axis));
    if (shape == Shape::Rect) return std::abs(u) < half.x && std::abs(v) < half.y;
    const float eu = u / half.x, ev = v / half.y;
    const float r2 = eu * eu + ev * ev;
    if (r2 > 1.7f) return false;
    // A pond: an ellipse with a wobbly shore.
    const float wobble = 0.22f * valueNoise(eu * 1.6f + centre.x, ev * 1.6f + centre.y, 0x51u);
    return r2 < (1.0f + wobble) * (1.0f + wobble);
}

Warp::Warp(float halfExtent, std::uint64_t seed) : m_half(halfExtent + 16.0f), m_step(8.0f) {
    m_n = static_cast<int>(std::ceil(2.0f * m_half / m_step)) + 1;
    m_d.resize(size_t(m_n) * size_t(m_n));
    const std::uint32_t s = seed32(seed, 21);
    for (int j = 0; j < m_n; ++j)
        for (int i = 0; i < m_n; ++i) {
            const float x = -m_half + float(i) * m_step, y = -m_half + float(j) * m_step;
            // ~6 m over ~400 m plus ~1.5 m over ~130 m: gentle road curves, no visible kinks.
            const glm::vec2 big(valueNoise(x / 400.0f, y / 400.0f, s), valueNoise(x / 400.0f, y / 400.0f, s + 1));
            const glm::vec2 small(valueNoise(x / 130.0f, y / 130.0f, s + 2), valueNoise(x / 130.0f, y / 130.0f, s + 3));
            m_d[size_t(j) * size_t(m_n) + size_t(i)] = 6.0f * big + 1.5f * small;
        }
}

glm::vec2 Warp::displacement(glm::vec2 p) const {
    if (m_n == 0) return glm::vec2(0.0f);
    const float fx = std::clamp((p.x + m_half) / m_step, 0.0f, float(m_n - 1) - 1e-3f);
    const float fy = std::clamp((p.y + m_half) / m_step, 0.0f, float(m_n - 1) - 1e-3f);
    const int i = static_cast<int>(fx), j = static_cast<int>(fy);
    const float tx = fx - float(i), ty = fy - float(j);
    const glm::vec2* r0 = &m_d[size_t(j) * size_t(m_n) + size_t(i)];
    const glm::vec2* r1 = r0 + m_n;
    return (r0[0] * (1.0f - tx) + r0[1] * tx) * (1.0f - ty) + (r1[0] * (1.0f - tx) + r1[1] * tx) * ty;
}

glm::vec2 Warp::toLayout(glm::vec2 local) const { return local + displacement(local); }

glm::vec2 Warp::toLocal(glm::vec2 layout) const {
    glm::vec2 p = layout;
    for (int i = 0; i < 8; ++i) p = layout - displacement(p);
    return p;
}

float River::distance(glm::vec2 q, float limit) const {
    const glm::vec2 d = q - origin;
    const float u = glm::dot(d, axis), v = glm::dot(d, perpLeft(axis));
    // |v - vc| >= |v| - (amp1 + amp2) and the slope term is at most 1 + (amp1 k1 + amp2 k2)²: a lower bound.
    const float maxSlope = amp1 * k1 + amp2 * k2;
    const float bound = (std::abs(v) - amp1 - amp2) / std::sqrt(1.0f + maxSlope * maxSlope);
    if (bound > limit) return bound;
    const float a1 = k1 * u + phase1, a2 = k2 * u + phase2;
    const float vc = amp1 * std::sin(a1) + amp2 * std::sin(a2);
    const float dv = amp1 * k1 * std::cos(a1) + amp2 * k2 * std::cos(a2);
    return std::abs(v - vc) / std::sqrt(1.0f + dv * dv);
}

glm::vec2 River::centre(float u) const {
    const float vc = amp1 * std::sin(k1 * u + phase1) + amp2 * std::sin(k2 * u + phase2);
    return origin + axis * u + perpLeft(axis) * vc;
}

glm::vec2 River::normal(float u) const {
    const float dv = amp1 * k1 * std::cos(k1 * u + phase1) + amp2 * k2 * std::cos(k2 * u + phase2);
    return glm::normalize(perpLeft(axis) - axis * dv);
}

int Layout::parcelAt(glm::vec2 q) const {
    std::int32_t node = 0;
    while (nodeCut[size_t(node)] >= 0) {
        const Cut& c = cuts[size_t(nodeCut[size_t(node)])];
        node = nodeChild[2 * size_t(node) + (glm::dot(c.normal, q) - c.offset >= 0.0f ? 1 : 0)];
    }
    return nodeParcel[size_t(node)];
}

std::uint32_t Layout::groundAtLayout(glm::vec2 q) const {
    if (hasCity && q.x >= cityMin.x && q.x <= cityMax.x && q.y >= cityMin.y && q.y <= cityMax.y) return cityRecord;
    // Walk the partition from the root: a parent's road or margin strip wins over everything below it, which makes
    // junctions and verges come out right.
    std::uint32_t id = 0;
    std::int32_t node = 0;
    bool found = false;
    while (nodeCut[size_t(node)] >= 0) {
        const Cut& c = cuts[size_t(nodeCut[size_t(node)])];
        const float s = glm::dot(c.normal, q) - c.offset, a = std::abs(s);
        if (a < c.roadHalf) {
            id = c.roadRecord;
            found = true;
            break;
        }
        if (a < c.marginHalf) {
            id = c.marginRecord;
            found = true;
            break;
        }
        node = nodeChild[2 * size_t(node) + (s >= 0.0f ? 1 : 0)];
    }
    if (!found) {
        const Parcel& p = parcels[size_t(nodeParcel[size_t(node)])];
        id = p.record;
        for (const Feature& f : p.features)
            if (f.contains(q)) {
                id = f.record;
                break;
            }
    }
    const float rd = river.distance(q, river.halfWidth + river.bankWidth);
    if (rd < river.halfWidth) return records[id].cls == Ground::MainRoad ? id : waterRecord; // main roads bridge
    if (rd < river.halfWidth + river.bankWidth) return isRoad(records[id].cls) ? id : bankRecord;
    return id;
}

namespace {

// Villages, placed in a region of at least ~2.5 x 2.5 km so that small scenes see them with their real frequency
// (about one village per 3 km²) instead of always sitting in one.
void placeVillages(Layout& l, Rng& rng, float halfExtent) {
    const float region = std::max(halfExtent, 1250.0f);
    const int villages = std::max(1, static_cast<int>(std::lround(4.0 * double(region) * double(region) / 3.0e6)));
    for (int i = 0; i < villages; ++i) {
        l.villages.push_back(glm::vec2(rng.uniformf(-0.85f, 0.85f), rng.uniformf(-0.85f, 0.85f)) * region);
        l.villageRadius.push_back(rng.uniformf(170.0f, 320.0f));
    }
}

// The river: a meander around a straight axis through the layout.
void placeRiver(River& r, Rng& rng, float halfExtent) {
    const float riverAngle = rng.uniformf(0.0f, kPi);
    r.axis = glm::vec2(std::cos(riverAngle), std::sin(riverAngle));
    r.origin = perpLeft(r.axis) * rng.uniformf(-0.4f, 0.4f) * std::max(halfExtent, 600.0f);
    r.amp1 = rng.uniformf(35.0f, 80.0f);
    r.k1 = 2.0f * kPi / rng.uniformf(550.0f, 900.0f);
    r.phase1 = rng.uniformf(0.0f, 2.0f * kPi);
    r.amp2 = rng.uniformf(6.0f, 16.0f);
    r.k2 = 2.0f * kPi / rng.uniformf(150.0f, 260.0f);
    r.phase2 = rng.uniformf(0.0f, 2.0f * kPi);
    r.halfWidth = rng.uniformf(5.5f, 8.5f);
    r.bankWidth = 3.5f;
}

// A leaf of the cut tree becomes a parcel with its ground record (crop, forest composition, lawn).
void addParcel(Layout& l, Pending&& p, LandUse use, float area, glm::vec2 centroid, glm::vec2 grain, std::uint64_t seed,
               Rng& rng) {
    Parcel parcel;
    parcel.poly = std::move(p.poly);
    parcel.edgeCut = std::move(p.tags);
    parcel.use = use;
    parcel.area = area;
    parcel.centroid = centroid;
    parcel.grain = grain;
    GroundRecord rec{Ground::Meadow, 0, centroid, parcel.grain, {}, seed32(seed, 500000 + l.parcels.size())};
    const double u = rng.uniform();
    switch (use) {
    case LandUse::Farm:
        rec.cls = u < 0.28 ? Ground::Meadow : u < 0.60 ? Ground::WinterCrop : u < 0.93 ? Ground::SummerCrop
                                                                                      : Ground::Fallow;
        rec.variant = static_cast<std::uint8_t>(rng.index(3));
        break;
    case LandUse::Forest: {
        // Composition: 0 deciduous, 1 mixed, 2 conifer, 3 conifer plantation in rows.
        rec.cls = Ground::ForestFloor;
        rec.variant = static_cast<std::uint8_t>(u < 0.50 ? 0 : u < 0.80 ? 1 : u < 0.91 ? 2 : 3);
        break;
    }
    case LandUse::Village: rec.cls = Ground::Lawn; break;
    }
    parcel.record = l.addRecord(rec);
    l.nodeParcel[size_t(p.node)] = static_cast<std::int32_t>(l.parcels.size());
    l.parcels.push_back(std::move(parcel));
}

} // namespace

Layout buildLayout(float halfExtent, std::uint64_t seed) {
    Layout l;
    l.halfExtent = halfExtent;
    l.seed = seed;
    l.warp = Warp(halfExtent, seed);
    Rng rng(mixSeed(seed, 1));

    placeVillages(l, rng, halfExtent);

    placeRiver(l.river, rng, halfExtent);

    l.waterRecord = l.addRecord({Ground::Water, 0, {}, {1.0f, 0.0f}, {}, seed32(seed, 31)});
    l.bankRecord = l.addRecord({Ground::Bank, 0, {}, {1.0f, 0.0f}, {}, seed32(seed, 32)});
    const std::uint32_t fieldMargin = l.addRecord({Ground::Margin, 0, {}, {1.0f, 0.0f}, {}, seed32(seed, 33)});
    const std::uint32_t hedgeStrip = l.addRecord({Ground::Margin, 1, {}, {1.0f, 0.0f}, {}, seed32(seed, 34)});
    const std::uint32_t verge = l.addRecord({Ground::Margin, 2, {}, {1.0f, 0.0f}, {}, seed32(seed, 35)});

    const float h = halfExtent;
    Pending root;
    root.poly = {{-h, -h}, {h, -h}, {h, h}, {-h, h}};
    root.tags = {-1, -1, -1, -1};
    const float grainAngle = rng.uniformf(0.0f, kPi);
    root.grain = glm::vec2(std::cos(grainAngle), std::sin(grainAngle));
    l.nodeCut.push_back(-1);
    l.nodeChild.insert(l.nodeChild.end(), {-1, -1});
    l.nodeParcel.push_back(-1);

    std::vector<Pending> stack{root};
    std::vector<glm::vec2> polyA, polyB;
    std::vector<std::int32_t> tagsA, tagsB;
    while (!stack.empty()) {
        Pending p = std::move(stack.back());
        stack.pop_back();
        const float area = polygonArea(p.poly);
        const glm::vec2 centroid = polygonCentroid(p.poly);
        const LandUse use = zoneAt(l, centroid);
        const glm::vec2 across = perpLeft(p.grain);
        const glm::vec2 eu = projectExtent(p.poly, p.grain), ev = projectExtent(p.poly, across);
        const float lenU = eu.y - eu.x, lenV = ev.y - ev.x;
        const float target = targetArea(use) * rng.uniformf(0.6f, 1.5f);
        bool leaf = area < target || p.depth > 30;
        // Keep a few village blocks whole for a sports ground, a parking lot or a park (SynthSettlement).
        if (!leaf && use == LandUse::Village && area > 5000.0f && area < 16000.0f && rng.chance(0.07)) leaf = true;

        if (!leaf) {
            // Cut across the longer side; farmland is sometimes split lengthwise too, giving long strip fields.
            const bool longU = lenU >= lenV;
            const float aspect = longU ? lenU / std::max(lenV, 1.0f) : lenV / std::max(lenU, 1.0f);
            bool acrossLong = true;
            if (use == LandUse::Farm && aspect < 2.6f && std::min(lenU, lenV) > 90.0f && rng.chance(0.45))
                acrossLong = false;
            const bool normalIsU = longU == acrossLong;
            glm::vec2 n = normalIsU ? p.grain : across;
            const glm::vec2 ext = normalIsU ? eu : ev;
            const float t = rng.uniformf(0.36f, 0.64f);
            const glm::vec2 pivot = centroid + n * (ext.x + t * (ext.y - ext.x) - glm::dot(n, centroid));
            n = rotate(n, rng.uniformf(-0.07f, 0.07f));
            const float offset = glm::dot(n, pivot);
            const CutKind kind = chooseCut(area, use, rng);
            const auto cutIndex = static_cast<std::int32_t>(l.cuts.size());
            clipPolygon(p.poly, p.tags, n, offset, -1.0f, polyA, tagsA, cutIndex);
            clipPolygon(p.poly, p.tags, n, offset, 1.0f, polyB, tagsB, cutIndex);
            if (polyA.size() < 3 || polyB.size() < 3 || polygonArea(polyA) < 0.1f * area ||
                polygonArea(polyB) < 0.1f * area) {
                leaf = true;
            } else {
                Cut c;
                c.normal = n;
                c.offset = offset;
                c.kind = kind;
                // The cut segment is the new edge of polyA (tagged with this cut).
                for (size_t i = 0; i < polyA.size(); ++i)
                    if (tagsA[i] == cutIndex) {
                        c.a = polyA[i];
                        c.b = polyA[(i + 1) % polyA.size()];
                    }
                GroundRecord road{Ground::MainRoad, 0, c.a, glm::normalize(perpLeft(n)), {}, seed32(seed, 1000 + l.cuts.size())};
                switch (kind) {
                case CutKind::MainRoad: c.roadHalf = 3.3f; c.marginHalf = 5.0f; c.marginRecord = verge;
                    c.avenue = rng.chance(0.35); break;
                case CutKind::Street: c.roadHalf = 4.8f; road.cls = Ground::Street; c.avenue = rng.chance(0.25); break;
                case CutKind::Track: c.roadHalf = 1.6f; c.marginHalf = 2.4f; c.marginRecord = verge;
                    road.cls = Ground::Track; break;
                case CutKind::ForestTrack: c.roadHalf = 1.8f; road.cls = Ground::ForestTrack; break;
                case CutKind::Hedge: c.marginHalf = 1.6f; c.marginRecord = hedgeStrip; break;
                case CutKind::Margin: c.marginHalf = 0.55f; c.marginRecord = fieldMargin; break;
                case CutKind::None: break;
                }
                if (c.roadHalf > 0.0f) {
                    road.half = glm::vec2(c.roadHalf, 0.0f);
                    c.roadRecord = l.addRecord(road);
                }
                l.cuts.push_back(c);
                const auto childA = static_cast<std::int32_t>(l.nodeCut.size());
                for (int k = 0; k < 2; ++k) {
                    l.nodeCut.push_back(-1);
                    l.nodeChild.insert(l.nodeChild.end(), {-1, -1});
                    l.nodeParcel.push_back(-1);
                }
                l.nodeCut[size_t(p.node)] = cutIndex;
                l.nodeChild[2 * size_t(p.node)] = childA;       // side dot(n,q) - offset < 0
                l.nodeChild[2 * size_t(p.node) + 1] = childA + 1;
                const glm::vec2 gA = rotate(p.grain, rng.uniformf(-0.04f, 0.04f));
                const glm::vec2 gB = rotate(p.grain, rng.uniformf(-0.04f, 0.04f));
                stack.push_back({polyB, tagsB, childA + 1, p.depth + 1, gB});
                stack.push_back({polyA, tagsA, childA, p.depth + 1, gA});
                continue;
            }
        }

        addParcel(l, std::move(p), use, area, centroid, lenU >= lenV ? p.grain : across, seed, rng);
    }
    return l;
}

} // namespace seasonview::synth
