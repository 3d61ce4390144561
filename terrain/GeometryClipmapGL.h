#pragma once
// GPU geometry clipmaps (Asirvatham & Hoppe 2005, GPU Gems 2 ch. 2): nested rings of n×n vertices around the
// viewer, drawn from a few static vertex/index buffers (one per piece shape: m×m block, fix-ups, trims; the outer
// edge stitched to the coarser level by degenerate triangles, made in the vertex shader by moving its odd vertices
// onto even ones, RingLayout::stitchedVertex), heights fetched in the vertex shader from an elevation clipmap (an R32F ClipmapGL
// streamed from the DEM's pyramid like the imagery), transition regions blending heights and normals towards the
// coarser level, per-piece view-frustum culling. Triangles drawn do not depend on the DEM's size: the levels are
// laid out in metres down to GeometryClipmapOptions::finestCellMetres whatever the DEM's spacing (levels finer than
// the DEM take bilinear heights from its finest level, the upsampling of §2.3.4 without synthesised detail), the
// finest drawn follows the viewer's height above the terrain, the coarsest is the one covering the scene, and pieces
// outside the imagery (whose fragments would be discarded) are culled like those outside the frustum.
#include "Camera.h"
#include "ClipmapGL.h"
#include "ElevationPyramid.h"
#include "GeometryClipmap.h"
#include "Scene.h"
#include "gl/GlObjects.h"
#include "gl/ShaderProgram.h"

#include <glm/mat2x2.hpp>
#include <glm/mat4x4.hpp>

#include <cmath>
#include <functional>
#include <map>
#include <memory>
#include <utility>
#include <vector>

namespace seasonview {

struct GeometryClipmapOptions {
    int n = 255;                             // vertices per level side, 2^k − 1
    // DEM levels: at least this many, more when the grid or the imagery needs them to be covered from anywhere in
    // it (geometryLevelCount).
    int levels = 1;
    // Geometry levels go down to cells of this size (metres), or the DEM's spacing where that is finer: a coarse
    // DEM gets upsampled levels (bilinear heights) so the mesh, and the triangle count, follow the screen and not
    // the DEM's resolution (GPU Gems 2 ch. 2 §2.1: n and the level count set the triangle budget, whatever the DEM).
    double finestCellMetres = 0.5;
    int elevationClipSize = 512;             // texels per toroidal elevation level (>= n + 2 block margins)
    std::int64_t uploadBudgetTexels = 1 << 18; // elevation texels per frame
    // Vertices per level side of the rings drawInstanced() draws (stacked canopy layers), 2^k − 1, at most n: the
    // same levels around the viewer with 4× coarser cells at a given distance and 1/16 of the triangles per level
    // (31 is cheaper still, but its layers cut into hilly terrain).
    int layerN = 63;
    // drawPatches(): the layer rings' pieces cut into patches of at most this many cells per side, each with its own
    // instances, so stacked layers are drawn only over the patches whose canopy reaches them.
    int layerPatchCells = 3;
    // false: no transition blending and no edge triangles between levels, for showing the cracks they close
    // (tests); never for rendering.
    bool stitchLevels = true;
};

struct GeometryFrameStats {
    std::int64_t triangles = 0; // drawn this frame (after culling), degenerate ones included
    int drawCalls = 0;
    int piecesCulled = 0;
    int levelsDrawn = 0;
};

class GeometryClipmapGL {
public:
    /// `elevation`: the DEM's pyramid (prepareElevation...), or null for a flat scene. Needs a GL 4.5 context.
    static Result<std::unique_ptr<GeometryClipmapGL>> create(const Scene& scene, const ElevationGrid& grid,
                                                             const ImagePyramid* elevation,
                                                             const GeometryClipmapOptions& options = {});

    /// Places the levels around the camera and moves the elevation clipmap with them (uploads within budget).
    ClipmapFrameStats update(const Camera& camera, int viewportHeight);
    /// Waits for every elevation block the current placement needs (stills, tests).
    ClipmapFrameStats completeSynchronously();

