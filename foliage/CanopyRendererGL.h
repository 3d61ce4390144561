#pragma once
// The stacked canopy (Ropinski et al. 2007 §4.2): N layers, layer i the terrain's geometry clipmap lifted to
// i / (N − 1) of the tree height; a fragment of layer i stays only where the derived canopy layer
// (CanopyClipmapGL.h) says its texel belongs to layer i, coloured with the leaf-on imagery, darker towards the lower
// layers, its texture coordinates shifted slightly per layer. Layer 0 lies on the ground: the terrain's `canopy`
// view draws it (ImagerySettings::canopyBase). Layers 1 .. N − 1 are instanced draws of the geometry clipmap's
// coarser layer rings (GeometryClipmapOptions::layerN), into the same depth buffer, each piece with only as many
// layers as its stack has pixels on screen (none where the stack is under minLiftPixels).
#include "CanopyClipmapGL.h"
#include "ClipmapTerrainRendererGL.h"
#include "Scene.h"
#include "TrunksGL.h"
#include "gl/GlObjects.h"
#include "gl/RenderTarget.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace seasonview {

/// How the stacked layers are drawn. Layers: each layer is its own lifted copy of the geometry clipmap's patches,
/// rasterised, its fragments kept where the canopy reaches the layer (the paper's §4.2 as written: up to N fragments
/// per pixel). March: only the top layer is rasterised (at half the frame's resolution), recording where the view rays
/// enter the stack (each pixel meets its own ray with the top layer's plane there); one
/// full-screen pass (shaders/canopy_march.frag) intersects each ray with the layers below in turn, over the terrain's
/// local plane, keeping the first layer whose canopy it meets (one march per pixel, N cheap fetches at most; the
/// same layers, exact on planar terrain).
enum class CanopyDrawMode { Layers, March };

struct CanopyDrawSettings {
    CanopyDrawMode mode = CanopyDrawMode::March;
    double treeHeight = 15.0;       // metres: the top layer's lift (the scene's tree_height_m)
    float darkest = 0.5f;           // colour factor of the lowest layer (the top layer keeps the leaf-on colour)
    glm::vec2 shift{0.3f, 0.2f};    // texture shift per layer, level-0 texels (§4.2)
    float anisotropy = 8.0f;        // as the terrain's ImagerySettings
    float shading = 0.0f;
    double minLiftPixels = 1.0;     // pieces where the whole stack is shorter than this on screen get no layers
    double pixelsPerLayer = 1.0;    // elsewhere layers are thinned to about one per this many pixels of stack
    // Metres: 0 = the layers stand on the ground (layer 0 is the ground pass's, ImagerySettings::canopyBase);
    // > 0 = the crowns' base: layers 0 .. N − 1 span crownBase .. treeHeight, trunks stand below (TrunksGL.h).
    double crownBase = 0.0;
    // The scene, for skipping per piece the layers that no canopy texel under it reaches
    // (CanopyClipmapGL::maxValueOver); null: every piece draws up to the top layer.
    const Scene* scene = nullptr;
};

/// Layers to draw (of at most `maxLayers`) for a piece whose box (local metres, z its terrain heights) is seen from
/// `eye`: about one per settings.pixelsPerLayer pixels of the tallest stack on screen over the box, at least 1,
/// none where it is under settings.minLiftPixels.
int canopyPieceLayers(const glm::dvec3& eye, double pixelsPerRadian, const glm::dvec3& lo, const glm::dvec3& hi,
                      const CanopyDrawSettings& settings, int maxLayers);

/// Whether the marched layers draw a patch (box in local metres, z its terrain heights) seen from `eye`: only where
/// every ray into its stack comes down through it faster than the terrain under it can rise (the tangent of the
/// lowest elevation angle over the box above the box's height range over its smaller side widened by `heightMargin`
/// on each side, the metres past the box its heights were taken over, plus 0.05). Rays looking up a slope, along it
/// or level with the crowns would leave the stack through its side, where no top layer is drawn to march from: such
/// patches are rasterised layer by layer instead.
bool canopyPatchMarches(const glm::dvec3& eye, const glm::dvec3& lo, const glm::dvec3& hi, double treeHeight,
                        double heightMargin = 0.0);

