#pragma once
// Ground albedo of a synthetic scene per class and season: linear reflectance in the camera's RGB bands, with the
// texture that keeps classes from being flat colours (mottling, crop rows, tramlines, furrows, mowing stripes,
// road markings, court and pitch lines).
#include "SynthLayout.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <cstdint>

namespace seasonview::synth {

/// Per-pixel noise shared by the ground materials, evaluated once per pixel (values in [-1,1]).
struct GroundNoise {
    float fine = 0.0f;   // ~0.6 m
    float mid = 0.0f;    // ~3.5 m
    float coarse = 0.0f; // ~30 m
    float grain = 0.0f;  // per pixel
};

/// Evaluates the noise at layout point q for a record (each record sees its own shifted copy of the noise).
GroundNoise groundNoise(glm::vec2 q, std::uint32_t recordSeed, std::uint32_t pixelHash);

/// Albedo at layout point q of ground `r` in the given season. `gsd` (metres per pixel) antialiases thin lines.
glm::vec3 groundAlbedo(const GroundRecord& r, glm::vec2 q, bool leafOn, const GroundNoise& n, float gsd);

/// Fraction of a pixel of size `gsd` covered by a line of `width` centred where `dist` is 0 (metres).
inline float lineCoverage(float dist, float width, float gsd) {
    const float c = (0.5f * width - (dist < 0.0f ? -dist : dist)) / gsd + 0.5f;
    return c < 0.0f ? 0.0f : (c > 1.0f ? 1.0f : c);
}

} // namespace seasonview::synth