    /// Binds the elevation clipmap (units firstUnit .. firstUnit + 3) and the local->image lookup
    /// (firstUnit + 4) and sets the uniforms of terrain_geometry.vert.
    void bind(const gl::ShaderProgram& program, int firstUnit) const;
    /// The elevation clipmap's layout as ELEV_CLIP_* definitions for programs that fetch heights
    /// (shaders/common_elevation.glsl); none for a flat scene.
    std::vector<std::string> layoutDefines() const {
        return m_elevation ? m_elevation->layoutDefines("ELEV_CLIP_") : std::vector<std::string>{};
    }
    /// Draws the pieces inside the frustum with `program` (bound by the caller, bind() called).
    GeometryFrameStats draw(const gl::ShaderProgram& program, const glm::dmat4& viewProj) const;

    /// Instances over one patch: level, its box in the local frame (metres, x east, y north, z the terrain's heights
    /// within two of the level's cells around it, before any lift); appends one (a, b) per instance to draw over it,
    /// none to skip it. The vertex shader gets ivec4(patch x0, patch y0, a, b) as the per-instance attribute 1
    /// (`aInstance`, level cells).
    using PatchInstances = std::function<void(int level, glm::dvec3 lo, glm::dvec3 hi, std::vector<glm::ivec2>& out)>;
    /// The rings of options.layerN vertices cut into patches of at most options.layerPatchCells² cells, each patch
    /// culled against the frustum with its box raised by up to `lift` metres and drawn as `instances` says (stacked
    /// layers, foliage/): per level and patch shape one instanced draw, its instances in descending order of a.
    GeometryFrameStats drawPatches(const gl::ShaderProgram& program, const glm::dmat4& viewProj, double lift,
                                   const PatchInstances& instances) const;

    /// Placement in geometry levels g = 0 .. levelCount() − 1, coordinates in units of 2^−subLevels() DEM samples:
    /// level g has cells of 2^(g − subLevels()) DEM samples (the first subLevels() levels are finer than the DEM).
    const GeometryPlacement& placement() const { return m_placement; }
    int levelCount() const { return m_levels; }
    int subLevels() const { return m_subLevels; }
    /// Metres per cell of geometry level g.
    double cellMetres(int g) const { return std::ldexp(m_grid.spacing, g - m_subLevels); }
    const ElevationGrid& grid() const { return m_grid; }
    std::int64_t residentBytes() const { return m_elevation ? m_elevation->residentBytes() : 0; }
    /// The elevation clipmap's first unreadable block (ClipmapGL::readError), if any.
    std::optional<ClipmapGL::ReadError> elevationReadError() const {
        return m_elevation ? m_elevation->readError() : std::nullopt;
    }
    std::int64_t totalTexelsUploaded() const { return m_elevation ? m_elevation->totalTexelsUploaded() : 0; }
    std::int64_t loaderCacheBytes() const { return m_elevation ? m_elevation->loaderCacheBytes() : 0; }

private:
    struct Mesh {
        gl::Buffer vertices, indices;
        gl::VertexArray vao;
        GLsizei indexCount = 0;
    };
    GeometryClipmapGL() = default;
    const Mesh& meshFor(int cellsX, int cellsY);
    void drawMesh(const Mesh& mesh, int instances = 1) const;
    GeometryFrameStats drawPieces(const gl::ShaderProgram& program, const glm::dmat4& viewProj, double lift,
                                  const PatchInstances* instances) const;

    const Scene* m_scene = nullptr;
    ElevationGrid m_grid;
    GeometryClipmapOptions m_options;
    RingLayout m_ring;
    RingLayout m_layerRing;             // options.layerN (drawInstanced)
    int m_levels = 1;    // geometry levels, sub-DEM ones included
    int m_subLevels = 0; // geometry levels finer than the DEM's samples
    glm::dvec2 m_imageryMin{0.0}, m_imageryMax{0.0}; // local bounds of the imagery (culling)
    HeightBounds m_bounds = HeightBounds::flat(0.0f); // per-piece culling boxes
    std::unique_ptr<ClipmapGL> m_elevation;
    std::vector<glm::ivec2> m_elevationLevelSizes;
    std::map<std::pair<int, int>, Mesh> m_meshes;
    std::map<std::pair<int, int>, Mesh> m_patchMeshes; // drawPatches(): binding 1 = m_instances, divisor 1
    mutable gl::Buffer m_instances;                    // re-specified by each drawPatches()
    gl::Texture m_localToImage;
    glm::dvec2 m_lookupMin{0.0}, m_lookupSize{1.0};
    glm::mat2 m_lookupSlope{1.0f};
    GeometryPlacement m_placement;
    GeometryPlacement m_layerPlacement; // the layerN rings around the same viewer, same finest level
};

} // namespace seasonview
