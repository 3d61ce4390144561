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

#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace seasonview {

/// What the imagery shows. CLI names: leafon, leafoff, blend, swipe, lod (imagery clipmap level colours), wireframe
/// (geometry clipmap triangles in their level's colour over the dimmed leaf-on), levels (geometry level colours),
/// relief (the terrain alone, shaded grey from its normals: no imagery fetched).
enum class ImageryView { LeafOn, LeafOff, Blend, Swipe, Lod, Wireframe, Levels, Relief };
std::optional<ImageryView> parseImageryView(const std::string& name);
const char* imageryViewName(ImageryView v);

struct ImagerySettings {
    ImageryView view = ImageryView::LeafOn;
    float blend = 0.5f; // blend: 0 = leaf-on, 1 = leaf-off
    float swipe = 0.5f; // swipe: fraction of the width showing leaf-on (left), the rest leaf-off
    // Maximum anisotropy of the clipmap's own footprint-assembly filter (probes per pixel, 1 = isotropic).
    float anisotropy = 8.0f;
    float shading = 0.0f; // 0..1: Lambert shading from the elevation clipmap's normals
};
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

    /// Renders the level-statistics pass into `scratch` (same size as the frame) and reduces it.
    FrameLevelStats measureLevels(const Camera& camera, const gl::RenderTarget& scratch) const;

    /// Triangles drawn by the last frame (after culling).
    std::int64_t triangles() const { return m_last.triangles; }
    const GeometryClipmapGL& geometry() const { return *m_geometry; }

private:
    ClipmapTerrainRendererGL(const ClipmapGL& clipmap) : m_clipmap(clipmap) {}
    GeometryFrameStats draw(const gl::ShaderProgram& program, const Camera& camera, const gl::RenderTarget& target) const;

    const ClipmapGL& m_clipmap;
    std::unique_ptr<GeometryClipmapGL> m_geometry;
    mutable GeometryFrameStats m_last;
    gl::ShaderProgram m_program, m_statsProgram;
};

} // namespace seasonview
