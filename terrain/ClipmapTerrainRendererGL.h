#pragma once
// The terrain draped with the imagery clipmaps (Ropinski et al. 2007 §2): every fragment picks its clipmap level
// from screen-space derivatives and falls back to coarser levels where blocks are not loaded yet. Geometry: the GPU
// geometry clipmaps (GeometryClipmapGL.h); imagery is draped by world position, so imagery and geometry LOD are
// independent.
#include "Camera.h"
#include "ClipmapGL.h"
#include "GeometryClipmapGL.h"
#include "Scene.h"
#include "TerrainMeshGL.h"
#include "gl/RenderTarget.h"
#include "gl/ShaderProgram.h"

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

namespace seasonview {

/// What the imagery shows. CLI names: leafon, leafoff, blend, swipe, lod (imagery clipmap level colours), wireframe
/// (geometry clipmap triangles in their level's colour over the dimmed leaf-on), levels (geometry level colours),
/// relief (the terrain alone, shaded grey from its normals: no imagery fetched), canopy (the ground of the stacked
/// canopy: leaf-off under the treetops, leaf-on elsewhere; the layers themselves are foliage/CanopyRendererGL.h).
enum class ImageryView { LeafOn, LeafOff, Blend, Swipe, Lod, Wireframe, Levels, Relief, Canopy };
std::optional<ImageryView> parseImageryView(const std::string& name);
const char* imageryViewName(ImageryView v);

/// How the terrain's fragments are shaded (ImagerySettings::path). Auto: Deferred on a software rasteriser, where
/// the geometry clipmap's small triangles have each pixel shaded several times (llvmpipe shades whole 4 × 4 blocks
/// once per triangle touching them), Forward on a GPU, where the resolve's full-screen pass and G-buffer cost more
/// than they save (docs/gpu.md: the leaf-on view 1.7× slower deferred at 1920 × 1080 on an NVIDIA H200).
enum class TerrainShading { Auto, Forward, Deferred };
std::optional<TerrainShading> parseTerrainShading(const std::string& name); // "auto", "forward", "deferred"
const char* terrainShadingName(TerrainShading t);
/// Forward or Deferred: Auto resolved for the current context's renderer (needs a current context).
TerrainShading resolveTerrainShading(TerrainShading t);
/// The same for a renderer named by its GL_RENDERER string (no context needed).
TerrainShading resolveTerrainShading(TerrainShading t, const std::string& glRenderer);

/// The canopy view's marched layers (foliage/CanopyRendererGL.h, CanopyDrawMode::March) for the deferred resolve to
/// march (shaders/terrain_resolve.frag, variant CANOPY_MARCH; common_canopy_march.glsl): the top layer's record of
/// where the rays enter the stack (two RGBA32F textures at half the frame's resolution: the point and plane each frame
/// pixel meets its own ray with) and what sets the march's own uniforms (the stack's heights, the eye, the rays, ...).
/// The crowns take the terrain's anisotropy and shading.
struct CanopyMarchInput {
    GLuint entry[2] = {0, 0};
    std::function<void(const gl::ShaderProgram&)> setUniforms;
};

struct ImagerySettings {
    ImageryView view = ImageryView::LeafOn;
    float blend = 0.5f; // blend: 0 = leaf-on, 1 = leaf-off
    float swipe = 0.5f; // swipe: fraction of the width showing leaf-on (left), the rest leaf-off
    // Maximum anisotropy of the clipmap's own footprint-assembly filter (probes per pixel, 1 = isotropic).
    float anisotropy = 8.0f;
    float shading = 0.0f; // 0..1: Lambert shading from the elevation clipmap's normals
    // Canopy view: the season of the ground under the treetops and elsewhere (0 leaf-on, 1 leaf-off).
    int groundUnderCanopy = 1;
    int groundElsewhere = 0;
    // Canopy view with stacked layers: > 0 makes the ground draw the lowest layer (leaf-on times this factor, the
    // layers' CanopyDrawSettings::darkest) where the canopy is, so the layers start one above it; 0 without layers.
    float canopyBase = 0.0f;
    // false: draw over what the target holds (colour and depth), e.g. canopy drawn first to hide the ground under it.
    bool clear = true;
    // How the terrain's fragments are shaded: Deferred (a geometry pass records position, derivatives and normal,
    // a full-screen pass shades each pixel once) or Forward (shaded as rasterised, every 4x4 block a small triangle
    // touches: several times per pixel where triangles are small), or Auto (resolveTerrainShading: deferred on a
    // software rasteriser, forward on a GPU). The same pixels either way; wireframe and levels are always forward.
    TerrainShading path = TerrainShading::Auto;
    // false: the pass only clears (when `clear`) and draws nothing, so what follows (the city) is drawn alone, as
    // Buchholz & Döllner 2005 §6 timed the facades without terrain.
    bool terrain = true;
    // Canopy view, deferred (resolvesDeferred()): the marched layers' entry record, marched in the resolve, which then
    // shows each pixel's crown or ground and writes its depth (one full-screen pass for both). Null: none.
    const CanopyMarchInput* canopyMarch = nullptr;
};

/// A per-texel canopy layer the ground pass can read (foliage/CanopyClipmapGL.h implements it): binds the samplers
/// of shaders/common_canopy.glsl to units firstUnit .. firstUnit + 2.
class CanopySource {
public:
    virtual ~CanopySource() = default;
    virtual void bind(const gl::ShaderProgram& program, int firstUnit) const = 0;
};
/// Texture units of the terrain passes: imagery clipmap 0.., elevation and lookup 8..12, canopy 13..15, G-buffer
/// 16..18 (position, footprint, depth), the canopy march's entry record 19..20 (kCanopyEntryUnit).
inline constexpr int kCanopyUnit = 13;
/// The SSBO binding of the canopy view's record of the canopy blocks its lookups read (shaders/common_view.glsl,
/// canopyAtNoting; foliage/CanopyClipmapGL.h reads it back).
inline constexpr int kCanopyReadsBinding = 3;
inline constexpr int kGBufferUnit = 16; // the deferred resolve's G-buffer: 16, 17 and 18
inline constexpr int kCanopyEntryUnit = 19;
inline constexpr float kMaxAnisotropy = 16.0f;

/// The colours of `--view lod`, level 0 first (paper Fig. 2: red, green, blue, ...).
extern const float kLevelColors[8][3];

/// Per-frame level statistics from the GPU (same definitions as clipmap/ClipmapCenters.h's CPU estimate).
struct FrameLevelStats {
    double coverage = 0.0;          // terrain pixels whose used level <= the level their footprint needs
    double meanLevelDeficit = 0.0;  // mean of max(0, used - needed)
    std::vector<double> usedLevelHistogram; // fraction of terrain pixels per used level
    std::int64_t terrainPixels = 0;
};

class ClipmapTerrainRendererGL {
public:
    /// `clipmap` layers: 0 = leaf-on, 1 = leaf-off. Keeps a reference to it and to `scene`. `elevation`: the DEM's
    /// pyramid (null: a flat scene).
    static Result<std::unique_ptr<ClipmapTerrainRendererGL>> create(const Scene& scene, const ClipmapGL& clipmap,
                                                                    const ImagePyramid* elevation,
                                                                    const GeometryClipmapOptions& options = {});

