#include "SynthMaterials.h"

#include "SynthRandom.h"

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>

namespace seasonview::synth {

namespace {

using glm::vec3;
constexpr float kTwoPi = 6.28318530718f;

// Distance from x to the nearest multiple of `period`.
float periodic(float x, float period) { return std::abs(x - period * std::floor(x / period + 0.5f)); }

vec3 grassOn(float h) { return glm::mix(vec3(0.058f, 0.10f, 0.038f), vec3(0.072f, 0.11f, 0.045f), h); }
vec3 grassOff(float h) { return glm::mix(vec3(0.068f, 0.083f, 0.045f), vec3(0.08f, 0.09f, 0.05f), h); }

struct Local {
    float u, v;          // along / across the record's axis, metres from its origin
    float h1, h2, h3;    // per-record random numbers in [0,1)
};

vec3 soilOf(const Local& l, const GroundNoise& n) {
    // Loamy to sandy soils, darker where moist.
    const vec3 soil = glm::mix(vec3(0.125f, 0.098f, 0.074f), vec3(0.17f, 0.14f, 0.105f), l.h3);
    return soil * (1.0f - 0.18f * smoothstep(0.1f, 0.8f, n.coarse));
}

// Tractor tramlines: pairs of wheel tracks 1.8 m apart every 18-24 m across the crop.
float tramline(const Local& l, float gsd) {
    const float period = 18.0f + 3.0f * std::floor(l.h2 * 3.0f);
    const float d = periodic(l.v - period * l.h1, period);
    return lineCoverage(d - 0.9f, 0.45f, gsd);
}

vec3 cropOrSoil(const GroundRecord& r, const Local& l, bool on, const GroundNoise& n, float gsd) {
    const vec3 soil = soilOf(l, n);
    const float tex = 1.0f + 0.06f * n.fine + 0.05f * n.grain;
    if (r.cls == Ground::WinterCrop && !on) {
        // March: young cereal rows over soil, denser in places.
        const float cover = std::clamp(0.6f + 0.3f * n.coarse + 0.12f * n.mid, 0.15f, 0.95f);
        const vec3 a = glm::mix(soil, vec3(0.045f, 0.10f, 0.03f) * (0.9f + 0.2f * l.h1), cover);
        return glm::mix(a, soil, 0.8f * tramline(l, gsd)) * tex;
    }
    if (r.cls == Ground::WinterCrop) {
        // August: stubble with straw swaths, ploughed, or ripe grain still standing.
        if (r.variant == 0) {
            const vec3 straw = vec3(0.30f, 0.25f, 0.15f) * (0.9f + 0.2f * l.h1);
            const vec3 a = glm::mix(straw, vec3(0.40f, 0.34f, 0.21f), lineCoverage(periodic(l.v, 7.5f), 1.4f, gsd));
            return glm::mix(a, soil, 0.5f * tramline(l, gsd)) * (1.0f + 0.1f * n.fine + 0.06f * n.grain + 0.06f * n.mid);
        }
        if (r.variant == 1) return soil * (1.0f + 0.13f * std::sin(kTwoPi * l.v / 0.9f) + 0.08f * n.mid) * tex;
        const vec3 ripe = vec3(0.32f, 0.26f, 0.13f) * (0.92f + 0.16f * l.h1) * (1.0f - 0.12f * smoothstep(0.3f, 0.9f, n.coarse));
        return glm::mix(ripe, soil, 0.7f * tramline(l, gsd)) * (1.0f + 0.05f * n.mid) * tex;
    }
    if (on) {
        // Summer crops in August: maize (dark, closed canopy), sugar beet (bright), potatoes (rows over ridges).
        if (r.variant == 0)
            return vec3(0.04f, 0.09f, 0.027f) * (1.0f + 0.08f * std::sin(kTwoPi * l.v / 0.75f) + 0.18f * n.mid) * tex;
        if (r.variant == 1) return vec3(0.055f, 0.125f, 0.04f) * (1.0f + 0.15f * n.mid) * tex;
        const float rows = 0.65f + 0.3f * std::sin(kTwoPi * l.v / 0.75f);
        const vec3 leaves = glm::mix(vec3(0.05f, 0.11f, 0.035f), vec3(0.12f, 0.12f, 0.05f), smoothstep(0.2f, 0.9f, n.coarse));
        return glm::mix(soil, leaves, rows) * tex;
    }
    // Summer-crop fields in March: bare ploughed, harrowed or ridged soil.
    const float period = r.variant == 0 ? 1.0f : 0.75f, amp = r.variant == 1 ? 0.04f : 0.14f;
    return soil * (1.0f + amp * std::sin(kTwoPi * l.v / period) + 0.08f * n.mid) * tex;
}

vec3 roadAlbedo(const GroundRecord& r, const Local& l, bool on, const GroundNoise& n, float gsd) {
    const float av = std::abs(l.v), half = r.half.x;
    const float tex = 1.0f + 0.10f * n.mid + 0.07f * n.fine + 0.10f * n.grain;
    const vec3 paint(0.6f, 0.6f, 0.58f);
    const vec3 green = on ? grassOn(l.h1) : grassOff(l.h1);
    switch (r.cls) {
    case Ground::MainRoad: {
        const vec3 asphalt = vec3(0.085f, 0.085f, 0.09f) * (on ? 1.0f : 1.18f) *
                             (1.0f - 0.2f * smoothstep(0.55f, 0.75f, n.coarse)) * tex; // patched repairs
        const float dash = periodic(l.u, 9.0f) < 1.5f ? lineCoverage(l.v, 0.15f, gsd) : 0.0f;
        const float edge = lineCoverage(av - (half - 0.45f), 0.2f, gsd);
        return glm::mix(asphalt, paint, std::max(dash, edge));
    }
    case Ground::Street: {
        const vec3 asphalt = vec3(0.10f, 0.10f, 0.102f) * (on ? 1.0f : 1.12f) * tex;
        const vec3 walk = vec3(0.19f, 0.18f, 0.165f) * (1.0f + 0.04f * n.mid + 0.04f * n.grain);
        const vec3 a = av < half - 1.8f ? asphalt : walk;
        return glm::mix(a, vec3(0.3f, 0.3f, 0.29f), lineCoverage(av - (half - 1.8f), 0.2f, gsd));
    }
    case Ground::Track: {
        const float rut = smoothstep(0.3f, 0.5f, av) * smoothstep(1.25f, 1.0f, av);
        const vec3 dirt = vec3(0.17f, 0.145f, 0.11f) * (1.0f + 0.15f * n.fine + 0.1f * n.grain);
        return glm::mix(green * (1.0f + 0.15f * n.fine), dirt, rut);
    }
    default: {
        const vec3 gravel = vec3(0.19f, 0.17f, 0.14f) * (1.0f + 0.12f * n.fine + 0.12f * n.grain);
        return glm::mix(gravel, on ? green : vec3(0.12f, 0.09f, 0.06f), 0.5f * smoothstep(0.6f, 0.1f, av));
    }
    }
}

vec3 courtAlbedo(const GroundRecord& r, const Local& l, bool on, const GroundNoise& n, float gsd) {
    const auto s = static_cast<CourtSurface>(r.variant);
    const bool green = s == CourtSurface::Green || (s == CourtSurface::LeafOnOnlyGreen && on) ||
                       (s == CourtSurface::LeafOffOnlyGreen && !on);
    if (s == CourtSurface::LeafOnOnlyGreen && !on) // covered for the winter: a pale tarpaulin dome
        return vec3(0.55f, 0.55f, 0.52f) * (1.0f + 0.04f * n.mid - 0.08f * lineCoverage(periodic(l.u, 2.0f), 0.1f, gsd));
    const float au = std::abs(l.u), av = std::abs(l.v);
    const bool inPlay = au < 11.885f && av < 5.485f;
    vec3 a = green ? (inPlay ? vec3(0.075f, 0.16f, 0.065f) : vec3(0.055f, 0.115f, 0.05f)) : vec3(0.33f, 0.13f, 0.07f);
    a *= 1.0f + 0.06f * n.mid + 0.05f * n.grain;
    constexpr float w = 0.08f;
    float line = 0.0f;
    if (av <= 5.53f) line = std::max(line, lineCoverage(au - 11.885f, w, gsd));
    if (au <= 11.93f) line = std::max({line, lineCoverage(av - 5.485f, w, gsd), lineCoverage(av - 4.115f, w, gsd)});
    if (av <= 4.16f) line = std::max(line, lineCoverage(au - 6.40f, w, gsd));
    if (au <= 6.40f) line = std::max(line, lineCoverage(l.v, w, gsd));
    a = glm::mix(a, vec3(0.7f), line);
    if (av < 6.4f) a = glm::mix(a, vec3(0.03f), lineCoverage(l.u, 0.1f, gsd)); // the net
    return a;
}

vec3 pitchAlbedo(const GroundRecord& r, const Local& l, bool on, const GroundNoise& n, float gsd) {
    const float hx = r.half.x, hy = r.half.y, s = hx / 52.5f, au = std::abs(l.u), av = std::abs(l.v);
    const float stripes = std::fmod(std::floor((l.u + hx) / 5.0f), 2.0f) < 1.0f ? 1.06f : 0.94f;
    vec3 a = (on ? vec3(0.05f, 0.12f, 0.035f) : vec3(0.06f, 0.10f, 0.04f)) * stripes * (1.0f + 0.08f * n.mid + 0.05f * n.fine);
    constexpr float w = 0.12f;
    float line = 0.0f;
    if (av <= hy) line = std::max({line, lineCoverage(au - hx, w, gsd), lineCoverage(l.u, w, gsd)});
    if (au <= hx) line = std::max(line, lineCoverage(av - hy, w, gsd));
    line = std::max(line, lineCoverage(std::sqrt(l.u * l.u + l.v * l.v) - 9.15f * s, w, gsd));
    for (const float bx : {16.5f * s, 5.5f * s}) {
        const float by = bx > 10.0f * s ? 20.16f * s : 9.16f * s;
        if (av <= by) line = std::max(line, lineCoverage(au - (hx - bx), w, gsd));
        if (au >= hx - bx) line = std::max(line, lineCoverage(av - by, w, gsd));
    }
    return glm::mix(a, vec3(0.65f), line);
}

} // namespace

GroundNoise groundNoise(glm::vec2 q, std::uint32_t recordSeed, std::uint32_t pixelHash) {
    const float o = float(recordSeed & 1023u) * 7.31f;
    GroundNoise n;
    n.fine = valueNoise(q.x * 1.7f + o, q.y * 1.7f, 0xA511u);
    n.mid = valueNoise(q.x / 3.5f + o, q.y / 3.5f, 0xB522u);
    n.coarse = valueNoise(q.x / 30.0f + o, q.y / 30.0f, 0xC533u);
    n.grain = unitFloat(pixelHash) * 2.0f - 1.0f;
    return n;
}

glm::vec3 groundAlbedo(const GroundRecord& r, glm::vec2 q, bool on, const GroundNoise& n, float gsd) {
    const glm::vec2 d = q - r.origin;
    const Local l{glm::dot(d, r.axis), glm::dot(d, perpLeft(r.axis)), unitFloat(hash32(r.seed)),
                  unitFloat(hash32(r.seed ^ 0x9E3779B9u)), unitFloat(hash32(r.seed ^ 0x7F4A7C15u))};
    const float tex = 1.0f + 0.10f * n.mid + 0.12f * n.fine + 0.08f * n.grain;
    switch (r.cls) {
    case Ground::Meadow: {
        if (!on) return glm::mix(grassOff(l.h1), vec3(0.10f, 0.09f, 0.06f), 0.5f * smoothstep(0.0f, 0.8f, n.coarse)) * tex;
        const float dry = smoothstep(0.1f, 0.7f, n.coarse + 0.4f * (l.h2 - 0.5f));
        vec3 a = glm::mix(grassOn(l.h1), vec3(0.11f, 0.115f, 0.05f), 0.45f * dry) * tex;
        if (r.variant == 1) a *= std::fmod(std::floor(l.v / 3.0f) + 100.0f, 2.0f) < 1.0f ? 1.07f : 0.93f; // mown hay
        if (r.variant == 2) a = glm::mix(a, soilOf(l, n), 0.45f * smoothstep(0.55f, 0.85f, n.mid));  // trampled
        return a;
    }
    case Ground::Lawn: {
        const float stripe = std::fmod(std::floor(l.v / 0.8f) + 1000.0f, 2.0f) < 1.0f ? 1.03f : 0.97f;
        return (on ? vec3(0.055f, 0.10f, 0.04f) * stripe : vec3(0.065f, 0.085f, 0.045f)) * tex;
    }
    case Ground::WinterCrop:
    case Ground::SummerCrop: return cropOrSoil(r, l, on, n, gsd);
    case Ground::Fallow:
        return glm::mix(soilOf(l, n), on ? vec3(0.08f, 0.105f, 0.05f) : vec3(0.11f, 0.10f, 0.07f), 0.5f + 0.35f * n.mid) * tex;
    case Ground::ForestFloor:
        if (on) return vec3(0.03f, 0.055f, 0.022f) * (1.0f + 0.3f * n.mid + 0.1f * n.fine);
        if (r.variant >= 2) return vec3(0.055f, 0.05f, 0.035f) * (1.0f + 0.3f * n.mid + 0.1f * n.fine);
        return vec3(0.12f, 0.085f, 0.055f) * (1.0f + 0.22f * n.mid + 0.12f * n.fine + 0.06f * n.grain);
    case Ground::Margin: {
        const float rough = 1.0f + 0.2f * n.fine;
        if (r.variant == 1) return (on ? vec3(0.05f, 0.08f, 0.03f) : vec3(0.08f, 0.07f, 0.05f)) * tex * rough;
        return (on ? vec3(0.068f, 0.10f, 0.042f) : vec3(0.085f, 0.085f, 0.055f)) * tex * rough;
    }
    case Ground::Bank: // reeds and tall herbs: lush in summer, straw-coloured in March
        return (on ? vec3(0.055f, 0.09f, 0.035f) : vec3(0.12f, 0.105f, 0.07f)) * tex * (1.0f + 0.25f * n.fine);
    case Ground::MainRoad:
    case Ground::Street:
    case Ground::Track:
    case Ground::ForestTrack: return roadAlbedo(r, l, on, n, gsd);
    case Ground::Paving: {
        if (r.variant == 2) { // parking lot: asphalt with stall lines
            const float au = std::abs(l.u), v = l.v;
            const bool stalls = (v > -15.5f && v < -5.5f) || (v > 1.5f && v < 11.5f);
            float line = stalls && au < r.half.x - 0.5f ? lineCoverage(periodic(l.u + r.half.x, 2.5f), 0.12f, gsd) : 0.0f;
            line = std::max({line, lineCoverage(v + 10.5f, 0.12f, gsd), lineCoverage(v - 6.5f, 0.12f, gsd)});
            return glm::mix(vec3(0.10f, 0.10f, 0.105f) * (1.0f + 0.08f * n.mid + 0.08f * n.grain), vec3(0.6f), line);
        }
        const vec3 base = r.variant == 0 ? vec3(0.22f, 0.21f, 0.19f) : vec3(0.25f, 0.16f, 0.11f);
        return base * (1.0f + 0.06f * n.mid + 0.06f * n.grain);
    }
    case Ground::Yard:
        return vec3(0.24f, 0.23f, 0.21f) * (1.0f + 0.08f * n.mid + 0.06f * n.grain) *
               (1.0f - 0.3f * smoothstep(0.2f, 0.9f, n.coarse + 0.3f * n.mid));
    case Ground::Water: {
        // Dark, olive in summer (algae, turbidity), greyer in March; slow ripples and drifting patches.
        const vec3 base = r.variant == 1 ? vec3(0.02f, 0.032f, 0.022f)
                                         : (on ? vec3(0.015f, 0.024f, 0.019f) : vec3(0.018f, 0.024f, 0.026f));
        return base * (1.0f + 0.12f * n.mid + 0.05f * n.fine + 0.15f * n.coarse);
    }
    case Ground::Court: return courtAlbedo(r, l, on, n, gsd);
    case Ground::Pitch: return pitchAlbedo(r, l, on, n, gsd);
    }
    return vec3(0.1f);
}

} // namespace seasonview::synth
