#include "SynthCamera.h"

#include "SynthRandom.h"

#include <cmath>

namespace seasonview::synth {

SeasonLook makeSeasonLook(bool leafOn, std::uint64_t seed, bool southernHemisphere) {
    Rng rng(mixSeed(seed, leafOn ? 0x5EA50Aull : 0x5EA50Bull));
    SeasonLook l;
    l.leafOn = leafOn;
    l.sunElevationDeg = leafOn ? rng.uniformf(50.0f, 60.0f) : rng.uniformf(19.0f, 27.0f);
    l.sunAzimuthDeg = leafOn ? rng.uniformf(137.0f, 165.0f) : rng.uniformf(172.0f, 208.0f);
    if (southernHemisphere) l.sunAzimuthDeg = std::fmod(l.sunAzimuthDeg + 180.0f, 360.0f);
    const float el = l.sunElevationDeg * 0.0174532925f, az = l.sunAzimuthDeg * 0.0174532925f;
    l.towardSun = glm::vec3(std::sin(az) * std::cos(el), std::cos(az) * std::cos(el), std::sin(el));
    // Low winter sun is redder; its sky contributes relatively more.
    l.sun = leafOn ? glm::vec3(1.0f, 0.98f, 0.93f) : glm::vec3(1.0f, 0.92f, 0.80f);
    l.sky = leafOn ? glm::vec3(0.12f, 0.145f, 0.18f) : glm::vec3(0.15f, 0.165f, 0.19f);
    const float flat = l.sun.g * l.towardSun.z + l.sky.g;
    // Auto exposure normalises the irradiance, imperfectly: the seasons differ in brightness by design.
    l.exposure = 2.2f / flat * (leafOn ? rng.uniformf(0.98f, 1.12f) : rng.uniformf(0.82f, 0.97f));
    l.whiteBalance = leafOn ? glm::vec3(rng.uniformf(0.96f, 1.06f), 1.0f, rng.uniformf(0.94f, 1.04f))
                            : glm::vec3(rng.uniformf(0.92f, 1.04f), 1.0f, rng.uniformf(0.98f, 1.10f));
    l.haze = leafOn ? rng.uniformf(0.03f, 0.07f) : rng.uniformf(0.06f, 0.11f);
    l.airlight = flat * glm::vec3(0.22f, 0.24f, 0.28f);
    l.noiseDn = rng.uniformf(1.2f, 2.0f);
    l.stripWidth = rng.uniformf(550.0f, 900.0f);
    l.stripOffset = rng.uniformf(0.0f, l.stripWidth);
    l.seed = static_cast<std::uint32_t>(rng.next());
    return l;
}

ToneCurve::ToneCurve() : m_lut(kSize) {
    for (int i = 0; i < kSize; ++i) {
        float v = (float(i) + 0.5f) / kScale;
        if (v > 0.8f) v = 0.8f + 0.2f * (1.0f - std::exp(-(v - 0.8f) / 0.2f)); // soft shoulder, never clips hard
        const float s = v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
        m_lut[size_t(i)] = 255.0f * s;
    }
}

float stripGain(const SeasonLook& look, float y) {
    const float s = (y + look.stripOffset) / look.stripWidth;
    const float f = std::floor(s);
    auto gain = [&](float strip) {
        return 1.0f + 0.035f * (2.0f * unitFloat(hash32(static_cast<std::uint32_t>(std::int32_t(strip)) ^ look.seed)) - 1.0f);
    };
    const float blend = smoothstep(0.5f - 15.0f / look.stripWidth, 0.5f + 15.0f / look.stripWidth, s - f);
    // Blend between this strip and the next around the seam halfway through it.
    return gain(f) + (gain(f + 1.0f) - gain(f)) * blend;
}

} // namespace seasonview::synth