    /// Places the geometry levels around the camera and streams their elevation (within the budget).
    ClipmapFrameStats updateGeometry(const Camera& camera, int viewportHeight);
    /// Waits for the elevation blocks of the current placement (stills).
    ClipmapFrameStats completeGeometry();

    GeometryFrameStats render(const Camera& camera, const ImagerySettings& settings, const gl::RenderTarget& target) const;
    /// Whether render() shades `settings` deferred (a geometry pass, then a full-screen resolve).
    static bool resolvesDeferred(const ImagerySettings& settings) {
        return resolveTerrainShading(settings.path) == TerrainShading::Deferred && settings.view != ImageryView::Wireframe &&
               settings.view != ImageryView::Levels;
    }

    /// Renders the level-statistics pass into `scratch` (same size as the frame) and reduces it.
    FrameLevelStats measureLevels(const Camera& camera, const gl::RenderTarget& scratch) const;

    /// The canopy the `canopy` view's ground reads (null: none, the ground is all `groundElsewhere`). Kept by
    /// reference.
    void setCanopy(const CanopySource* canopy) { m_canopy = canopy; }
    /// Binds everything terrain_geometry.vert + terrain_clipmap.frag read (clipmap, elevation, canopy) and sets
    /// uViewProj: for other passes over the same geometry (the canopy layers).
    void bindTerrain(const gl::ShaderProgram& program, const glm::dmat4& viewProj) const;

