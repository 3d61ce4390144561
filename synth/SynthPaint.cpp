#include "SynthPaint.h"

#include "SynthMaterials.h"
#include "SynthParallel.h"
#include "SynthRandom.h"
#include "SynthShadow.h"

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cassert>
#include <cmath>

namespace seasonview::synth {

namespace {

using glm::vec3;

// Light falling on a surface: direct sun (cosine, shadow-dimmed) plus sky (scaled by how much sky it sees).
struct Light {
    vec3 sun, sky;
    vec3 operator()(vec3 albedo, float cosSun, float lit, float skyView) const {
        return albedo * (sun * (cosSun * lit) + sky * skyView);
    }
};

float trunkRadius(const Tree& t) { return 0.08f + 0.01f * t.height; }

float litFraction(std::uint8_t bits, glm::vec2 p) {
    if (bits & kShadowOpaque) return 0.0f;
    if (bits & kShadowWeak) // thin twigs: a light, patchy dimming
        return 0.6f - 0.25f * valueNoise(p.x * 3.0f, p.y * 3.0f, 0xD1u);
    return 1.0f;
}

vec3 deciduousAlbedo(std::uint32_t seed) {
    static const vec3 species[] = {{0.045f, 0.092f, 0.030f}, {0.052f, 0.108f, 0.030f}, {0.065f, 0.120f, 0.042f},
                                   {0.065f, 0.100f, 0.055f}, {0.048f, 0.100f, 0.032f}};
    const std::uint32_t h = hash32(seed);
    if ((h & 255u) < 4u) return vec3(0.05f, 0.036f, 0.033f); // copper beech: a treetop that is not green
    return species[(h >> 8) % 5u] * (0.88f + 0.24f * unitFloat(hash32(h)));
}

vec3 coniferAlbedo(std::uint32_t seed, bool leafOn) {
    static const vec3 species[] = {{0.028f, 0.050f, 0.030f}, {0.038f, 0.058f, 0.040f}, {0.025f, 0.048f, 0.032f}};
    const std::uint32_t h = hash32(seed ^ 0xC0F1u);
    const vec3 a = species[h % 3u] * (0.88f + 0.24f * unitFloat(hash32(h)));
    return leafOn ? a : a * vec3(1.06f, 0.95f, 0.92f); // winter needles are a little browner
}

vec3 roofAlbedo(const Building& b, bool leafOn) {
    if (b.greenLeafOnOnly && leafOn)
        return b.material == RoofMaterial::Sedum ? vec3(0.07f, 0.12f, 0.04f) : vec3(0.07f, 0.15f, 0.055f);
    switch (b.material) {
    case RoofMaterial::RedTile: return vec3(0.30f, 0.11f, 0.07f);
    case RoofMaterial::BrownTile: return vec3(0.16f, 0.08f, 0.06f);
    case RoofMaterial::Anthracite: return vec3(0.055f, 0.055f, 0.06f);
    case RoofMaterial::GreyTile: return vec3(0.13f, 0.13f, 0.13f);
    case RoofMaterial::FibreCement: return vec3(0.22f, 0.22f, 0.21f);
    case RoofMaterial::Gravel: return vec3(0.20f, 0.19f, 0.17f);
    case RoofMaterial::Bitumen: return vec3(0.07f, 0.07f, 0.07f);
    case RoofMaterial::Sedum: return vec3(0.12f, 0.075f, 0.055f); // dormant sedum is red-brown
    }
    return vec3(0.1f);
}

vec3 carAlbedo(CarColour c) {
    static const vec3 palette[] = {{0.62f, 0.62f, 0.62f}, {0.025f, 0.025f, 0.028f}, {0.35f, 0.36f, 0.37f},
                                   {0.14f, 0.14f, 0.15f}, {0.03f, 0.06f, 0.18f},    {0.42f, 0.04f, 0.03f},
                                   {0.03f, 0.12f, 0.04f}, {0.12f, 0.35f, 0.06f},    {0.40f, 0.34f, 0.24f}};
    return palette[std::min(size_t(c), std::size(palette) - 1)];
}

struct Painter {
    const PaintInput& in;
    const SeasonLook& look;
    Light light;
    float gsd;

