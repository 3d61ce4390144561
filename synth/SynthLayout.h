#pragma once
// Vector layout of a synthetic scene: parcels from a recursive binary space partition (BSP) whose cut lines become
// main roads, village streets, farm tracks, hedges and field margins (T-junctions come for free: a child's cut ends
// at its parent's); a meandering river; per-parcel features (driveways, courts, ponds) added by the settlement step.
//
// Everything here lives in *layout space*: the scene's local frame (metres from the scene centre, x east, y north)
// bent by a smooth displacement of a few metres (Warp) so that roads and field edges curve gently. Trees are the
// exception: they are placed in the local frame itself so that their crowns stay exact discs.
#include "SynthPolygon.h"

#include <glm/vec2.hpp>

#include <cstdint>
#include <vector>

namespace seasonview::synth {

/// Ground cover classes. Season behaviour is in SynthMaterials.cpp.
enum class Ground : std::uint8_t {
    Meadow,      // pasture / hay meadow: green in both seasons
    Lawn,        // mown garden and park lawn: green in both seasons
    WinterCrop,  // winter cereal: green in leaf-off (March), stubble / ripe / ploughed in leaf-on (August)
    SummerCrop,  // maize, beet: green in leaf-on, bare ploughed soil in leaf-off
    Fallow,      // bare or weedy soil in both seasons
    ForestFloor, // under a forest canopy
    Margin,      // grass strip along field edges, hedges and road verges
    Bank,        // river bank
    MainRoad,    // two-lane asphalt with markings
    Street,      // village street: asphalt with sidewalks
    Track,       // farm track: two ruts and a grass middle strip
    ForestTrack, // gravel
    Paving,      // driveways, terraces, parking lots
    Yard,        // farmyard concrete
    Water,
    Court,       // tennis court; variant = CourtSurface
    Pitch,       // football pitch: grass with white lines
};

inline bool isRoad(Ground g) {
    return g == Ground::MainRoad || g == Ground::Street || g == Ground::Track || g == Ground::ForestTrack;
}

/// Court surfaces per season. LeafOnOnlyGreen is the paper's false positive (Ropinski 2007 §4.1: "green objects
/// present in the summer texture but not in the winter texture").
enum class CourtSurface : std::uint8_t { Clay, Green, LeafOnOnlyGreen, LeafOffOnlyGreen };

/// One ground record: a parcel, a road, a feature, or a shared class (water, margins). Coordinates in layout space.
struct GroundRecord {
    Ground cls = Ground::Meadow;
    std::uint8_t variant = 0;       // class-specific (crop stage, forest composition, court surface, ...)
    glm::vec2 origin{0.0f};         // feature centre, or a point on a road's centreline
    glm::vec2 axis{1.0f, 0.0f};     // unit: crop rows / road direction / feature long axis
    glm::vec2 half{0.0f};           // feature half extents; roads: x = half width of the whole road
    std::uint32_t seed = 0;         // per-record texture and colour variation
};

enum class LandUse : std::uint8_t { Farm, Forest, Village };
enum class CutKind : std::uint8_t { None, MainRoad, Street, Track, ForestTrack, Hedge, Margin };
/// What the settlement step made of a parcel.
enum class ParcelRole : std::uint8_t { Plain, House, Park, Sports, Parking, Farmstead };

/// A straight cut of the partition, spanning its node's polygon from a to b.
struct Cut {
    glm::vec2 a{0.0f}, b{0.0f};
    glm::vec2 normal{1.0f, 0.0f};
    float offset = 0.0f;            // line: dot(normal, q) == offset
    CutKind kind = CutKind::None;
    float roadHalf = 0.0f;          // |distance| < roadHalf -> roadRecord
    float marginHalf = 0.0f;        // |distance| < marginHalf -> marginRecord (verge, hedge strip, field margin)
    std::uint32_t roadRecord = 0, marginRecord = 0;
    bool avenue = false;            // lined with trees
};

/// A ground feature inside a parcel (first match wins, in insertion order).
struct Feature {
    enum class Shape : std::uint8_t { Rect, Blob };
    Shape shape = Shape::Rect;
    glm::vec2 centre{0.0f}, axis{1.0f, 0.0f}, half{1.0f};
    std::uint32_t record = 0;
    bool contains(glm::vec2 q) const;
};

/// A leaf of the partition.
struct Parcel {
    std::vector<glm::vec2> poly;        // convex, counter-clockwise, layout space
    std::vector<std::int32_t> edgeCut;  // per edge: index into Layout::cuts, -1 on the layout border
    LandUse use = LandUse::Farm;
    ParcelRole role = ParcelRole::Plain;
    glm::vec2 grain{1.0f, 0.0f};        // unit direction of the parcel's long side
    glm::vec2 centroid{0.0f};
    float area = 0.0f;
    std::uint32_t record = 0;
    std::vector<Feature> features;
};

/// Smooth displacement making straight cuts curve: layout = local + d(local), |d| <~ 8 m, |grad d| <~ 0.05.
class Warp {
public:
    Warp() = default;
    Warp(float halfExtent, std::uint64_t seed);
    glm::vec2 toLayout(glm::vec2 local) const;
    /// Inverse by fixed-point iteration (converges since the displacement's gradient is small).
    glm::vec2 toLocal(glm::vec2 layout) const;

private:
    glm::vec2 displacement(glm::vec2 local) const;
    float m_half = 0.0f, m_step = 8.0f;
    int m_n = 0;
    std::vector<glm::vec2> m_d;
};

/// A meandering river of constant width along a straight axis.
struct River {
    glm::vec2 origin{0.0f}, axis{1.0f, 0.0f};
    float amp1 = 0.0f, k1 = 0.0f, phase1 = 0.0f, amp2 = 0.0f, k2 = 0.0f, phase2 = 0.0f;
    float halfWidth = 0.0f, bankWidth = 0.0f;
    /// Approximate distance (metres, layout space) from the centreline: |v - centre(u)| / sqrt(1 + centre'(u)²),
    /// continuous. Where it is certainly >= `limit` a cheaper value >= `limit` may be returned instead, so callers
    /// must not distinguish distances beyond the limit they pass.
    float distance(glm::vec2 q, float limit = 1e30f) const;
    /// Centreline point at along-axis coordinate u and the unit normal there.
    glm::vec2 centre(float u) const;
    glm::vec2 normal(float u) const;
};

struct Layout {
    float halfExtent = 0.0f;   // the layout covers [-halfExtent, halfExtent]^2, local metres
    std::uint64_t seed = 0;
    Warp warp;
    River river;
    std::vector<glm::vec2> villages;  // village centres, layout space
    std::vector<float> villageRadius;
    std::vector<std::int32_t> nodeCut, nodeChild, nodeParcel;  // BSP: per node cut (-1 leaf), 2 children, parcel
    std::vector<Cut> cuts;
    std::vector<Parcel> parcels;
    std::vector<GroundRecord> records;
    std::uint32_t waterRecord = 0, bankRecord = 0;
    /// A block city (placeBlockCity): inside [cityMin, cityMax] (layout space) the ground is pavement.
    bool hasCity = false;
    glm::vec2 cityMin{0.0f}, cityMax{0.0f};
    std::uint32_t cityRecord = 0;

    std::uint32_t addRecord(const GroundRecord& r) {
        records.push_back(r);
        return static_cast<std::uint32_t>(records.size() - 1);
    }
    /// Ground record index at a layout-space point.
    std::uint32_t groundAtLayout(glm::vec2 q) const;
    /// Ground record index at a point of the local frame.
    std::uint32_t groundAt(glm::vec2 local) const { return groundAtLayout(warp.toLayout(local)); }
    /// Index of the parcel containing a layout-space point.
    int parcelAt(glm::vec2 q) const;
};

/// Builds the partition, land use, roads and river for a layout covering [-halfExtent, halfExtent]^2 (metres).
/// Deterministic in (halfExtent, seed).
Layout buildLayout(float halfExtent, std::uint64_t seed);

} // namespace seasonview::synth
