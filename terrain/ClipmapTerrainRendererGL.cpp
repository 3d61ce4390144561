#include "ClipmapTerrainRendererGL.h"

#include "ReferenceRendererGL.h" // kBackgroundColor

#include <algorithm>

namespace seasonview {

const float kLevelColors[8][3] = {{1.0f, 0.15f, 0.1f}, {0.1f, 0.85f, 0.2f}, {0.15f, 0.3f, 1.0f}, {1.0f, 0.9f, 0.1f},
                                  {0.95f, 0.2f, 0.95f}, {0.1f, 0.9f, 0.95f}, {1.0f, 0.55f, 0.1f}, {0.6f, 0.6f, 0.6f}};

namespace {
constexpr ImageryView kViews[] = {ImageryView::LeafOn, ImageryView::LeafOff, ImageryView::Blend, ImageryView::Swipe,
                                  ImageryView::Lod};
} // namespace

const char* imageryViewName(ImageryView v) {
    switch (v) {
    case ImageryView::LeafOn: return "leafon";
    case ImageryView::LeafOff: return "leafoff";
    case ImageryView::Blend: return "blend";
    case ImageryView::Swipe: return "swipe";
    case ImageryView::Lod: return "lod";
    }
    return "?";
}

std::optional<ImageryView> parseImageryView(const std::string& name) {
    for (ImageryView v : kViews)
        if (name == imageryViewName(v)) return v;
    return std::nullopt;
}

Result<std::unique_ptr<ClipmapTerrainRendererGL>> ClipmapTerrainRendererGL::create(const Scene& scene,
                                                                                   const ClipmapGL& clipmap) {
    assert(clipmap.layers() >= 2 && "ClipmapTerrainRendererGL::create(): needs leaf-on and leaf-off layers");
    auto r = std::unique_ptr<ClipmapTerrainRendererGL>(new ClipmapTerrainRendererGL(clipmap));
    auto p = gl::ShaderProgram::build("terrain_reference.vert", "terrain_clipmap.frag");
    if (!p) return p.error();
    r->m_program = std::move(*p);
    auto s = gl::ShaderProgram::build("terrain_reference.vert", "terrain_clipmap.frag", {"LEVEL_STATS"});
    if (!s) return s.error();
    r->m_statsProgram = std::move(*s);
    r->m_mesh = std::make_unique<TerrainMeshGL>(buildReferenceMesh(scene));
    return r;
}

void ClipmapTerrainRendererGL::draw(const gl::ShaderProgram& program, const Camera& camera,
                                    const gl::RenderTarget& target) const {
    const double aspect = double(target.width()) / double(target.height());
    program.set("uViewProj", glm::mat4(camera.projectionMatrix(aspect, 0.05) * camera.viewMatrix()));
    m_clipmap.bind(program, 0);
    program.use();
    m_mesh->draw();
}

void ClipmapTerrainRendererGL::render(const Camera& camera, const ImagerySettings& s,
                                      const gl::RenderTarget& target) const {
    target.bind();
    beginTerrainPass(kBackgroundColor.r, kBackgroundColor.g, kBackgroundColor.b, kBackgroundColor.a);
    m_program.set("uView", int(s.view));
    m_program.set("uBlend", std::clamp(s.blend, 0.0f, 1.0f));
    m_program.set("uSwipeX", std::clamp(s.swipe, 0.0f, 1.0f) * float(target.width()));
    m_program.set("uClipAniso", std::clamp(s.anisotropy, 1.0f, kMaxAnisotropy));
    for (int i = 0; i < 8; ++i)
        m_program.set(("uLevelColors[" + std::to_string(i) + "]").c_str(),
                      glm::vec3(kLevelColors[i][0], kLevelColors[i][1], kLevelColors[i][2]));
    draw(m_program, camera, target);
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