    vec3 ground(std::uint32_t gid, glm::vec2 q, glm::vec2 p, std::uint32_t pixelHash, float cosT, std::uint8_t bits) const {
        const GroundRecord& r = in.layout.records[gid];
        const GroundNoise n = groundNoise(q, r.seed, pixelHash);
        const vec3 a = groundAlbedo(r, q, look.leafOn, n, gsd);
        const float cosSun = r.cls == Ground::Water ? look.towardSun.z : cosT; // water lies flat
        const float skyView = r.cls == Ground::ForestFloor ? 0.6f : 1.0f;
        return light(a, cosSun, litFraction(bits, p), skyView);
    }

    vec3 deciduous(const Tree& t, glm::vec2 p, bool opaqueShadow) const {
        const glm::vec2 d = p - t.centre;
        const float rho2 = glm::dot(d, d) / (t.radius * t.radius);
        const float c = 0.5f * (t.height - t.crownBase);
        const float o = float(t.seed & 1023u) * 3.7f;
        // Spheroid normal bent by leaf clumps (~1.1 m), clump brightness (~0.5 m) for self-occlusion.
        const float gx = valueNoise(p.x / 1.1f + o, p.y / 1.1f, 0xE1u), gy = valueNoise(p.x / 1.1f + o, p.y / 1.1f, 0xE2u);
        const float cl = valueNoise(p.x / 0.5f + o, p.y / 0.5f, 0xE3u);
        const vec3 nrm = glm::normalize(vec3(d.x / t.radius + 0.7f * gx, d.y / t.radius + 0.7f * gy,
                                             std::sqrt(std::max(0.0f, 1.0f - rho2)) * 1.3f * t.radius / c + 0.45f));
        const float ao = (0.72f + 0.28f * cl) * (1.0f - 0.3f * smoothstep(0.8f, 1.0f, rho2) * (cl < -0.2f ? 1.0f : 0.2f));
        const vec3 a = deciduousAlbedo(t.seed) * (0.88f + 0.22f * cl);
        const float lit = opaqueShadow ? 0.0f : 1.0f;
        // Leaves transmit and scatter green light: shaded foliage stays green rather than turning sky-blue.
        const float cosSun = std::max(0.0f, glm::dot(nrm, look.towardSun)) * ao * lit + 0.08f + 0.05f * lit;
        return light(a, cosSun, 1.0f, (0.35f + 0.5f * nrm.z) * ao);
    }

    vec3 leafless(const Tree& t, glm::vec2 p, vec3 below, bool opaqueShadow) const {
        const glm::vec2 d = p - t.centre;
        const float dist = glm::length(d), rho2 = dist * dist / (t.radius * t.radius);
        const glm::vec2 dir = d / std::max(dist, 1e-3f);
        const float o = float(t.seed & 1023u) * 5.3f, rho = std::sqrt(rho2);
        // Radial limbs fanning out (noise around the circle) and a fine twig tangle.
        const float limbs = valueNoise(dir.x * 4.5f + rho * 1.2f + o, dir.y * 4.5f - rho * 0.8f, 0xF1u);
        const float twigs = valueNoise(p.x / 0.25f + o, p.y / 0.25f, 0xF2u);
        float alpha = (0.85f + 0.3f * limbs + 0.25f * twigs) * (1.0f - 0.45f * rho2 * rho);
        if (dist < 1.5f * trunkRadius(t)) alpha = 0.95f; // trunk and the base of the limbs
        alpha = std::clamp(alpha, 0.0f, 0.95f);
        // Twigs lit on the sun side of the crown, the inner tangle in its own shade; high-contrast fine texture.
        const float sunSide = 0.5f + 0.5f * rho * glm::dot(dir, glm::normalize(glm::vec2(look.towardSun)));
        const float tex = std::clamp(0.75f + 0.6f * twigs + 0.25f * limbs, 0.25f, 1.4f);
        const vec3 bark = vec3(0.095f, 0.082f, 0.07f) * (0.85f + 0.3f * unitFloat(hash32(t.seed))) * tex;
        const float cosSun = 0.06f + 0.42f * sunSide;
        return glm::mix(below, light(bark, cosSun, opaqueShadow ? 0.0f : 1.0f, 0.7f), alpha);
    }

