#pragma once
// A ReferenceMesh uploaded for drawing (both the reference and the clipmap renderers draw it until the geometry
// clipmaps arrive): vertex attribute 0 = local position (metres), 1 = leaf-on image coordinates in [0,1].
#include "ReferenceMesh.h"
#include "gl/GlObjects.h"

#include <cstdint>

namespace seasonview {

class TerrainMeshGL {
public:
    explicit TerrainMeshGL(const ReferenceMesh& mesh);
    void draw() const;
    std::int64_t triangles() const { return m_indexCount / 3; }

private:
    gl::Buffer m_vertices, m_indices;
    gl::VertexArray m_vao;
    GLsizei m_indexCount = 0;
};

/// Near plane distance of every terrain pass (metres); with reversed Z, depth = kNearPlane / eye depth.
inline constexpr double kNearPlane = 0.05;

/// Clears the bound framebuffer (colour to r,g,b,a; depth for reversed Z) and sets the depth state every terrain pass
/// uses (glClipControl zero-to-one, GL_GREATER).
void beginTerrainPass(float r, float g, float b, float a, bool clear = true);

} // namespace seasonview
