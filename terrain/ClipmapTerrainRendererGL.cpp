#include "ClipmapTerrainRendererGL.h"

#include "ReferenceRendererGL.h" // kBackgroundColor

#include <algorithm>
#include <cmath>
#include <tuple>
#include <cstdio>
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
    // The leaf-on view's program now (a shader that does not compile fails here), the others when first drawn.
    if (auto p = r->buildProgram(ImageryView::LeafOn, false); !p) return p.error();
    auto s = gl::ShaderProgram::build("terrain_geometry.vert", "terrain_clipmap.frag", {"LEVEL_STATS", "NORMALS 0"});
    if (!s) return s.error();
    r->m_statsProgram = std::move(*s);
    auto g = GeometryClipmapGL::create(scene, elevationGrid(scene), elevation, options);
    if (!g) return g.error();
    r->m_geometry = std::move(*g);
    return r;
}

Result<const gl::ShaderProgram*> ClipmapTerrainRendererGL::buildProgram(ImageryView view, bool normals,
                                                                        int swipeSeason) const {
    const auto key = std::make_tuple(int(view), normals, swipeSeason);
    auto it = m_programs.find(key);
    if (it != m_programs.end()) return &it->second;
    std::vector<std::string> defines = {"VIEW " + std::to_string(int(view)), normals ? "NORMALS 1" : "NORMALS 0"};
    if (view == ImageryView::Swipe) defines.push_back("SWIPE_SEASON " + std::to_string(swipeSeason));
    auto p = gl::ShaderProgram::build("terrain_geometry.vert", "terrain_clipmap.frag", defines);
    if (!p) return p.error();
    return &m_programs.emplace(key, std::move(*p)).first->second;
}

const gl::ShaderProgram& ClipmapTerrainRendererGL::program(ImageryView view, bool normals, int swipeSeason) const {
    auto p = buildProgram(view, normals, swipeSeason);
    if (!p) {
        // The same source compiled in create() with other constants: a failure here is a bug in the shaders
        // (ClipmapTerrainGLTest.EveryViewVariantCompiles builds each), not bad input.
        std::fprintf(stderr, "seasonview: internal error: %s\n", p.error().message.c_str());
        std::abort();
    }
    return **p;
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
    auto setUniforms = [&](const gl::ShaderProgram& prog) {
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
    };
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
            const gl::ShaderProgram& prog = program(s.view, normals, season);
            setUniforms(prog);
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
    const gl::ShaderProgram& prog = program(s.view, normals);
    setUniforms(prog);
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
    m_statsProgram.set("uClipAniso", 1.0f);
    draw(m_statsProgram, camera, scratch);
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
