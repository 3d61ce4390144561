#include "BlockMapGL.h"

#include "TerrainMeshGL.h" // kNearPlane

#include <glm/geometric.hpp>

#include <algorithm>
#include <optional>
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

Result<gl::ShaderProgram> BlockMapGL::buildProgram(bool roofImagery, bool frontFaces) {
    std::vector<std::string> defines;
    if (roofImagery) defines.push_back("ROOF_IMAGERY");
    if (frontFaces) defines.push_back("FRONT_FACES");
    return gl::ShaderProgram::build("blockmap.vert", "blockmap.frag", defines);
}

bool BlockMapGL::needsBackFaces(const glm::dvec3& eye, double margin) const {
    const double side = double(m_size) * m_texel;
    return eye.x >= m_origin.x - margin && eye.x <= m_origin.x + side + margin && eye.y >= m_origin.y - margin &&
           eye.y <= m_origin.y + side + margin && eye.z >= m_zBase - margin && eye.z <= m_zTop + margin;
}

Result<std::unique_ptr<BlockMapGL>> BlockMapGL::create(const BlockMap& map) {
    auto program = buildProgram(false);
    if (!program) return program.error();
    auto own = std::make_unique<gl::ShaderProgram>(std::move(*program));
    auto b = create(map, *own);
    if (!b) return b.error();
    (*b)->m_ownProgram = std::move(own);
    return b;
}

Result<std::unique_ptr<BlockMapGL>> BlockMapGL::create(const BlockMap& map, const gl::ShaderProgram& program,
                                                       const BlockMapWallLayout* walls) {
    std::unique_ptr<BlockMapGL> b(new BlockMapGL());
    b->m_program = &program;
    const int n = map.size;
    b->m_origin = map.origin;
    b->m_texel = map.texel;
    b->m_zBase = map.zBase;
    b->m_zTop = map.zTop;
    b->m_size = n;
    b->m_height = texture2D(GL_R8UI, n, n, GL_RED_INTEGER, GL_UNSIGNED_BYTE, map.height.data());
    b->m_distance = texture2D(GL_R8UI, n, n, GL_RED_INTEGER, GL_UNSIGNED_BYTE, map.distance.data());
    b->m_column = texture2D(GL_R32UI, n, n, GL_RED_INTEGER, GL_UNSIGNED_INT, map.column.data());
    b->m_roofNormal = texture2D(GL_RG8, n, n, GL_RG, GL_UNSIGNED_BYTE, map.roofNormal.data());
    GLint maxSize = 0;
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &maxSize);
    // The walls as the loader laid them out for this GL's texture width, else laid out here.
    std::optional<BlockMapWallLayout> own;
    if (!walls || walls->maxTextureSize > maxSize) {
        auto laid = layOutWalls(map, maxSize);
        if (!laid) return laid.error();
        own = std::move(*laid);
        walls = &*own;
    }
    const int perRow = walls->perRow, rows = walls->rows, span = walls->span;
    const std::vector<std::uint8_t>& wall = walls->wall;
    const std::vector<std::uint8_t>& normals = walls->normals;
    b->m_wall = texture2D(GL_RGBA8, perRow * span, std::max(rows, 1), GL_RGBA, GL_UNSIGNED_BYTE, wall.data());
    b->m_normal = texture2D(GL_RGB8, perRow, std::max(rows, 1), GL_RGB, GL_UNSIGNED_BYTE, normals.data());
    b->m_columnsPerRow = perRow;
    b->m_wallTexels = map.wallTexels;
    b->m_wallSpan = span;
    b->m_bytes = std::uint64_t(n) * std::uint64_t(n) * 8 + wall.size() + normals.size();
    b->m_vao = gl::VertexArray::create();
    return b;
}

int BlockMapGL::draw(const Camera& camera, const gl::RenderTarget& target, const DrawSettings& s) const {
    target.bind();
    const double aspect = double(target.width()) / double(target.height());
    const double pixelAngle = 2.0 * std::tan(camera.fovYDeg * M_PI / 360.0) / double(target.height());
    begin(*m_program, camera.projectionMatrix(aspect, kNearPlane) * camera.viewMatrix(), camera.position, pixelAngle, s);
    drawOne();
    end();
    return 1;
}

void BlockMapGL::begin(const gl::ShaderProgram& p, const glm::dmat4& viewProj, const glm::dvec3& eye,
                       double pixelAngle, const DrawSettings& s, bool frontFaces) {
    p.set("uPixelAngle", float(pixelAngle));
    p.set("uViewProj", glm::mat4(viewProj));
    p.set("uEye", glm::vec3(eye));
    p.set("uRoofColour", s.roofColour);
    p.set("uSunDir", glm::vec3(glm::normalize(glm::dvec3(-0.5, 0.6, 0.75))));
    p.set("uOutputKind", s.outputKind ? 1 : 0);
    const char* names[kTextures] = {"uBmHeight", "uBmDistance", "uBmColumn", "uBmWall", "uBmNormal", "uBmRoofNormal"};
    for (int i = 0; i < kTextures; ++i) p.set(names[i], kUnit + i);
    p.use();
    glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE); // reversed Z in [0, 1]: gl_FragDepth is the hit's clip z / w
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_GREATER);
    glEnable(GL_CULL_FACE);
    // One fragment per pixel either way: the front faces (the eye outside), or the back faces (inside it or not).
    glCullFace(frontFaces ? GL_BACK : GL_FRONT);
}

void BlockMapGL::drawOne(const gl::ShaderProgram& p) const {
    const double side = double(m_size) * m_texel;
    p.set("uBoxMin", glm::vec3(glm::dvec3(m_origin, m_zBase)));
    p.set("uBoxMax", glm::vec3(glm::dvec3(m_origin + side, m_zTop)));
    p.set("uBmOrigin", glm::vec2(m_origin));
    p.set("uBmTexel", float(m_texel));
    p.set("uBmSize", m_size);
    p.set("uBmZBase", float(m_zBase));
    p.set("uBmZTop", float(m_zTop));
    p.set("uBmColumnsPerRow", m_columnsPerRow);
    p.set("uBmWallTexels", m_wallTexels);
    p.set("uBmWallSpan", m_wallSpan);
    const GLuint textures[kTextures] = {m_height.id(), m_distance.id(), m_column.id(),
                                        m_wall.id(),   m_normal.id(),   m_roofNormal.id()};
    for (int i = 0; i < kTextures; ++i) glBindTextureUnit(GLuint(kUnit + i), textures[i]);
    glBindVertexArray(m_vao.id());
    glDrawArrays(GL_TRIANGLES, 0, 36);
}

void BlockMapGL::end() {
    glBindVertexArray(0);
    glDisable(GL_CULL_FACE);
    glCullFace(GL_BACK);
    for (int i = 0; i < kTextures; ++i) glBindTextureUnit(GLuint(kUnit + i), 0);
}

} // namespace seasonview::city
