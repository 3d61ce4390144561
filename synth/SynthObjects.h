#pragma once
// The 3D objects of a synthetic scene — trees, buildings, cars — and the two steps that place them.
// Trees live in the local frame (metres from the scene centre, x east, y north) so that their crowns are exact
// discs; buildings and cars live in layout space like the ground they stand on (see SynthLayout.h).
#include "SynthLayout.h"

#include <glm/vec2.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace seasonview::synth {

struct Tree {
    glm::vec2 centre{0.0f};   // local frame, metres
    float radius = 3.0f;      // crown radius in plan view, metres
    float height = 15.0f;     // crown top above the ground, metres
    float crownBase = 6.0f;   // crown bottom above the ground, metres
    bool conifer = false;
    std::uint32_t seed = 0;

    /// Height (metres above ground) of the crown's upper surface at squared plan distance d2 < radius² from the
    /// centre: a spheroid cap for deciduous trees, a cone for conifers.
    float surface(float d2) const {
        const float rho2 = d2 / (radius * radius);
        if (conifer) return height - (height - crownBase) * std::sqrt(rho2);
        const float mid = 0.5f * (height + crownBase);
        return mid + (height - mid) * std::sqrt(std::max(0.0f, 1.0f - rho2));
    }
};

enum class Roof : std::uint8_t { Gable, Hip, Flat };
enum class RoofMaterial : std::uint8_t { RedTile, BrownTile, Anthracite, GreyTile, FibreCement, Gravel, Bitumen, Sedum };

struct Building {
    glm::vec2 centre{0.0f}, axis{1.0f, 0.0f};  // layout space; axis = ridge direction (unit)
    glm::vec2 half{5.0f};                      // half extents along the axis and across it, metres
    float eave = 5.0f, ridge = 9.0f;           // metres above the ground
    Roof roof = Roof::Gable;
    RoofMaterial material = RoofMaterial::RedTile;
    bool greenLeafOnOnly = false;  // green roof in leaf-on only: a false positive for Ropinski 2007 §4.1's rule
    bool solar = false;            // photovoltaic panels on the sun-facing roof plane
    std::uint32_t seed = 0;

    /// Roof height (metres above ground) at roof coordinates u (along axis), v (across), |u|<half.x, |v|<half.y.
    float roofHeight(float u, float v) const {
        const float slope = (ridge - eave) / half.y;
        switch (roof) {
        case Roof::Gable: return eave + (half.y - std::abs(v)) * slope;
        case Roof::Hip: return eave + std::min(half.y - std::abs(v), half.x - std::abs(u)) * slope;
        case Roof::Flat: return eave;
        }
        return eave;
    }
};

/// Car body colours (palette in SynthPaint.cpp). The green ones appear in one season only.
enum class CarColour : std::uint8_t { White, Black, Silver, Grey, Blue, Red, DarkGreen, BrightGreen, Beige, Count };

struct Car {
    glm::vec2 centre{0.0f}, axis{1.0f, 0.0f};  // layout space; axis = driving direction (unit)
    std::uint8_t seasons = 3;                  // bit 0: present in leaf-on, bit 1: present in leaf-off
    CarColour colour = CarColour::White;
    std::uint32_t seed = 0;
    static constexpr float kHalfLength = 2.2f, kHalfWidth = 0.9f, kHeight = 1.5f;
};

struct Objects {
    std::vector<Tree> trees;
    std::vector<Building> buildings;
    std::vector<Car> cars;
};

/// Settlement step: village parcels become house lots (house, garage, driveway, terrace, cars), one sports ground
/// (pitch, tennis courts), park (pond) and parking lot (store, parked cars) per village; some farm parcels become
/// farmsteads. Adds ground features to `layout`, buildings and cars to `objects`; street and road traffic too.
void placeSettlement(Layout& layout, Objects& objects);

/// Vegetation step: forest stands (including conifer plantations in rows), hedgerows, avenues, street trees,
/// gardens, parks, river banks, farmstead groves, solitary pasture trees. Any two trees i, j satisfy
/// |ci - cj| >= max(ri, rj) + 0.5 m, so no crown covers another tree's centre; no tree stands on a building.
/// Trees of each type (at least 3 deciduous and 3 conifers) are guaranteed inside [-sceneHalf, sceneHalf]².
void placeVegetation(const Layout& layout, Objects& objects, float sceneHalf);

/// Block city for benchmarks (Buchholz's thesis §4.7.1: 10,000 block buildings): replaces everything in a square
/// around the scene centre with blocks of 4 × 2 buildings (16 m × 12 m, 3 to 10 storeys, mostly flat roofs) between
/// 12 m streets, `count` buildings in all, on pavement; trees, cars and buildings in the square are removed. The
/// square is as small as the count allows (about 0.38 km² per 1000 buildings).
void placeBlockCity(Layout& layout, Objects& objects, int count, std::uint64_t seed);

} // namespace seasonview::synth