/// Which patches a CanopyRendererGL::render call draws.
enum class CanopyPass {
    Marched,    // CanopyDrawMode::March: the patches canopyPatchMarches() accepts, marched (before the ground)
    Rasterised, // the others (all of them in CanopyDrawMode::Layers), every layer rasterised (after the ground)
};

/// The tangent of the lowest elevation angle at which `eye` sees the top of a box's stack (local metres, z its
/// terrain heights, the stack `treeHeight` above them); 0 where the eye is not above it.
double lowestElevationTan(const glm::dvec3& eye, const glm::dvec3& lo, const glm::dvec3& hi, double treeHeight);

/// The canopy level a stacked layer over a box (local metres) reads, from a camera: one level for the whole box, the
/// level of the pixel footprint at its centre, clamped to 0 .. clipLevels (the coarse base), returned as (lowest,
/// highest) = (it, it). The layer shader clamps its level to them, so CanopyClipmapGL::maxValueOver over them bounds
/// what any fragment of the box reads.
class CanopyLevelBounds {
public:
    CanopyLevelBounds(const Camera& camera, double pixelsPerRadian, double texelMetres);
    glm::ivec2 levels(const glm::dvec3& lo, const glm::dvec3& hi, int clipLevels) const;

private:
    glm::dvec3 m_eye;
    double m_pixelsPerRadian, m_texelMetres;
};

class CanopyRendererGL {
public:
    static Result<std::unique_ptr<CanopyRendererGL>> create();

    /// The canopy view whole: the ground (`imagery`, its canopyBase set when layer 0 lies on it), the layers and,
    /// when given, the trunks, in the order that spares the most work. The marched layers' entry record goes first,
    /// and the terrain's deferred resolve marches it (ImagerySettings::canopyMarch: each pixel samples the imagery
    /// once, for its crown or its ground; forward terrain shading: a march pass of its own before the terrain).
    /// Rasterised layers go after the ground, whose pass draws their layer 0 on it.
    GeometryFrameStats renderView(const Camera& camera, const ClipmapTerrainRendererGL& terrain, ImagerySettings imagery,
                                  const CanopyClipmapGL& canopy, const CanopyDrawSettings& settings,
                                  const TrunksGL* trunks, const gl::RenderTarget& target) const;
    /// Draws the patches of `pass` of the canopy.options().layers layers over the frame `terrain` just rendered into
    /// `target` (or, marched, into a target whose depth test state beginTerrainPass() set).
    GeometryFrameStats render(const Camera& camera, const ClipmapTerrainRendererGL& terrain, const CanopyClipmapGL& canopy,
                              const CanopyDrawSettings& settings, const gl::RenderTarget& target, CanopyPass pass) const;

private:
    CanopyRendererGL() = default;
    // The marched pass's record of where the rays enter the stack (common_canopy_march.glsl), at 1 / kEntryScale of
    // the target's resolution in each axis: RGBA32F (p, the plane's normal xy), (entry point, first layer + 256 ×
    // level), its own depth.
    static constexpr int kEntryScale = 2; // common_canopy_march.glsl's kCanopyEntryScale
    void ensureEntry(const gl::RenderTarget& target) const;
    static glm::ivec2 entrySize(const gl::RenderTarget& target) {
        return {(target.width() + kEntryScale - 1) / kEntryScale, (target.height() + kEntryScale - 1) / kEntryScale};
    }
    // The march with forward terrain shading: a full-screen pass before the terrain (with deferred shading the
    // terrain's resolve marches, ImagerySettings::canopyMarch).
    GeometryFrameStats marchForward(const Camera& camera, const ClipmapTerrainRendererGL& terrain,
                                    const CanopyClipmapGL& canopy, const gl::RenderTarget& target) const;
    mutable gl::Framebuffer m_entryFramebuffer;
    mutable gl::Texture m_entry[2];
    mutable gl::Renderbuffer m_entryDepth; // the top layer's own depth: the terrain's geometry pass draws under it
    mutable glm::ivec2 m_entrySize{0};
    mutable gl::VertexArray m_emptyVao;
    mutable CanopyMarchInput m_marchInput; // the entry record and the march's uniforms of the last Marched pass
    mutable bool m_entryRecorded = false;  // the last Marched pass recorded entries (it draws none without layers)
    mutable float m_marchAnisotropy = 8.0f, m_marchShade = 0.0f;
};

} // namespace seasonview
