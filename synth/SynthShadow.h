#pragma once
// Cast shadows of one season: terrain, buildings, cars and crowns on a height field, swept along the sun's azimuth,
// band by band.
#include "SynthObjects.h"
#include "SynthRaster.h"
#include "SynthTerrain.h"

#include <glm/vec3.hpp>

#include <cstdint>
#include <vector>

namespace seasonview::synth {

enum ShadowBits : std::uint8_t {
    kShadowOpaque = 1, // the sun is blocked (terrain, roofs, cars, conifers, leaf-on crowns, leaf-off trunks)
    kShadowWeak = 2,   // the sun ray passes through a leafless crown: thin, weak shadow
};

/// Shadow bits of one season. `towardSun` is the unit vector to the sun (x east, y north, z up) and must lie within
/// 45° of due north or south in azimuth (|x| <= |y|), as for midday survey flights. In leaf-off, deciduous crowns
/// block the sun only at their trunk and cast a weak shadow otherwise; the ground under a leafless crown is what
/// receives light there.
///
/// A sheared sweep: the extended grid's rows are processed away from the sun and every pixel belongs to exactly one
/// ray (ray = column - round(step * k)), so each ray carries its running shadow height with no diffusion,
/// O(pixels). The sweep is exact whatever the shadow length (a hill shadows as far as it does): the state of the
/// rays is carried from band to band, and saved at band boundaries (checkpoints) when the bands are painted in the
/// other direction. Rays are independent, so they are split between threads without changing a bit.
class ShadowSweep {
public:
    /// Keeps references to `objects` and `terrain`, which must outlive the sweep. The state starts empty (before
    /// the first row in sweep order).
    ShadowSweep(const PixelGrid& grid, const ObjectIds& ids, const Objects& objects, const Terrain& terrain,
                glm::vec3 towardSun, bool leafOn);

    /// Whether the sweep visits extended rows in increasing order (sun in the north: shadows fall south).
    bool increasingRows() const { return m_rowStep > 0; }

    /// Sweeps every row of `rows` in sweep order, continuing from the current state: the rows swept since the
    /// state was empty (or since the checkpoint restored) must be exactly those that precede `rows` in sweep order.
    /// When `bits` is not null it receives rows.rows × grid.size bytes: ShadowBits of the imagery columns of each
    /// row of `rows`, first row first.
    void sweep(const ObjectRows& rows, std::uint8_t* bits, int threads);

    /// The state of the rays that extended rows [r0, r1) cross.
    struct Checkpoint {
        size_t firstRay = 0;
        std::vector<double> top, weakLo, weakHi; // weak* stay empty in leaf-on (no weak casters)
    };
    /// Saves what sweeping rows [r0, r1) next will need.
    Checkpoint save(int r0, int r1) const;
    /// Makes the state what it was at save(): afterwards sweep() may be called for the rows passed to save().
    void restore(const Checkpoint& checkpoint);

private:
    int stepOf(int row) const { return m_rowStep > 0 ? row : m_grid.extSize() - 1 - row; }
    long shiftOf(int step) const;
    void rayRange(int r0, int r1, size_t& first, size_t& end) const;

    PixelGrid m_grid;
    ObjectIds m_ids;
    const Objects& m_objects;
    const Terrain& m_terrain;
    bool m_leafOn = true;
    int m_rowStep = 1;
    double m_k = 0.0, m_drop = 0.0, m_eps = 0.0;
    std::vector<double> m_top, m_weakLo, m_weakHi; // per ray, "lifted" heights (see SynthShadow.cpp)
};

} // namespace seasonview::synth
