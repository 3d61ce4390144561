#include "ReferenceRendererGL.h"

#include <glm/gtc/type_ptr.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>

namespace seasonview {

ReferenceRendererGL::SeasonTexture ReferenceRendererGL::upload(const Image<std::uint8_t>& rgba, int maxSize,
                                                               float anisotropy) {
    SeasonTexture st;
    st.layout = computeTileLayout(rgba.width, rgba.height, maxSize);
    const TileLayout& L = st.layout;
    const int levels = 1 + int(std::floor(std::log2(double(std::max(L.tileWidth, L.tileHeight)))));
    st.texture = gl::Texture::create(GL_TEXTURE_2D_ARRAY);
    const GLuint t = st.texture.id();
    glTextureStorage3D(t, levels, GL_RGBA8, L.tileWidth, L.tileHeight, L.layers());
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    if (L.layers() == 1) {
        glTextureSubImage3D(t, 0, 0, 0, 0, L.tileWidth, L.tileHeight, 1, GL_RGBA, GL_UNSIGNED_BYTE, rgba.pixels.data());
    } else {
        // Each layer holds image pixels [tile*step - border, tile*step + step + border), clamped at the image edge.
        std::vector<std::uint8_t> staging(size_t(L.tileWidth) * size_t(L.tileHeight) * 4);
        for (int ty = 0; ty < L.tilesY; ++ty)
            for (int tx = 0; tx < L.tilesX; ++tx) {
                for (int y = 0; y < L.tileHeight; ++y) {
                    const int sy = std::clamp(ty * L.step - L.border + y, 0, rgba.height - 1);
                    for (int x = 0; x < L.tileWidth; ++x) {
                        const int sx = std::clamp(tx * L.step - L.border + x, 0, rgba.width - 1);
                        std::memcpy(&staging[(size_t(y) * size_t(L.tileWidth) + size_t(x)) * 4],
                                    &rgba.pixels[(size_t(sy) * size_t(rgba.width) + size_t(sx)) * 4], 4);
                    }
                }
                glTextureSubImage3D(t, 0, 0, 0, ty * L.tilesX + tx, L.tileWidth, L.tileHeight, 1, GL_RGBA,
                                    GL_UNSIGNED_BYTE, staging.data());
            }
    }
    glGenerateTextureMipmap(t);
    glTextureParameteri(t, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
    glTextureParameteri(t, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTextureParameteri(t, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTextureParameteri(t, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    if (anisotropy > 1.0f && (epoxy_gl_version() >= 46 || epoxy_has_gl_extension("GL_EXT_texture_filter_anisotropic") ||
                              epoxy_has_gl_extension("GL_ARB_texture_filter_anisotropic"))) {
        GLfloat maxAniso = 1.0f;
        glGetFloatv(GL_MAX_TEXTURE_MAX_ANISOTROPY_EXT, &maxAniso);
        glTextureParameterf(t, GL_TEXTURE_MAX_ANISOTROPY_EXT, std::min(anisotropy, maxAniso));
    }
    return st;
}

Result<std::unique_ptr<ReferenceRendererGL>> ReferenceRendererGL::create(const Scene& scene,
                                                                         const ReferenceOptions& options) {
    auto r = std::unique_ptr<ReferenceRendererGL>(new ReferenceRendererGL());
    auto program = gl::ShaderProgram::build("terrain_reference.vert", "terrain_reference.frag");
    if (!program) return program.error();
    r->m_program = std::move(*program);

    const ReferenceMesh mesh = buildReferenceMesh(scene);
    r->m_stats.meshStride = mesh.stride;
    r->m_stats.triangles = std::int64_t(mesh.indices.size() / 3);
    r->m_mesh = std::make_unique<TerrainMeshGL>(mesh);

    GLint glMax = 0;
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &glMax);
    const int maxSize = options.maxTextureSize > 0 ? std::min(options.maxTextureSize, glMax) : glMax;
    r->m_imageWidth = scene.leafon.info.width;
    r->m_imageHeight = scene.leafon.info.height;
    const ImageryLayer* layers[2] = {&scene.leafon, &scene.leafoff};
    if (!options.levelZero && scene.warped())
        return Error{"reference renderer: a warped scene is drawn from its prepared pyramids' level 0"};
    for (int s = 0; s < 2; ++s) {
        auto rgba = options.levelZero ? readImageU8((*options.levelZero)[size_t(s)], 4)
                                      : readDisplayRgba(layers[s]->info, layers[s]->stretch);
        if (!rgba) return rgba.error();
        if (rgba->channels != 4 || rgba->width != r->m_imageWidth || rgba->height != r->m_imageHeight)
            return fileError(options.levelZero ? (*options.levelZero)[size_t(s)].string() : layers[s]->info.path.string(),
                             "is not the scene's RGBA level 0");
        r->m_seasons[s] = upload(*rgba, maxSize, options.anisotropy);
    }
    r->m_stats.textureLayers = r->m_seasons[0].layout.layers();
    return r;
}

void ReferenceRendererGL::render(const Camera& camera, Season season, const gl::RenderTarget& target) const {
    target.bind();
    beginTerrainPass(kBackgroundColor.r, kBackgroundColor.g, kBackgroundColor.b, kBackgroundColor.a);
    const double aspect = double(target.width()) / double(target.height());
    glm::dmat4 view = camera.viewMatrix();
    const glm::mat4 viewProj = glm::mat4(camera.projectionMatrix(aspect, kNearPlane) * view);
    const SeasonTexture& st = m_seasons[season == Season::LeafOn ? 0 : 1];
    const SeasonTexture& other = m_seasons[season == Season::LeafOn ? 1 : 0];
    const TileLayout& L = st.layout;
    m_program.set("uViewProj", viewProj);
    m_program.set("uImageSize", glm::vec2(float(m_imageWidth), float(m_imageHeight)));
    m_program.set("uTileSize", glm::vec2(float(L.tileWidth), float(L.tileHeight)));
    m_program.set("uTileStep", float(L.step > 0 ? L.step : std::max(m_imageWidth, m_imageHeight)));
    m_program.set("uTileBorder", float(L.border));
    m_program.set("uTilesX", L.tilesX);
    m_program.set("uTilesY", L.tilesY);
    m_program.set("uImagery", 0);
    m_program.set("uOther", 1);
    m_program.set("uNoDataColour", kNoDataColor);
    m_program.use();
    glBindTextureUnit(0, st.texture.id());
    glBindTextureUnit(1, other.texture.id()); // same tile layout: both are the grid
    m_mesh->draw();
}

} // namespace seasonview
