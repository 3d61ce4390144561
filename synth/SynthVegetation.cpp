// Vegetation step of the synthetic scene: where trees stand and how big they are.
#include "SynthObjects.h"
#include "SynthRandom.h"

#include <glm/geometric.hpp>

#include <cmath>

namespace seasonview::synth {

namespace {

constexpr float kPi = 3.14159265358979f;
constexpr float kMaxRadius = 7.0f;

constexpr std::uint32_t bit(Ground g) { return 1u << unsigned(g); }
constexpr std::uint32_t kGreen = bit(Ground::Meadow) | bit(Ground::Lawn) | bit(Ground::Margin);
constexpr std::uint32_t kOpenLand = kGreen | bit(Ground::Fallow) | bit(Ground::WinterCrop) | bit(Ground::SummerCrop) |
                                    bit(Ground::ForestFloor);

// Uniform buckets of indices over a square, for neighbour queries.
class Buckets {
public:
    Buckets(float half, float cell) : m_half(half), m_cell(cell), m_n(int(std::ceil(2.0f * half / cell)) + 1) {
        m_cells.resize(size_t(m_n) * size_t(m_n));
    }
    int cellOf(float v) const { return std::clamp(int((v + m_half) / m_cell), 0, m_n - 1); }
    void insert(int index, glm::vec2 lo, glm::vec2 hi) {
        for (int j = cellOf(lo.y); j <= cellOf(hi.y); ++j)
            for (int i = cellOf(lo.x); i <= cellOf(hi.x); ++i) m_cells[size_t(j) * size_t(m_n) + size_t(i)].push_back(index);
    }
    template <class Fn> bool all(glm::vec2 lo, glm::vec2 hi, const Fn& fn) const {
        for (int j = cellOf(lo.y); j <= cellOf(hi.y); ++j)
            for (int i = cellOf(lo.x); i <= cellOf(hi.x); ++i)
                for (int k : m_cells[size_t(j) * size_t(m_n) + size_t(i)])
                    if (!fn(k)) return false;
        return true;
    }

private:
    float m_half, m_cell;
    int m_n;
    std::vector<std::vector<int>> m_cells;
};

class Planter {
public:
    Planter(const Layout& l, Objects& o)
        : m_l(l), m_o(o), m_trees(l.halfExtent + 20.0f, 8.0f), m_buildings(l.halfExtent + 20.0f, 32.0f),
          m_rng(mixSeed(l.seed, 3)) {
        for (size_t i = 0; i < o.buildings.size(); ++i) {
            const Building& b = o.buildings[i];
            const float r = glm::length(b.half) + 1.0f;
            m_buildings.insert(int(i), b.centre - glm::vec2(r), b.centre + glm::vec2(r));
        }
    }
    Rng& rng() { return m_rng; }

