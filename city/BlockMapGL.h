#pragma once
// A BlockMap on the GPU (Cignoni et al. 2007 §3.2): its height, distance and column maps as integer textures, its
// wall columns and normals as colour textures, drawn by ray casting in a fragment shader (shaders/blockmap.frag, the
// copy of BlockMap.cpp's traceBlockMap) over its bounding box's back faces, writing each hit's colour and depth so it
// composes with the terrain and the polygons drawn around it.
#include "BlockMap.h"
#include "Camera.h"
#include "gl/GlObjects.h"
#include "gl/RenderTarget.h"
#include "gl/ShaderProgram.h"

#include <memory>

namespace seasonview::city {

class BlockMapGL {
public:
    /// Texture units a map's textures are bound to: kUnit .. kUnit + kTextures - 1 (past the terrain's, so the
    /// ROOF_IMAGERY program samples the clipmaps on theirs).
    static constexpr int kUnit = 22, kTextures = 6;

    /// The program that draws maps (shaders/blockmap.*): with `roofImagery` its ROOF_IMAGERY variant (bind the
    /// terrain's clipmaps to it: ClipmapTerrainRendererGL::bindTerrain), with `frontFaces` its FRONT_FACES variant
    /// (for boxes the eye is well outside of: begin(..., true)). A shader that does not build is a bug.
    static Result<gl::ShaderProgram> buildProgram(bool roofImagery, bool frontFaces = false);
    /// Whether a box drawn from `eye` needs its back faces (the eye inside it, or within `margin` metres: its front
    /// faces would be clipped by the near plane).
    bool needsBackFaces(const glm::dvec3& eye, double margin) const;
    /// Uploads `map` (kept on the GPU only), drawn with its own program. Errors: its wall columns do not fit the GPU's
    /// textures, the shaders do not build (a bug).
    static Result<std::unique_ptr<BlockMapGL>> create(const BlockMap& map);
    /// The same, drawn with `program` (buildProgram(); kept by reference), with its walls as `walls` lays them out
    /// (layOutWalls on a loader thread; null, or laid out for a wider texture than this GL's: laid out here).
    static Result<std::unique_ptr<BlockMapGL>> create(const BlockMap& map, const gl::ShaderProgram& program,
                                                      const BlockMapWallLayout* walls = nullptr);

    struct DrawSettings {
        glm::vec3 roofColour{0.6f, 0.55f, 0.5f};
        bool outputKind = false; // colour (kind, 0, 0, 1): 0.5 a roof, 1 a wall (tests)
    };
    /// Draws into `target` over what it holds, depth-tested (reversed Z, GL_GREATER) and writing depth. Returns the
    /// draw calls (1).
    int draw(const Camera& camera, const gl::RenderTarget& target, const DrawSettings& settings) const;
    int draw(const Camera& camera, const gl::RenderTarget& target) const { return draw(camera, target, DrawSettings{}); }

    /// Many maps with one program: begin() sets what they share and the state (into the bound target; `pixelAngle`:
    /// radians per pixel, which filters the walls' colours), drawOne() draws each, end() restores the state.
    static void begin(const gl::ShaderProgram& program, const glm::dmat4& viewProj, const glm::dvec3& eye,
                      double pixelAngle, const DrawSettings& settings, bool frontFaces = false);
    void drawOne() const { drawOne(*m_program); }
    void drawOne(const gl::ShaderProgram& program) const;
    static void end();

    /// GPU bytes of its textures.
    std::uint64_t bytes() const { return m_bytes; }

private:
    BlockMapGL() = default;
    std::unique_ptr<gl::ShaderProgram> m_ownProgram;
    const gl::ShaderProgram* m_program = nullptr;
    gl::Texture m_height, m_distance, m_column, m_wall, m_normal, m_roofNormal;
    gl::VertexArray m_vao;
    glm::dvec2 m_origin{0.0};
    double m_texel = 1.0, m_zBase = 0.0, m_zTop = 1.0;
    int m_size = 0;
    int m_columnsPerRow = 1, m_wallTexels = 1, m_wallSpan = 1;
    std::uint64_t m_bytes = 0;
};

} // namespace seasonview::city