    /// A program of `vertex` + `fragment` with `defines` and the layouts of this renderer's clipmaps (imagery and
    /// elevation, layoutDefines()), built when first asked for and kept: for the passes over this terrain's geometry
    /// and clipmaps (the canopy layers, the trunks). A shader that does not compile is a bug here (the same sources
    /// compiled in create()): it aborts.
    const gl::ShaderProgram& program(const char* vertex, const char* fragment,
                                     const std::vector<std::string>& defines) const;

    /// Triangles drawn by the last frame (after culling).
    std::int64_t triangles() const { return m_last.triangles; }
    const GeometryClipmapGL& geometry() const { return *m_geometry; }

private:
    ClipmapTerrainRendererGL(const ClipmapGL& clipmap) : m_clipmap(clipmap) {}
    /// The uniforms of a view's programs (forward and resolve) from the settings.
    void setViewUniforms(const gl::ShaderProgram& prog, const ImagerySettings& s, float swipeX) const;
    /// render() with deferred shading: the geometry pass into the G-buffer, then the resolve (per swipe side).
    GeometryFrameStats renderDeferred(const Camera& camera, const ImagerySettings& s, const gl::RenderTarget& target,
                                      bool normals, float swipeX) const;
    /// Draws the terrain with `program`, culling pieces outside NDC x in `ndcX` (the part of the frame drawn).
    GeometryFrameStats draw(const gl::ShaderProgram& program, const Camera& camera, const gl::RenderTarget& target,
                            glm::dvec2 ndcX = {-1.0, 1.0}) const;

    const ClipmapGL& m_clipmap;
    const CanopySource* m_canopy = nullptr;
    std::unique_ptr<GeometryClipmapGL> m_geometry;
    mutable GeometryFrameStats m_last;
    /// Programs of terrain_geometry.vert + terrain_clipmap.frag (and of the deferred resolve) with the given defines,
    /// each built when first drawn: VIEW, SWIPE_SEASON and NORMALS are compile-time constants
    /// (shaders/common_view.glsl says why), so every view is its own program.
    Result<const gl::ShaderProgram*> buildProgram(const char* vertex, const char* fragment,
                                                  const std::vector<std::string>& defines) const;
    std::vector<std::string> m_layoutDefines; // the clipmaps' layouts as compile-time constants
    std::vector<std::string> viewDefines(ImageryView view, int swipeSeason) const;
    bool m_seasonsComplete = false; // both seasons read as they are, no nodata: no fallback to the other season
    /// The deferred pass's G-buffer at the target's size, sharing its depth buffer.
    void ensureGBuffer(const gl::RenderTarget& target) const;
    mutable std::map<std::string, gl::ShaderProgram> m_programs;
    mutable gl::Framebuffer m_gbuffer;
    mutable gl::Texture m_gPosition, m_gFootprint; // RGBA32F: (p, dFdx p), (dFdy p, normal xy)
    mutable gl::Texture m_gDepth;                  // R32F: the depth, for the canopy march's resolve
    mutable glm::ivec2 m_gbufferSize{0};
    mutable GLuint m_gbufferDepth = 0;
    mutable gl::VertexArray m_emptyVao;
    gl::Buffer m_noCanopyReads; // bound for common_view.glsl's record of canopy levels read when there is no canopy
};

} // namespace seasonview
