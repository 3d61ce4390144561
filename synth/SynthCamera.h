#pragma once
// Sun, sky and camera of one season of a synthetic scene: what makes the two images of a pair differ beyond the
// vegetation (Ropinski 2007 §4.1: "the lighting conditions may differ drastically"): sun elevation and azimuth,
// irradiance colour, exposure, white balance, haze, flight-strip brightness steps and sensor noise.
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <array>
#include <cstdint>
#include <vector>

namespace seasonview::synth {

struct SeasonLook {
    bool leafOn = true;
    float sunElevationDeg = 55.0f, sunAzimuthDeg = 150.0f; // azimuth clockwise from north
    glm::vec3 towardSun{0.0f, 0.0f, 1.0f};                 // unit, x east, y north, z up
    glm::vec3 sun{1.0f};        // direct irradiance on a surface facing the sun (relative units, RGB)
    glm::vec3 sky{0.15f};       // diffuse sky irradiance on a horizontal surface
    float exposure = 2.0f;      // radiance -> linear camera signal
    glm::vec3 whiteBalance{1.0f};
    float haze = 0.05f;         // fraction of the signal replaced by airlight (varies ±50% over the scene)
    glm::vec3 airlight{0.2f};   // path radiance colour, in radiance units
    float noiseDn = 1.5f;       // sensor noise standard deviation at mid grey, digital numbers
    float stripWidth = 700.0f, stripOffset = 0.0f; // east-west flight strips with slightly different gains
    std::uint32_t seed = 0;
};

/// The look of one season, drawn from the seed: leaf-on = August late morning (sun 50-60° high, azimuth 137-165°),
/// leaf-off = March around noon (sun 19-27° high, azimuth 172-208°), hazier and exposed differently. In the southern
/// hemisphere the sun is in the north (azimuth + 180°). The azimuth always lies within 45° of the meridian.
SeasonLook makeSeasonLook(bool leafOn, std::uint64_t seed, bool southernHemisphere);

/// Maps linear camera signal to 8-bit digital numbers: sRGB encoding with a soft highlight shoulder.
class ToneCurve {
public:
    ToneCurve();
    /// Digital number (0..255, not rounded) of a linear signal >= 0.
    float operator()(float v) const {
        const int i = static_cast<int>(v * kScale);
        return m_lut[static_cast<size_t>(i < 0 ? 0 : (i >= kSize ? kSize - 1 : i))];
    }

private:
    static constexpr int kSize = 16384;
    static constexpr float kScale = 8192.0f; // covers signals 0..2
    std::vector<float> m_lut;
};

/// Flight-strip gain of the look at local northing y (metres): steps of a few percent, blended over 30 m.
float stripGain(const SeasonLook& look, float y);

} // namespace seasonview::synth
