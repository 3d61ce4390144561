#pragma once
// Deterministic randomness for the synthetic scene generator (`seasonview synth`): a splitmix64 stream, integer
// hashes and hash-based value noise. No std:: distributions anywhere (their output is implementation-defined), so
// a seed gives the same scene with every standard library; every per-pixel value is a pure function of position
// and seed, so the output does not depend on how rows are split between threads.
#include <cmath>
#include <cstdint>

namespace seasonview::synth {

constexpr std::uint64_t splitmix64(std::uint64_t x) {
    x += 0x9E3779B97F4A7C15ull;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
}

/// Derives an independent seed from a seed and a key (e.g. the seed of object i).
constexpr std::uint64_t mixSeed(std::uint64_t seed, std::uint64_t key) {
    return splitmix64(seed ^ (splitmix64(key) + 0x632BE59BD9B4E019ull));
}

/// 32-bit integer finaliser (lowbias32): good avalanche for lattice and per-pixel hashes.
constexpr std::uint32_t hash32(std::uint32_t x) {
    x ^= x >> 16;
    x *= 0x7FEB352Du;
    x ^= x >> 15;
    x *= 0x846CA68Bu;
    x ^= x >> 16;
    return x;
}

constexpr std::uint32_t hash2(std::int32_t x, std::int32_t y, std::uint32_t seed) {
    return hash32(static_cast<std::uint32_t>(x) * 0x9E3779B1u ^ hash32(static_cast<std::uint32_t>(y) ^ seed));
}

/// A hash mapped to [0,1).
constexpr float unitFloat(std::uint32_t h) { return static_cast<float>(h >> 8) * (1.0f / 16777216.0f); }

/// Sequential random numbers for the (single-threaded) layout stage.
class Rng {
public:
    explicit Rng(std::uint64_t seed) : m_state(splitmix64(seed)) {}

    std::uint64_t next() {
        m_state += 0x9E3779B97F4A7C15ull;
        return splitmix64(m_state);
    }
    /// Uniform in [0,1), 53 random bits.
    double uniform() { return static_cast<double>(next() >> 11) * (1.0 / 9007199254740992.0); }
    double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
    float uniformf(float lo, float hi) { return static_cast<float>(uniform(lo, hi)); }
    bool chance(double p) { return uniform() < p; }
    /// Uniform integer in [0, n), n > 0.
    int index(int n) { return static_cast<int>((next() >> 32) * static_cast<std::uint64_t>(n) >> 32); }
    /// Roughly normal (Irwin-Hall of 4 uniforms), mean 0, standard deviation 1, bounded by +-3.46.
    double normalish() { return (uniform() + uniform() + uniform() + uniform() - 2.0) * 1.7320508075688772; }

private:
    std::uint64_t m_state;
};

/// Value noise in [-1,1] with lattice spacing 1: hashed lattice values, smoothstep-interpolated.
inline float valueNoise(float x, float y, std::uint32_t seed) {
    const float fx = std::floor(x), fy = std::floor(y);
    const auto ix = static_cast<std::int32_t>(fx), iy = static_cast<std::int32_t>(fy);
    float tx = x - fx, ty = y - fy;
    tx = tx * tx * (3.0f - 2.0f * tx);
    ty = ty * ty * (3.0f - 2.0f * ty);
    const float v00 = unitFloat(hash2(ix, iy, seed)), v10 = unitFloat(hash2(ix + 1, iy, seed));
    const float v01 = unitFloat(hash2(ix, iy + 1, seed)), v11 = unitFloat(hash2(ix + 1, iy + 1, seed));
    const float a = v00 + (v10 - v00) * tx, b = v01 + (v11 - v01) * tx;
    return 2.0f * (a + (b - a) * ty) - 1.0f;
}

/// Fractal sum of `octaves` value-noise octaves (lacunarity ~2, given gain), normalised to [-1,1].
inline float fbm(float x, float y, std::uint32_t seed, int octaves, float gain = 0.5f) {
    float sum = 0.0f, amp = 1.0f, norm = 0.0f;
    for (int o = 0; o < octaves; ++o) {
        sum += amp * valueNoise(x, y, seed + static_cast<std::uint32_t>(o) * 0x68E31DA4u);
        norm += amp;
        amp *= gain;
        // Rotate a little between octaves so lattice artefacts do not line up.
        const float nx = 1.60f * x - 1.20f * y + 19.1f, ny = 1.20f * x + 1.60f * y - 7.3f;
        x = nx;
        y = ny;
    }
    return sum / norm;
}

/// Hermite smoothstep of t between e0 and e1 (e0 may exceed e1 for a falling edge).
constexpr float smoothstep(float e0, float e1, float t) {
    float x = (t - e0) / (e1 - e0);
    x = x < 0.0f ? 0.0f : (x > 1.0f ? 1.0f : x);
    return x * x * (3.0f - 2.0f * x);
}

} // namespace seasonview::synth
