#pragma once
// The geometry of a multiresolution texture-atlas tree (Buchholz & Döllner 2005; Buchholz's thesis §4.5), plain C++:
// how large each texture must be in a node's atlas so nothing is magnified beyond dmin (§4.5.2 "Texture Size
// Estimation"), the atlas area a texture needs with its repetitions and border ("Computation of the Required Atlas
// Area"), packing those areas into a fixed-size atlas ("Texture Atlas Generation": MAXRECTS with quarter turns, or
// stb_rect_pack's skyline), the area-balanced
// four-way split of a node's triangles (§4.5.3), and the root-atlas texture coordinates with a per-level scale
// (§4.5.4, the texture-matrix trick).
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace seasonview::city {

/// A textured triangle: world positions (metres), texture coordinates (texture units: 1 = one repetition), and the
/// texture it samples.
struct TexturedTriangle {
    std::array<glm::dvec3, 3> v{};
    std::array<glm::dvec2, 3> t{};
    int texture = 0;
};

/// Screen pixels per world metre of a segment facing the camera at distance d: w / (2 d tan(fov / 2)) (§4.5.2; the
/// horizontal field of view `fovXDeg` and screen width `screenWidth` the tree is built for).
double projectionFactor(double dmin, double fovXDeg, int screenWidth);

/// World-space lengths of the texture-space unit vectors (1, 0) and (0, 1) mapped onto the triangle's plane
/// (s_world, t_world of §4.5.2). Degenerate texture coordinates: all equal -> nothing (one colour, 1×1 texel); on one
/// line -> both are the stretch of the longest texture-space edge (|vj - vi| / |tj - ti|). Degenerate positions
/// (zero area) -> zeros: such a triangle never covers a pixel.
struct WorldScale {
    double s = 0.0, t = 0.0;
    bool singleColour = false;
};
WorldScale textureWorldScale(const TexturedTriangle& tri);

/// Texels a whole repetition of the texture needs so that `tri` is not magnified at dmin: ceil(s_world · f_proj)
/// by ceil(t_world · f_proj), at least 1×1.
glm::ivec2 requiredTextureSize(const TexturedTriangle& tri, double fproj);

/// A texture's share of a node's atlas: the texture-space rectangle the node's triangles use (their texture
/// coordinates' bounding box: fractions of one repetition or several repetitions), grown around its centre to
/// include the border, and the texel size it takes in the atlas, border included.
struct AtlasArea {
    int texture = 0;
    glm::dvec2 srcMin{0.0}, srcMax{0.0}; // texture space, border included
    glm::ivec2 size{0};                   // atlas texels, border included
    glm::ivec2 position{0};               // atlas texels (after packing)
    /// How much finer than the stored texels the view would want at dmin: max over the axes of uncapped / capped
    /// texels per repetition (1 when the original's size did not cap it). The ancestors' minDistances grow by it.
    double capFactor = 1.0;
    /// Placed transposed (a quarter turn and a mirror): texture u runs along the atlas's y. Texels and texture
    /// coordinates go through the same map (atlasTexel), so the mirror costs nothing. Set by packing.
    bool rotated = false;
    /// The atlas texels it covers as placed: `size`, transposed when rotated.
    glm::ivec2 footprint() const { return rotated ? glm::ivec2(size.y, size.x) : size; }
    /// Atlas texel of area-local texel coordinates `local` (0..size, texture orientation).
    glm::dvec2 atlasTexel(glm::dvec2 local) const {
        return glm::dvec2(position) + (rotated ? glm::dvec2(local.y, local.x) : local);
    }
};

/// The area of one texture for the triangles `tris` (all of that texture): size = ceil(max(s_world f_proj) · w(A_tex))
/// + 2b by ceil(max(t_world f_proj) · h(A_tex)) + 2b (rounded once, not per repetition); A_tex scaled about its centre by (w + 2b) / w and (h + 2b) / h so the
/// border holds the texture's own neighbouring content (§4.5.2, b = 8). Sizes are multiples of b; a size the
/// original caps snaps to the original's texels (b-texel grid): its atlas texels are the original's, one to one.
/// `maxTexels`: the original texture's size; no texture is stored larger than its original (a finer atlas copy
/// would only magnify it: the cap matters for close dmin and for slivers whose s_world is huge).
AtlasArea requiredAtlasArea(const std::vector<const TexturedTriangle*>& tris, double fproj, int border = 8,
                            glm::dvec2 maxTexels = glm::dvec2(INFINITY));

/// How areas are packed into an atlas.
/// - MaxRects (the default): Jylänki's MAXRECTS with best-short-side fit, global best choice and quarter turns
///   ("A Thousand Ways to Pack the Bin", 2010, §3.3): all maximal free rectangles are kept, each step places the
///   area whose best position leaves the least short-side slack. Facade areas taller than half the atlas pack
///   three or four to an atlas instead of two.
/// - Skyline: stb_rect_pack's skyline bottom-left, largest first, no turns (what the thesis's packer does).
enum class AtlasPacker : std::uint8_t { MaxRects, Skyline };
const char* atlasPackerName(AtlasPacker p);
std::optional<AtlasPacker> parseAtlasPacker(const std::string& name);

/// Packs the areas into an atlasSize² atlas; sets each area's position (and `rotated`). False when they do not all
/// fit. `fill`: the fraction of the atlas the areas cover. Deterministic.
bool packAtlas(std::vector<AtlasArea>& areas, int atlasSize, double* fill = nullptr,
               AtlasPacker packer = AtlasPacker::MaxRects);

/// Splits triangles into four groups along the two longest axes of their bounding box: first into halves of equal
/// summed world area by midpoint along the longest axis, then each half the same way along the second (§4.5.3).
/// Each cut leaves both of its sides non-empty when it has two triangles or more, so repeated splitting always ends
/// (groups of a very small set may be empty). Returns indices into `tris`.
std::array<std::vector<std::uint32_t>, 4> splitByArea(const std::vector<TexturedTriangle>& tris,
                                                      const std::vector<std::uint32_t>& subset);

/// The same split for arbitrary items given by midpoint and area (e.g. whole texture groups, see AtlasTreeBuild).
std::array<std::vector<std::uint32_t>, 4> splitPointsByArea(const std::vector<glm::dvec3>& midpoints,
                                                           const std::vector<double>& areas,
                                                           const std::vector<std::uint32_t>& subset);

double triangleArea(const TexturedTriangle& tri);

/// Root-atlas texture coordinates of a coordinate `t` in [0,1]² of the atlas of the node reached by `path` (child
/// indices from the root: 0 bottom-left, 1 bottom-right, 2 top-left, 3 top-right) (§4.5.4).
glm::dvec2 rootAtlasCoord(glm::dvec2 t, const std::vector<int>& path);
/// The inverse as the shader does it with the level's scale: fract(r · 2^level).
glm::dvec2 levelAtlasCoord(glm::dvec2 root, int level);

} // namespace seasonview::city
