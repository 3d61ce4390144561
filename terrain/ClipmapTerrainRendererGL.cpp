#include "ClipmapTerrainRendererGL.h"

#include "ReferenceRendererGL.h" // kBackgroundColor
#include "gl/GlContext.h"

#include <algorithm>
#include <cmath>
#include <tuple>
#include <cstdio>
#include <cassert>
#include <cstdlib>
#include <string>

#include <glm/geometric.hpp>

namespace seasonview {

const float kLevelColors[8][3] = {{1.0f, 0.15f, 0.1f}, {0.1f, 0.85f, 0.2f}, {0.15f, 0.3f, 1.0f}, {1.0f, 0.9f, 0.1f},
                                  {0.95f, 0.2f, 0.95f}, {0.1f, 0.9f, 0.95f}, {1.0f, 0.55f, 0.1f}, {0.6f, 0.6f, 0.6f}};

namespace {
constexpr ImageryView kViews[] = {ImageryView::LeafOn, ImageryView::LeafOff, ImageryView::Blend, ImageryView::Swipe,
                                  ImageryView::Lod,    ImageryView::Wireframe, ImageryView::Levels, ImageryView::Relief,
                                  ImageryView::Canopy};
} // namespace

const char* terrainShadingName(TerrainShading t) {
    switch (t) {
    case TerrainShading::Auto: return "auto";
    case TerrainShading::Forward: return "forward";
    case TerrainShading::Deferred: return "deferred";
    }
    return "?";
}

namespace {
TerrainShading resolveFor(TerrainShading t, bool software) {
    if (t != TerrainShading::Auto) return t;
    return software ? TerrainShading::Deferred : TerrainShading::Forward;
}
} // namespace

TerrainShading resolveTerrainShading(TerrainShading t) { return resolveFor(t, gl::currentIsSoftwareRenderer()); }

TerrainShading resolveTerrainShading(TerrainShading t, const std::string& glRenderer) {
    return resolveFor(t, gl::isSoftwareRenderer(glRenderer));
}

std::optional<TerrainShading> parseTerrainShading(const std::string& name) {
    if (name == "auto") return TerrainShading::Auto;
    if (name == "forward") return TerrainShading::Forward;
    if (name == "deferred") return TerrainShading::Deferred;
    return std::nullopt;
}

const char* imageryViewName(ImageryView v) {
    switch (v) {
    case ImageryView::LeafOn: return "leafon";
    case ImageryView::LeafOff: return "leafoff";
    case ImageryView::Blend: return "blend";
    case ImageryView::Swipe: return "swipe";
    case ImageryView::Lod: return "lod";
    case ImageryView::Wireframe: return "wireframe";
    case ImageryView::Levels: return "levels";
    case ImageryView::Relief: return "relief";
    case ImageryView::Canopy: return "canopy";
    }
    return "?";
}

std::optional<ImageryView> parseImageryView(const std::string& name) {
    for (ImageryView v : kViews)
        if (name == imageryViewName(v)) return v;
    return std::nullopt;
}

Result<std::unique_ptr<ClipmapTerrainRendererGL>> ClipmapTerrainRendererGL::create(
    const Scene& scene, const ClipmapGL& clipmap, const ImagePyramid* elevation, const GeometryClipmapOptions& options) {
    assert(clipmap.layers() >= 2 && "ClipmapTerrainRendererGL::create(): needs leaf-on and leaf-off layers");
    auto r = std::unique_ptr<ClipmapTerrainRendererGL>(new ClipmapTerrainRendererGL(clipmap));
    r->m_seasonsComplete = scene.leafon.direct && scene.leafoff.direct;
    auto g = GeometryClipmapGL::create(scene, elevationGrid(scene), elevation, options);
    if (!g) return g.error();
    r->m_geometry = std::move(*g);
    r->m_noCanopyReads = gl::Buffer::create();
    glNamedBufferStorage(r->m_noCanopyReads.id(), 16, nullptr, 0); // the shaders write it only with a canopy
    r->m_layoutDefines = clipmap.layoutDefines("CLIP_");
    for (const std::string& d : r->m_geometry->layoutDefines()) r->m_layoutDefines.push_back(d);
    // The leaf-on view's programs now (a shader that does not compile fails here), the others when first drawn.
    if (auto p = r->buildProgram("terrain_geometry.vert", "terrain_clipmap.frag", {"VIEW 0", "NORMALS 0"}); !p)
        return p.error();
    if (auto p = r->buildProgram("terrain_geometry.vert", "terrain_clipmap.frag", {"GBUFFER", "NORMALS 0"}); !p)
        return p.error();
    if (auto p = r->buildProgram("terrain_resolve.vert", "terrain_resolve.frag", {"VIEW 0"}); !p) return p.error();
    if (auto p = r->buildProgram("terrain_geometry.vert", "terrain_clipmap.frag", {"LEVEL_STATS", "NORMALS 0"}); !p)
        return p.error();
    return r;
}

Result<const gl::ShaderProgram*> ClipmapTerrainRendererGL::buildProgram(const char* vertex, const char* fragment,
                                                                        const std::vector<std::string>& defines) const {
    std::string key = std::string(vertex) + "|" + fragment;
    for (const std::string& d : defines) key += "|" + d;
    auto it = m_programs.find(key);
    if (it != m_programs.end()) return &it->second;
    std::vector<std::string> all = defines;
    all.insert(all.end(), m_layoutDefines.begin(), m_layoutDefines.end());
    auto p = gl::ShaderProgram::build(vertex, fragment, all);
    if (!p) return p.error();
    return &m_programs.emplace(key, std::move(*p)).first->second;
}

const gl::ShaderProgram& ClipmapTerrainRendererGL::program(const char* vertex, const char* fragment,
                                                           const std::vector<std::string>& defines) const {
    auto p = buildProgram(vertex, fragment, defines);
    if (!p) {
        // The same sources compiled in create() with other constants: a failure here is a bug in the shaders
        // (TerrainClipmapGLTest.EveryViewProgramDraws builds each), not bad input.
        std::fprintf(stderr, "seasonview: internal error: %s\n", p.error().message.c_str());
        std::abort();
    }
    return **p;
}

std::vector<std::string> ClipmapTerrainRendererGL::viewDefines(ImageryView view, int swipeSeason) const {
    std::vector<std::string> d = {"VIEW " + std::to_string(int(view))};
    if (m_seasonsComplete) d.push_back("SEASONS_COMPLETE");
    if (view == ImageryView::Swipe) d.push_back("SWIPE_SEASON " + std::to_string(swipeSeason));
    return d;
}

void ClipmapTerrainRendererGL::ensureGBuffer(const gl::RenderTarget& target) const {
    if (m_gbuffer && m_gbufferSize == glm::ivec2(target.width(), target.height()) &&
        m_gbufferDepth == target.depthRenderbuffer())
        return;
    m_gPosition = gl::Texture::create(GL_TEXTURE_2D);
    m_gFootprint = gl::Texture::create(GL_TEXTURE_2D);
    m_gDepth = gl::Texture::create(GL_TEXTURE_2D);
    for (const gl::Texture* t : {&m_gPosition, &m_gFootprint, &m_gDepth}) {
        glTextureStorage2D(t->id(), 1, t == &m_gDepth ? GL_R32F : GL_RGBA32F, target.width(), target.height());
        glTextureParameteri(t->id(), GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        glTextureParameteri(t->id(), GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    }
    m_gbuffer = gl::Framebuffer::create();
    glNamedFramebufferTexture(m_gbuffer.id(), GL_COLOR_ATTACHMENT0, m_gPosition.id(), 0);
    glNamedFramebufferTexture(m_gbuffer.id(), GL_COLOR_ATTACHMENT1, m_gFootprint.id(), 0);
    glNamedFramebufferTexture(m_gbuffer.id(), GL_COLOR_ATTACHMENT2, m_gDepth.id(), 0);
    glNamedFramebufferRenderbuffer(m_gbuffer.id(), GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, target.depthRenderbuffer());
    const GLenum buffers[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
    glNamedFramebufferDrawBuffers(m_gbuffer.id(), 2, buffers);
    assert(glCheckNamedFramebufferStatus(m_gbuffer.id(), GL_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE &&
           "ClipmapTerrainRendererGL: incomplete G-buffer");
    m_gbufferSize = {target.width(), target.height()};
    m_gbufferDepth = target.depthRenderbuffer();
    if (!m_emptyVao) m_emptyVao = gl::VertexArray::create();
}

ClipmapFrameStats ClipmapTerrainRendererGL::updateGeometry(const Camera& camera, int viewportHeight) {
    return m_geometry->update(camera, viewportHeight);
}

ClipmapFrameStats ClipmapTerrainRendererGL::completeGeometry() { return m_geometry->completeSynchronously(); }

void ClipmapTerrainRendererGL::bindTerrain(const gl::ShaderProgram& program, const glm::dmat4& viewProj) const {
    program.set("uViewProj", glm::mat4(viewProj));
    m_clipmap.bind(program, 0);
    m_geometry->bind(program, 8);
    if (m_canopy) {
        m_canopy->bind(program, kCanopyUnit);
    } else {
        // Integer samplers must not share unit 0 with the float clip arrays, even unread.
        program.set("uCanopyClip", kCanopyUnit);
        program.set("uCanopyCoarse", kCanopyUnit + 1);
        program.set("uCanopyTags", kCanopyUnit + 2);
        // The canopy view's record of the levels read (common_view.glsl) goes to a buffer nothing reads.
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kCanopyReadsBinding, m_noCanopyReads.id());
    }
    program.set("uHasCanopy", m_canopy ? 1 : 0);
}

GeometryFrameStats ClipmapTerrainRendererGL::draw(const gl::ShaderProgram& program, const Camera& camera,
                                                  const gl::RenderTarget& target, glm::dvec2 ndcX) const {
    const double aspect = double(target.width()) / double(target.height());
    const glm::dmat4 viewProj = camera.projectionMatrix(aspect, kNearPlane) * camera.viewMatrix();
    bindTerrain(program, viewProj);
    program.use();
    // Pieces are culled against the part of the frustum drawn: NDC x in ndcX, stretched to [-1, 1].
    glm::dmat4 narrow(1.0);
    narrow[0][0] = 2.0 / (ndcX.y - ndcX.x);
    narrow[3][0] = -(ndcX.x + ndcX.y) / (ndcX.y - ndcX.x);
    m_last = m_geometry->draw(program, narrow * viewProj);
    return m_last;
}

void ClipmapTerrainRendererGL::setViewUniforms(const gl::ShaderProgram& prog, const ImagerySettings& s,
                                               float swipeX) const {
    const float shade = std::clamp(s.shading, 0.0f, 1.0f);
    prog.set("uBlend", std::clamp(s.blend, 0.0f, 1.0f));
    prog.set("uSwipeX", swipeX);
    prog.set("uClipAniso", std::clamp(s.anisotropy, 1.0f, kMaxAnisotropy));
    prog.set("uShade", shade);
    prog.set("uSunDir", glm::vec3(glm::normalize(glm::dvec3(-0.5, 0.6, 0.75)))); // from the north-west, high
    prog.set("uWirePass", 0);
    prog.set("uCanopyGround[0]", std::clamp(s.groundElsewhere, 0, 1));
    prog.set("uCanopyGround[1]", std::clamp(s.groundUnderCanopy, 0, 1));
    prog.set("uCanopyBase", std::clamp(s.canopyBase, 0.0f, 1.0f));
    prog.set("uNoDataColour", kNoDataColor);
    for (int i = 0; i < 8; ++i)
        prog.set(("uLevelColors[" + std::to_string(i) + "]").c_str(),
                 glm::vec3(kLevelColors[i][0], kLevelColors[i][1], kLevelColors[i][2]));
}

GeometryFrameStats ClipmapTerrainRendererGL::renderDeferred(const Camera& camera, const ImagerySettings& s,
                                                            const gl::RenderTarget& target, bool normals,
                                                            float swipeX) const {
    // Deferred (the inspection views wireframe and levels stay forward: they colour by the geometry level).
    // The geometry pass records each pixel's level-0 position, derivatives and normal (and the depth, into the
    // target's own depth buffer, for the passes that follow); the resolve shades every pixel it left once.
    ensureGBuffer(target);
    // The canopy view with marched layers: the resolve marches them and writes each pixel's depth, the terrain's
    // from a third target where no crown is met.
    const bool march = s.canopyMarch && s.view == ImageryView::Canopy;
    // Without normals (n = z) the depth takes the normal's place in the second target: one target less to write and
    // fetch per pixel.
    const bool depthTarget = march && normals, depthPacked = march && !normals;
    const GLenum buffers[3] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2};
    glNamedFramebufferDrawBuffers(m_gbuffer.id(), depthTarget ? 3 : 2, buffers);
    glBindFramebuffer(GL_FRAMEBUFFER, m_gbuffer.id());
    glViewport(0, 0, target.width(), target.height());
    const float noTerrain[4] = {-1.0f, -1.0f, 0.0f, 0.0f};
    glClearNamedFramebufferfv(m_gbuffer.id(), GL_COLOR, 0, noTerrain);
    std::vector<std::string> geometryDefines = {"GBUFFER", normals ? "NORMALS 1" : "NORMALS 0"};
    if (depthTarget) geometryDefines.push_back("GBUFFER_DEPTH");
    if (depthPacked) geometryDefines.push_back("GBUFFER_DEPTH_PACKED");
    const gl::ShaderProgram& geometryPass = program("terrain_geometry.vert", "terrain_clipmap.frag", geometryDefines);
    GeometryFrameStats st = draw(geometryPass, camera, target);
    target.bind();
    if (march) {
        glDepthFunc(GL_ALWAYS); // the resolve writes every pixel's depth: a crown's, or the terrain's as it was
    } else {
        glDisable(GL_DEPTH_TEST);
    }
    glBindVertexArray(m_emptyVao.id());
    const double aspect = double(target.width()) / double(target.height());
    const glm::dmat4 viewProj = camera.projectionMatrix(aspect, kNearPlane) * camera.viewMatrix();
    // The swipe view in two scissored resolves, each sampling its season only (one that picked the season per
    // pixel would run both seasons' sampling under a mask).
    const int split = int(std::ceil(double(swipeX) - 0.5)); // pixel x < split: centre left of swipeX
    const bool swipe = s.view == ImageryView::Swipe;
    if (swipe) glEnable(GL_SCISSOR_TEST);
    for (int season = 0; season < (swipe ? 2 : 1); ++season) {
        const int x0 = season == 0 ? 0 : split, x1 = season == 0 && swipe ? split : target.width();
        if (x1 <= x0) continue;
        std::vector<std::string> defines = viewDefines(s.view, season);
        if (march) defines.push_back("CANOPY_MARCH");
        if (depthPacked) defines.push_back("GBUFFER_DEPTH_PACKED");
        const gl::ShaderProgram& resolve = program("terrain_resolve.vert", "terrain_resolve.frag", defines);
        setViewUniforms(resolve, s, swipeX);
        bindTerrain(resolve, viewProj);
        glBindTextureUnit(kGBufferUnit, m_gPosition.id());
        glBindTextureUnit(kGBufferUnit + 1, m_gFootprint.id());
        resolve.set("uGPosition", kGBufferUnit);
        resolve.set("uGFootprint", kGBufferUnit + 1);
        if (march) {
            glBindTextureUnit(kGBufferUnit + 2, depthTarget ? m_gDepth.id() : 0);
            resolve.set("uGDepth", kGBufferUnit + 2);
            for (int i = 0; i < 2; ++i) glBindTextureUnit(GLuint(kCanopyEntryUnit + i), s.canopyMarch->entry[i]);
            resolve.set("uEntry", kCanopyEntryUnit);
            resolve.set("uEntryRay", kCanopyEntryUnit + 1);
            if (s.canopyMarch->setUniforms) s.canopyMarch->setUniforms(resolve);
        }
        resolve.use();
        if (swipe) glScissor(x0, 0, x1 - x0, target.height());
        glDrawArrays(GL_TRIANGLES, 0, 3);
        ++st.drawCalls;
    }
    glDisable(GL_SCISSOR_TEST);
    glBindTextureUnit(kGBufferUnit, 0); // the G-buffer is drawn into next frame
    glBindTextureUnit(kGBufferUnit + 1, 0);
    if (march) {
        glBindTextureUnit(kGBufferUnit + 2, 0);
        for (int i = 0; i < 2; ++i) glBindTextureUnit(GLuint(kCanopyEntryUnit + i), 0);
    }
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_GREATER);
    m_last = st;
    return st;
}

GeometryFrameStats ClipmapTerrainRendererGL::render(const Camera& camera, const ImagerySettings& s,
                                                    const gl::RenderTarget& target) const {
    target.bind();
    beginTerrainPass(kBackgroundColor.r, kBackgroundColor.g, kBackgroundColor.b, kBackgroundColor.a, s.clear);
    if (!s.terrain) {
        m_last = {};
        m_last.drawCalls = 0;
        return m_last;
    }
    const float shade = std::clamp(s.shading, 0.0f, 1.0f);
    const bool normals = shade > 0.0f || s.view == ImageryView::Relief;
    const float swipeX = std::clamp(s.swipe, 0.0f, 1.0f) * float(target.width());
    if (resolvesDeferred(s)) return renderDeferred(camera, s, target, normals, swipeX);
    if (s.view == ImageryView::Swipe) {
        // Two passes, each scissored to its side and culled against its part of the frustum: a program per side
        // samples one season (its fragments would otherwise run both seasons' sampling under a mask). The pixels
        // are those of one pass that picks the season per pixel: the same fragments, the same colours.
        GeometryFrameStats st;
        const int split = int(std::ceil(double(swipeX) - 0.5)); // pixel x < split: centre left of swipeX
        glEnable(GL_SCISSOR_TEST);
        for (int season : {0, 1}) {
            const int x0 = season == 0 ? 0 : split, x1 = season == 0 ? split : target.width();
            if (x1 <= x0) continue;
            std::vector<std::string> defines = viewDefines(s.view, season);
            defines.push_back(normals ? "NORMALS 1" : "NORMALS 0");
            const gl::ShaderProgram& prog = program("terrain_geometry.vert", "terrain_clipmap.frag", defines);
            setViewUniforms(prog, s, swipeX);
            glScissor(x0, 0, x1 - x0, target.height());
            const double w = double(target.width());
            const GeometryFrameStats side =
                draw(prog, camera, target, {2.0 * double(x0) / w - 1.0, 2.0 * double(x1) / w - 1.0});
            st.triangles += side.triangles;
            st.drawCalls += side.drawCalls;
            st.piecesCulled += side.piecesCulled;
            st.levelsDrawn = std::max(st.levelsDrawn, side.levelsDrawn);
        }
        glDisable(GL_SCISSOR_TEST);
        m_last = st;
        return st;
    }
    std::vector<std::string> defines = viewDefines(s.view, 0);
    defines.push_back(normals ? "NORMALS 1" : "NORMALS 0");
    const gl::ShaderProgram& prog = program("terrain_geometry.vert", "terrain_clipmap.frag", defines);
    setViewUniforms(prog, s, swipeX);
    GeometryFrameStats st = draw(prog, camera, target);
    if (s.view == ImageryView::Wireframe) {
        // The triangle edges over the filled terrain: drawn again as lines, pulled towards the viewer (reversed
        // Z: larger depth is nearer) so they win the depth test against their own faces.
        glPolygonMode(GL_FRONT_AND_BACK, GL_LINE);
        glEnable(GL_POLYGON_OFFSET_LINE);
        glPolygonOffset(1.0f, 1.0f);
        glDepthFunc(GL_GEQUAL);
        prog.set("uWirePass", 1);
        draw(prog, camera, target);
        prog.set("uWirePass", 0);
        glDepthFunc(GL_GREATER);
        glDisable(GL_POLYGON_OFFSET_LINE);
        glPolygonMode(GL_FRONT_AND_BACK, GL_FILL);
    }
    m_last = st;
    return st;
}

FrameLevelStats ClipmapTerrainRendererGL::measureLevels(const Camera& camera, const gl::RenderTarget& scratch) const {
    scratch.bind();
    beginTerrainPass(0, 0, 0, 0);
    // Isotropic: the statistics compare levels with the footprint's isotropic level, like the CPU estimate.
    const gl::ShaderProgram& stats = program("terrain_geometry.vert", "terrain_clipmap.frag", {"LEVEL_STATS", "NORMALS 0"});
    stats.set("uClipAniso", 1.0f);
    draw(stats, camera, scratch);
    const std::vector<std::uint8_t> px = scratch.readRgba();
    FrameLevelStats st;
    std::vector<std::int64_t> hist;
    std::int64_t good = 0, deficit = 0;
    for (size_t i = 0; i < px.size(); i += 4) {
        if (px[i + 3] == 0) continue; // sky
        const int needed = px[i], used = px[i + 1];
        ++st.terrainPixels;
        good += used <= needed ? 1 : 0;
        deficit += std::max(0, used - needed);
        if (size_t(used) >= hist.size()) hist.resize(size_t(used) + 1, 0);
        ++hist[size_t(used)];
    }
    if (st.terrainPixels > 0) {
        st.coverage = double(good) / double(st.terrainPixels);
        st.meanLevelDeficit = double(deficit) / double(st.terrainPixels);
        for (std::int64_t h : hist) st.usedLevelHistogram.push_back(double(h) / double(st.terrainPixels));
    }
    return st;
}

} // namespace seasonview