    vec3 conifer(const Tree& t, glm::vec2 p, bool opaqueShadow) const {
        const glm::vec2 d = p - t.centre;
        const float dist = glm::length(d), rho = dist / t.radius;
        const glm::vec2 dir = d / std::max(dist, 1e-3f);
        const float o = float(t.seed & 1023u) * 2.9f;
        // A cone lit from the side, with star-like branch tips and whorls.
        const float star = valueNoise(dir.x * 3.5f + o, dir.y * 3.5f, 0xA1u);
        const float fine = valueNoise(p.x / 0.35f + o, p.y / 0.35f, 0xA2u);
        const vec3 nrm = glm::normalize(vec3(dir * (1.6f * std::min(rho * 4.0f, 1.0f)) + glm::vec2(0.3f * star, 0.3f * fine), 1.0f));
        const float whorl = std::sin(rho * t.radius * 7.5f + star);
        float bright = 0.78f + 0.22f * star + 0.08f * whorl + 0.1f * fine;
        if (rho > 0.75f && star < -0.25f) bright *= 0.6f; // gaps between branch tips
        const float lit = opaqueShadow ? 0.0f : 1.0f;
        const float cosSun = std::max(0.0f, glm::dot(nrm, look.towardSun)) * lit + 0.07f + 0.03f * lit; // translucency
        return light(coniferAlbedo(t.seed, look.leafOn) * bright, cosSun, 1.0f, 0.4f + 0.45f * nrm.z);
    }

    vec3 roof(const Building& b, glm::vec2 q, std::uint32_t pixelHash, bool opaqueShadow) const {
        const glm::vec2 d = q - b.centre, across = perpLeft(b.axis);
        const float u = glm::dot(d, b.axis), v = glm::dot(d, across);
        const float slope = (b.ridge - b.eave) / b.half.y;
        vec3 nrm(0.0f, 0.0f, 1.0f);
        float fromEave = std::min(b.half.y - std::abs(v), b.half.x - std::abs(u));
        if (b.roof == Roof::Gable || (b.roof == Roof::Hip && b.half.y - std::abs(v) <= b.half.x - std::abs(u))) {
            nrm = glm::normalize(vec3(across * ((v >= 0.0f ? 1.0f : -1.0f) * slope), 1.0f));
            fromEave = b.half.y - std::abs(v);
        } else if (b.roof == Roof::Hip) {
            nrm = glm::normalize(vec3(b.axis * ((u >= 0.0f ? 1.0f : -1.0f) * slope), 1.0f));
        }
        const float o = float(b.seed & 1023u) * 4.1f;
        const float grain = unitFloat(pixelHash) * 2.0f - 1.0f;
        vec3 a = roofAlbedo(b, look.leafOn) *
                 (1.0f + 0.07f * valueNoise(q.x / 2.5f + o, q.y / 2.5f, 0xB1u) + 0.04f * grain);
        if (b.roof == Roof::Flat) {
            const bool parapet = std::abs(u) > b.half.x - 0.35f || std::abs(v) > b.half.y - 0.35f;
            a = parapet ? vec3(0.26f, 0.26f, 0.25f) : a * (1.0f + 0.12f * valueNoise(q.x * 2.0f + o, q.y * 2.0f, 0xB2u));
        } else {
            a *= 1.0f + 0.04f * std::sin(fromEave * 19.0f);                                // tile courses
            a = glm::mix(a, a * 1.25f, lineCoverage(b.half.y - fromEave, 0.3f, gsd) * 0.6f); // ridge tiles
            a = glm::mix(a, a * 0.55f, lineCoverage(fromEave - 0.1f, 0.2f, gsd));          // gutters
            // Panels on the plane facing the equator-side sun.
            const float facing = glm::dot(across * (v >= 0.0f ? 1.0f : -1.0f), glm::vec2(look.towardSun));
            if (b.solar && b.half.y - std::abs(v) == fromEave && facing > 0.2f && std::abs(u) < b.half.x - 0.8f &&
                std::abs(v) > 0.6f && std::abs(v) < b.half.y - 0.5f) {
                const float frame = std::max(lineCoverage(std::fmod(std::abs(u), 1.05f), 0.06f, gsd),
                                             lineCoverage(std::fmod(std::abs(v) - 0.6f, 1.75f), 0.06f, gsd));
                a = glm::mix(vec3(0.025f, 0.03f, 0.06f), vec3(0.3f), frame);
            }
        }
        const float cosSun = std::max(0.0f, glm::dot(nrm, look.towardSun));
        return light(a, cosSun, opaqueShadow ? 0.0f : 1.0f, 0.55f + 0.45f * nrm.z);
    }