    /// Plants a tree at a local-frame point if the ground there is in `allowed`, it keeps clear of buildings and it
    /// keeps the spacing rule |ci - cj| >= max(max(ri, rj) + 0.5, closeness * (ri + rj)).
    bool plant(glm::vec2 c, float r, bool conifer, std::uint32_t allowed, float closeness) {
        const float lim = m_l.halfExtent - r;
        if (std::abs(c.x) > lim || std::abs(c.y) > lim) return false;
        const glm::vec2 q = m_l.warp.toLayout(c);
        if (!(allowed & bit(m_l.records[m_l.groundAtLayout(q)].cls))) return false;
        const float reach = std::max(kMaxRadius + 0.5f, closeness * (r + kMaxRadius));
        const bool spaced = m_trees.all(c - glm::vec2(reach), c + glm::vec2(reach), [&](int k) {
            const Tree& t = m_o.trees[size_t(k)];
            const float need = std::max(std::max(r, t.radius) + 0.5f, closeness * (r + t.radius));
            return glm::length(t.centre - c) >= need;
        });
        if (!spaced) return false;
        const bool clear = m_buildings.all(q, q, [&](int k) {
            const Building& b = m_o.buildings[size_t(k)];
            const glm::vec2 d = q - b.centre;
            const float dx = std::max(std::abs(glm::dot(d, b.axis)) - b.half.x, 0.0f);
            const float dy = std::max(std::abs(glm::dot(d, perpLeft(b.axis))) - b.half.y, 0.0f);
            return dx * dx + dy * dy >= (0.6f * r + 0.8f) * (0.6f * r + 0.8f);
        });
        if (!clear) return false;
        Tree t;
        t.centre = c;
        t.radius = r;
        t.conifer = conifer;
        if (conifer) {
            t.height = std::clamp(r * m_rng.uniformf(5.5f, 7.5f) + m_rng.uniformf(0.0f, 3.0f), 6.0f, 34.0f);
            t.crownBase = t.height * m_rng.uniformf(0.12f, 0.4f);
        } else {
            t.height = std::clamp(r * m_rng.uniformf(2.6f, 3.6f) + m_rng.uniformf(2.5f, 6.0f), 5.0f, 32.0f);
            t.crownBase = t.height * m_rng.uniformf(0.3f, 0.5f);
        }
        t.seed = static_cast<std::uint32_t>(m_rng.next());
        m_trees.insert(int(m_o.trees.size()), c, c);
        m_o.trees.push_back(t);
        return true;
    }
    /// Same, given a layout-space point.
    bool plantLayout(glm::vec2 q, float r, bool conifer, std::uint32_t allowed, float closeness) {
        return plant(m_l.warp.toLocal(q), r, conifer, allowed, closeness);
    }

private:
    const Layout& m_l;
    Objects& m_o;
    Buckets m_trees, m_buildings;
    Rng m_rng;
};

// Trees along a layout-space segment at `offset` metres to its left, every `step()` metres.
template <class Step, class Plant> void alongSegment(glm::vec2 a, glm::vec2 b, float offset, const Step& step, const Plant& fn) {
    const float len = glm::length(b - a);
    if (len < 1.0f) return;
    const glm::vec2 t = (b - a) / len;
    for (float u = 0.5f * step(); u < len; u += step()) fn(a + t * u + perpLeft(t) * offset);
}

glm::vec2 randomIn(Rng& rng, const std::vector<glm::vec2>& poly) {
    glm::vec2 lo(1e30f), hi(-1e30f);
    for (glm::vec2 v : poly) {
        lo = glm::min(lo, v);
        hi = glm::max(hi, v);
    }
    return glm::vec2(rng.uniformf(lo.x, hi.x), rng.uniformf(lo.y, hi.y));
}

void plantForest(Planter& pl, const Layout& l, const Parcel& p) {
    Rng& rng = pl.rng();
    const GroundRecord& rec = l.records[p.record];
    const std::uint32_t allowed = bit(Ground::ForestFloor);
    if (rec.variant == 3) {
        // Conifer plantation: rows along the stand's grain, a few gaps.
        const glm::vec2 ax = p.grain, ac = perpLeft(ax);
        const float rowStep = rng.uniformf(3.8f, 4.8f), step = rng.uniformf(3.4f, 4.2f), r0 = rng.uniformf(1.9f, 2.5f);
        const glm::vec2 eu = projectExtent(p.poly, ax), ev = projectExtent(p.poly, ac);
        for (float v = ev.x + 0.5f * rowStep; v < ev.y; v += rowStep)
            for (float u = eu.x + 0.5f * step; u < eu.y; u += step) {
                const glm::vec2 q = ax * (u + rng.uniformf(-0.35f, 0.35f)) + ac * (v + rng.uniformf(-0.35f, 0.35f));
                const float r = r0 * rng.uniformf(0.85f, 1.12f);
                if (insideDistance(p.poly, q) > 0.5f && !rng.chance(0.07)) pl.plantLayout(q, r, true, allowed, 0.0f);
            }
        return;
    }
    const int attempts = int(p.area / (kPi * 3.8f * 3.8f) * 8.0f);
    for (int i = 0; i < attempts; ++i) {
        const glm::vec2 q = randomIn(rng, p.poly);
        if (insideDistance(p.poly, q) < 0.0f) continue;
        bool conifer = false;
        if (rec.variant == 2) conifer = rng.chance(0.9);
        else if (rec.variant == 1) conifer = valueNoise(q.x / 45.0f, q.y / 45.0f, rec.seed) + rng.uniformf(-0.3f, 0.3f) > 0.25f;
        else conifer = rng.chance(0.04);
        const float r = conifer ? rng.uniformf(2.0f, 3.4f) : 2.5f + 3.5f * std::pow(rng.uniformf(0.0f, 1.0f), 1.3f);
        pl.plantLayout(q, r, conifer, allowed, conifer ? 0.75f : 0.66f); // a nearly closed canopy
    }
}

} // namespace

void placeVegetation(const Layout& l, Objects& o, float sceneHalf) {
    Planter pl(l, o);
    Rng& rng = pl.rng();

    // Avenues and street trees; hedgerows along hedge cuts.
    for (const Cut& c : l.cuts) {
        if (c.avenue && (c.kind == CutKind::MainRoad || c.kind == CutKind::Street)) {
            const float step = rng.uniformf(9.0f, 14.0f), r0 = rng.uniformf(3.0f, 5.0f);
            const float off = c.roadHalf + (c.kind == CutKind::MainRoad ? 1.2f : 1.0f);
            for (float side : {-1.0f, 1.0f})
                alongSegment(c.a, c.b, side * off, [&] { return step; },
                             [&](glm::vec2 q) { pl.plantLayout(q, r0 * rng.uniformf(0.9f, 1.1f), false, kGreen, 0.0f); });
        } else if (c.kind == CutKind::Hedge) {
            alongSegment(c.a, c.b, 0.0f, [&] { return rng.uniformf(2.5f, 6.0f); }, [&](glm::vec2 q) {
                if (rng.chance(0.12)) return;
                const float r = rng.chance(0.2) ? rng.uniformf(4.5f, 7.0f) : rng.uniformf(1.6f, 3.8f);
                const glm::vec2 t = glm::normalize(c.b - c.a);
                pl.plantLayout(q + perpLeft(t) * rng.uniformf(-0.9f, 0.9f), r, rng.chance(0.04), kOpenLand, 0.55f);
            });
        }
    }

    // Gardens, parks, farmstead groves, solitary pasture trees.
    for (const Parcel& p : l.parcels) {
        if (p.use == LandUse::Village && p.role != ParcelRole::Sports && p.role != ParcelRole::Parking) {
            const int n = p.role == ParcelRole::Park ? int(p.area / 260.0f) : rng.index(4);
            for (int i = 0, tries = 0; i < n && tries < 8 * n + 8; ++tries) {
                const glm::vec2 q = randomIn(rng, p.poly);
                if (insideDistance(p.poly, q) < 1.5f) continue;
                const bool conifer = rng.chance(p.role == ParcelRole::Park ? 0.15 : 0.25);
                const float r = conifer ? rng.uniformf(1.5f, 3.0f)
                                        : (p.role == ParcelRole::Park ? rng.uniformf(3.0f, 7.0f) : rng.uniformf(2.0f, 5.0f));
                if (pl.plantLayout(q, r, conifer, bit(Ground::Lawn), 0.7f)) ++i;
            }
        } else if (p.role == ParcelRole::Farmstead && !p.features.empty()) {
            const Feature& yard = p.features[0];
            const glm::vec2 ac = perpLeft(yard.axis);
            const glm::vec2 h = yard.half + glm::vec2(rng.uniformf(5.0f, 9.0f));
            const glm::vec2 corners[4] = {yard.centre - yard.axis * h.x - ac * h.y, yard.centre + yard.axis * h.x - ac * h.y,
                                          yard.centre + yard.axis * h.x + ac * h.y, yard.centre - yard.axis * h.x + ac * h.y};
            for (int k = 0; k < 4; ++k)
                alongSegment(corners[k], corners[(k + 1) % 4], 0.0f, [&] { return rng.uniformf(7.0f, 12.0f); },
                             [&](glm::vec2 q) {
                                 if (!rng.chance(0.8)) return;
                                 pl.plantLayout(q, rng.uniformf(4.0f, 7.0f), rng.chance(0.15), kGreen, 0.6f);
                             });
        } else if (p.use == LandUse::Farm && l.records[p.record].cls == Ground::Meadow) {
            const int n = int(p.area / 25000.0f * rng.uniformf(0.0f, 1.6f));
            for (int i = 0; i < n; ++i) {
                const glm::vec2 q = randomIn(rng, p.poly);
                if (insideDistance(p.poly, q) > 8.0f) pl.plantLayout(q, rng.uniformf(4.0f, 7.0f), false, bit(Ground::Meadow), 1.0f);
            }
        }
    }

    // Alders and willows along the river banks, in runs with gaps.
    const River& rv = l.river;
    const float reach = 1.5f * l.halfExtent;
    for (float side : {-1.0f, 1.0f}) {
        bool run = true;
        for (float u = -reach; u < reach; u += rng.uniformf(4.0f, 10.0f)) {
            if (rng.chance(0.12)) run = !run;
            if (!run) continue;
            const glm::vec2 q = rv.centre(u) + rv.normal(u) * (side * (rv.halfWidth + rng.uniformf(0.5f, 3.5f)));
            pl.plantLayout(q, rng.uniformf(2.5f, 6.0f), false,
                           kOpenLand | bit(Ground::Bank) | bit(Ground::Fallow), 0.65f);
        }
    }

    for (const Parcel& p : l.parcels)
        if (p.use == LandUse::Forest) plantForest(pl, l, p);

    // Small scenes may miss a class entirely: plant a few of each near the scene centre so that both truth masks
    // are never empty.
    for (bool conifer : {false, true}) {
        auto count = [&] {
            int n = 0;
            for (const Tree& t : o.trees)
                n += t.conifer == conifer && std::abs(t.centre.x) < sceneHalf && std::abs(t.centre.y) < sceneHalf;
            return n;
        };
        const float span = std::max(sceneHalf - 4.0f, 1.0f);
        for (int tries = 0, have = count(); have < 3 && tries < 2000; ++tries) {
            const glm::vec2 c(rng.uniformf(-span, span), rng.uniformf(-span, span));
            const float r = conifer ? rng.uniformf(1.8f, 3.0f) : rng.uniformf(2.5f, 5.0f);
            have += pl.plant(c, r, conifer, kOpenLand | bit(Ground::Bank), 0.6f);
        }
    }
}

} // namespace seasonview::synth
