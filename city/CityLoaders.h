#pragma once
// Internal to city/: the format readers behind loadCityModel and the polygon checks they share.
#include "CityModel.h"

#include <map>

namespace seasonview::city::detail {

/// Counts of polygon problems while reading one file, turned into one warning line each.
struct PolygonChecks {
    std::size_t degenerate = 0;
    std::size_t nonPlanar = 0;
    double worstOffPlane = 0.0; // metres
    void addWarnings(CityModel& model) const;
};

/// Adds one polygon, already triangulated (`indices` into `verts`, three per triangle), to the model: skipped when
/// degenerate (fewer than three distinct vertices or no area), warned about when a vertex lies more than
/// max(5 cm, 1 % of its extent) off its Newell plane. `uvs` empty or one per vertex. Zero-area triangles are dropped.
void addPolygon(CityModel& model, const std::vector<glm::dvec3>& verts, const std::vector<glm::dvec2>& uvs,
                const std::vector<unsigned>& indices, int texture, std::uint32_t building, Surface surface,
                PolygonChecks& checks);

/// Triangles of a simple polygon (indices into `verts`, three per triangle): ear clipping in the plane the
/// polygon's Newell normal is closest to, so concave outlines (L-shaped walls, courtyards' rims) come out right;
/// a fan when no ear is left (self-intersecting input). Fewer than 3 vertices: none.
std::vector<unsigned> triangulatePolygon(const std::vector<glm::dvec3>& verts);

/// The surface kind of a triangle from its normal (for sources without semantics): up-facing (> 60° from
/// vertical walls) = roof, down-facing = ground, else wall.
Surface surfaceFromNormal(const TexturedTriangle& tri);

/// Index of a texture file in model.textures (added once per path); -1 when it cannot be used: counted in `missing`
/// (a warning: real models often name textures they do not ship) when the file does not exist, and said in
/// `unreadable` (the first such file; an error: a damaged texture is lost data) when it exists but its header does not
/// read as an image OpenImageIO knows.
int textureIndex(CityModel& model, const std::string& path, bool repeat, std::map<std::string, int>& known,
                 std::vector<std::string>& missing, std::string& unreadable);

Result<CityModel> loadCityGml(const std::string& path, const CityLoadOptions& options);
Result<CityModel> loadObj(const std::string& path, const CityLoadOptions& options);

} // namespace seasonview::city::detail
