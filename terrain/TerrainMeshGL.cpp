#include "TerrainMeshGL.h"

namespace seasonview {

TerrainMeshGL::TerrainMeshGL(const ReferenceMesh& mesh)
    : m_vertices(gl::Buffer::create()), m_indices(gl::Buffer::create()), m_vao(gl::VertexArray::create()) {
    glNamedBufferStorage(m_vertices.id(), GLsizeiptr(mesh.vertices.size() * sizeof(ReferenceVertex)),
                         mesh.vertices.data(), 0);
    glNamedBufferStorage(m_indices.id(), GLsizeiptr(mesh.indices.size() * sizeof(std::uint32_t)), mesh.indices.data(),
                         0);
    m_indexCount = GLsizei(mesh.indices.size());
    const GLuint vao = m_vao.id();
    glVertexArrayVertexBuffer(vao, 0, m_vertices.id(), 0, sizeof(ReferenceVertex));
    glVertexArrayElementBuffer(vao, m_indices.id());
    glEnableVertexArrayAttrib(vao, 0);
    glEnableVertexArrayAttrib(vao, 1);
    glVertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, offsetof(ReferenceVertex, x));
    glVertexArrayAttribFormat(vao, 1, 2, GL_FLOAT, GL_FALSE, offsetof(ReferenceVertex, u));
    glVertexArrayAttribBinding(vao, 0, 0);
    glVertexArrayAttribBinding(vao, 1, 0);
}

void TerrainMeshGL::draw() const {
    glBindVertexArray(m_vao.id());
    glDrawElements(GL_TRIANGLES, m_indexCount, GL_UNSIGNED_INT, nullptr);
    glBindVertexArray(0);
}

void beginTerrainPass(float r, float g, float b, float a, bool clear) {
    glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE); // reversed Z: far = 0
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_GREATER);
    glDisable(GL_CULL_FACE);
    glClearColor(r, g, b, a);
    glClearDepth(0.0);
    if (clear) glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
}

} // namespace seasonview
