#include "BlockMapGL.h"

#include "TerrainMeshGL.h" // kNearPlane

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <string>

namespace seasonview::city {

namespace {

gl::Texture texture2D(GLenum internalFormat, int width, int height, GLenum format, GLenum type, const void* data) {
    gl::Texture t = gl::Texture::create(GL_TEXTURE_2D);
    glTextureStorage2D(t.id(), 1, internalFormat, std::max(width, 1), std::max(height, 1));
    glTextureParameteri(t.id(), GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTextureParameteri(t.id(), GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    if (width > 0 && height > 0 && data) {
        glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
        glTextureSubImage2D(t.id(), 0, 0, 0, width, height, format, type, data);
        glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    }
    return t;
}

} // namespace

Result<std::unique_ptr<BlockMapGL>> BlockMapGL::create(const BlockMap& map) {
    auto program = gl::ShaderProgram::build("blockmap.vert", "blockmap.frag");
    if (!program) return program.error();
    std::unique_ptr<BlockMapGL> b(new BlockMapGL());
    b->m_program = std::move(*program);
    const int n = map.size, columns = map.columns();
    b->m_origin = map.origin;
    b->m_texel = map.texel;
    b->m_zBase = map.zBase;
    b->m_zTop = map.zTop;
    b->m_size = n;
    b->m_height = texture2D(GL_R8UI, n, n, GL_RED_INTEGER, GL_UNSIGNED_BYTE, map.height.data());
    b->m_distance = texture2D(GL_R8UI, n, n, GL_RED_INTEGER, GL_UNSIGNED_BYTE, map.distance.data());
    b->m_column = texture2D(GL_R32UI, n, n, GL_RED_INTEGER, GL_UNSIGNED_INT, map.column.data());
    // Columns in rows of `perRow` (a map may have up to n² of them, past any texture's width): column c's colours at
    // x = (c mod perRow) · wallTexels + j, y = c / perRow; its normal at (c mod perRow, c / perRow).
    GLint maxSize = 0;
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &maxSize);
    const int W = map.wallTexels;
    const int perRow = std::max(1, std::min(std::max(columns, 1), maxSize / std::max(W, 1)));
    const int rows = (columns + perRow - 1) / perRow;
    if (W > maxSize || rows > maxSize)
        return Error{"BlockMap: " + std::to_string(columns) + " wall columns of " + std::to_string(W) +
                     " texels do not fit the GPU's " + std::to_string(maxSize) + "-texel textures"};
    std::vector<std::uint8_t> wall(std::size_t(perRow) * std::size_t(W) * std::size_t(std::max(rows, 1)) * 3, 0);
    std::vector<std::uint8_t> normals(std::size_t(perRow) * std::size_t(std::max(rows, 1)) * 3, 0);
    for (int c = 0; c < columns; ++c) {
        const std::size_t x = std::size_t(c % perRow), y = std::size_t(c / perRow);
        std::copy_n(&map.wallRgb[std::size_t(c) * std::size_t(W) * 3], std::size_t(W) * 3,
                    &wall[(y * std::size_t(perRow) * std::size_t(W) + x * std::size_t(W)) * 3]);
        for (int i = 0; i < 3; ++i)
            normals[(y * std::size_t(perRow) + x) * 3 + std::size_t(i)] =
                std::uint8_t(std::lround((map.wallNormal[std::size_t(c)][i] * 0.5f + 0.5f) * 255.0f));
    }
    b->m_wall = texture2D(GL_RGB8, perRow * W, std::max(rows, 1), GL_RGB, GL_UNSIGNED_BYTE, wall.data());
    b->m_normal = texture2D(GL_RGB8, perRow, std::max(rows, 1), GL_RGB, GL_UNSIGNED_BYTE, normals.data());
    b->m_columnsPerRow = perRow;
    b->m_wallTexels = W;
    b->m_vao = gl::VertexArray::create();
    return b;
}

int BlockMapGL::draw(const Camera& camera, const gl::RenderTarget& target, const DrawSettings& s) const {
    target.bind();
    const double aspect = double(target.width()) / double(target.height());
    const glm::dmat4 viewProj = camera.projectionMatrix(aspect, kNearPlane) * camera.viewMatrix();
    const gl::ShaderProgram& p = m_program;
    p.set("uViewProj", glm::mat4(viewProj));
    const double side = double(m_size) * m_texel;
    p.set("uBoxMin", glm::vec3(glm::dvec3(m_origin, m_zBase)));
    p.set("uBoxMax", glm::vec3(glm::dvec3(m_origin + side, m_zTop)));
    p.set("uBmOrigin", glm::vec2(m_origin));
    p.set("uBmTexel", float(m_texel));
    p.set("uBmSize", m_size);
    p.set("uBmZBase", float(m_zBase));
    p.set("uBmZTop", float(m_zTop));
    p.set("uEye", glm::vec3(camera.position));
    p.set("uRoofColour", s.roofColour);
    p.set("uSunDir", glm::vec3(glm::normalize(glm::dvec3(-0.5, 0.6, 0.75))));
    p.set("uOutputKind", s.outputKind ? 1 : 0);
    p.set("uBmColumnsPerRow", m_columnsPerRow);
    p.set("uBmWallTexels", m_wallTexels);
    const GLuint textures[5] = {m_height.id(), m_distance.id(), m_column.id(), m_wall.id(), m_normal.id()};
    const char* names[5] = {"uBmHeight", "uBmDistance", "uBmColumn", "uBmWall", "uBmNormal"};
    for (int i = 0; i < 5; ++i) {
        glBindTextureUnit(GLuint(i), textures[i]);
        p.set(names[i], i);
    }
    p.use();
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_GREATER);
    glEnable(GL_CULL_FACE);
    glCullFace(GL_FRONT); // the back faces: one fragment per pixel, the eye inside the box or not
    glBindVertexArray(m_vao.id());
    glDrawArrays(GL_TRIANGLES, 0, 36);
    glBindVertexArray(0);
    glDisable(GL_CULL_FACE);
    for (int i = 0; i < 5; ++i) glBindTextureUnit(GLuint(i), 0);
    return 1;
}

} // namespace seasonview::city