    vec3 car(const Car& c, glm::vec2 q, bool opaqueShadow) const {
        const glm::vec2 d = q - c.centre;
        const float u = glm::dot(d, c.axis), v = std::abs(glm::dot(d, perpLeft(c.axis)));
        vec3 a = carAlbedo(c.colour);
        const bool glass = (u > 0.35f && u < 0.95f && v < 0.72f) || (u > -1.55f && u < -1.25f && v < 0.72f) ||
                           (u > -1.4f && u < 0.9f && v > 0.62f && v < 0.8f);
        if (glass) a = vec3(0.03f, 0.035f, 0.04f);
        if (v > 0.8f) a *= 0.6f; // flanks, facing sideways
        return light(a, look.towardSun.z, opaqueShadow ? 0.0f : 1.0f, 0.8f);
    }
};

} // namespace

void paintRows(const PaintInput& in, const SeasonLook& look, std::vector<std::uint8_t>& rgb, int threads) {
    const ObjectIds& m = in.ids;
    const ObjectRows& objects = in.objectRows;
    const PixelGrid& g = in.grid;
    const int w = g.size;
    assert(objects.row0 <= in.row0 + g.margin && in.row0 + in.rows + g.margin <= objects.row0 + objects.rows &&
           "paintRows(): the object rows do not cover the band");
    rgb.assign(size_t(in.rows) * size_t(w) * 3, 0);
    const ToneCurve tone;
    const Painter painter{in, look, Light{look.sun, look.sky}, g.gsd};
    const Terrain& t = in.terrain;

    parallelChunks(in.rows, 16, threads, [&](int b0, int b1) {
        for (int br = b0; br < b1; ++br) {
            const int r = in.row0 + br; // imagery row
            const float y = g.centreExt(0, r + g.margin).y;
            const float strip = stripGain(look, y);
            const float fy = (t.halfExtent - y) / t.spacing - 0.5f;
            for (int c = 0; c < w; ++c) {
                const size_t pi = size_t(r) * size_t(w) + size_t(c); // global: seeds the per-pixel hashes
                const size_t bi = size_t(br) * size_t(w) + size_t(c);
                const glm::vec2 p = g.centreExt(c + g.margin, r + g.margin);
                const glm::vec2 q = in.layout.warp.toLayout(p);
                const std::uint32_t pixelHash = hash32(static_cast<std::uint32_t>(pi) ^ 0x5BD1E995u);
                const std::uint8_t bits = in.shadow[bi];
                const bool opaque = (bits & kShadowOpaque) != 0;
                const float cosT = t.bilinearRows(in.terrainShade.data(), in.shadeRow0,
                                                  (p.x + t.halfExtent) / t.spacing - 0.5f, fy);
                const std::uint32_t id = objects.object[objects.at(c + g.margin, r + g.margin)];
                vec3 rad;
                if (m.isTree(id)) {
                    const Tree& tree = in.objects.trees[id - 1];
                    if (tree.conifer) rad = painter.conifer(tree, p, opaque);
                    else if (look.leafOn) rad = painter.deciduous(tree, p, opaque);
                    else rad = painter.leafless(tree, p, painter.ground(in.ground[bi], q, p, pixelHash, cosT, bits), opaque);
                } else if (m.isBuilding(id)) {
                    rad = painter.roof(in.objects.buildings[id - m.firstBuilding], q, pixelHash, opaque);
                } else if (m.isCar(id) && (in.objects.cars[id - m.firstCar].seasons & (look.leafOn ? 1 : 2))) {
                    rad = painter.car(in.objects.cars[id - m.firstCar], q, opaque);
                } else {
                    rad = painter.ground(in.ground[bi], q, p, pixelHash, cosT, bits);
                }

                // Camera: haze (patchy), exposure with flight-strip steps, white balance, tone curve, sensor noise.
                const float h = look.haze * (1.0f + 0.5f * valueNoise(p.x / 800.0f, p.y / 800.0f, look.seed));
                const vec3 signal = (rad * (1.0f - h) + look.airlight * h) * (look.exposure * strip) * look.whiteBalance;
                for (int k = 0; k < 3; ++k) {
                    const float dn = tone(signal[k]);
                    const std::uint32_t nh = hash32(static_cast<std::uint32_t>(pi * 3 + size_t(k)) ^ look.seed);
                    const float tri = (float(nh & 0xFFFFu) + float(nh >> 16)) * (1.0f / 65536.0f) - 1.0f; // triangular
                    const float v = dn + tri * 2.449f * look.noiseDn * (0.7f + 0.6f * dn / 255.0f);
                    rgb[bi * 3 + size_t(k)] = static_cast<std::uint8_t>(std::clamp(v + 0.5f, 0.0f, 255.0f));
                }
            }
        }
    });
}

} // namespace seasonview::synth
