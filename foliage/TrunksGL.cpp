#include "TrunksGL.h"

#include "TerrainMeshGL.h" // kNearPlane

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>

#include <glm/geometric.hpp>
#include <glm/gtc/type_ptr.hpp>

namespace seasonview {

namespace {
constexpr int kVerticesPerTrunk = 4; // trunk.vert: a strip, the quad facing the eye
constexpr int kTrianglesPerTrunk = 2;
constexpr GLintptr kHeader = 16;         // DrawArraysIndirectCommand before the trunks
} // namespace

Result<std::unique_ptr<TrunksGL>> TrunksGL::create(const Scene& scene, const ClipmapGL& imagery,
                                                   const CanopyClipmapGL& canopy, const TrunkOptions& options) {
    auto t = std::unique_ptr<TrunksGL>(new TrunksGL(imagery, canopy));
    t->m_options = options;
    for (int pass : {0, 1, 2}) { // the pass is a compile-time constant (shaders/trunk_find.comp)
        std::vector<std::string> defines = imagery.layoutDefines("CLIP_");
        defines.push_back("PASS " + std::to_string(pass));
        auto f = gl::ShaderProgram::buildCompute("trunk_find.comp", defines);
        if (!f) return f.error();
        t->m_find[pass] = std::move(*f);
    }
    t->m_vao = gl::VertexArray::create();
    t->m_buffer = gl::Buffer::create();
    glNamedBufferStorage(t->m_buffer.id(), kHeader + GLsizeiptr(options.capacity) * 16, nullptr,
                         GL_DYNAMIC_STORAGE_BIT);
    const std::uint32_t header[4] = {std::uint32_t(kVerticesPerTrunk), 0, 0, 0};
    glNamedBufferSubData(t->m_buffer.id(), 0, kHeader, header);

    // Image pixel -> local metres: affine through three of the scene's exact inverses (exact for UTM imagery;
    // geographic imagery is within a fraction of a pixel over a scene).
    const glm::dvec2 image(scene.leafon.info.width, scene.leafon.info.height);
    const glm::dvec2 o = scene.imagePixelToLocal({0.0, 0.0});
    const glm::dvec2 ex = (scene.imagePixelToLocal({image.x, 0.0}) - o) / image.x;
    const glm::dvec2 ey = (scene.imagePixelToLocal({0.0, image.y}) - o) / image.y;
    t->m_imageToLocal = glm::dmat3(glm::dvec3(ex, 0.0), glm::dvec3(ey, 0.0), glm::dvec3(o, 1.0));
    t->m_metresPerPixel = scene.gsd;

    // The level: the finest clip level whose texels reach texelMetres.
    const int clipLevels = imagery.schedule().layout().clipLevels();
    int level = 0;
    while (level + 1 < clipLevels && std::ldexp(scene.gsd, level) < options.texelMetres * 0.99) ++level;
    t->m_level = level;
    const double texel = std::ldexp(scene.gsd, level);
    t->m_minRadius = float(options.minCrownRadius / texel);
    t->m_maxRadius = std::max(2, int(std::ceil(options.maxCrownRadius / texel)));
    const int size = imagery.schedule().layout().size;
    t->m_distance = gl::Texture::create(GL_TEXTURE_2D);
    glTextureStorage2D(t->m_distance.id(), 1, GL_R32F, size, size);
    t->m_column = gl::Texture::create(GL_TEXTURE_2D);
    glTextureStorage2D(t->m_column.id(), 1, GL_RG32F, size, size);
    t->m_cpu = options.cpuSearch.value_or(canopy.derivesOnCpu()) && clipLevels > 0;
    if (t->m_cpu) canopy.keepCopyOf(level);
    return t;
}

TrunksGL::~TrunksGL() {
    if (m_job.valid()) m_job.wait();
}

CrownSearchLevel TrunksGL::snapshot() const {
    const ClipmapLayout& L = m_imagery.schedule().layout();
    CrownSearchLevel s;
    s.size = L.size;
    s.block = L.block;
    s.level = m_level;
    s.window = m_imagery.schedule().window(m_level);
    s.values = m_canopy.levelCopy();
    s.tags = m_canopy.slotTags(m_level);
    return s;
}

void TrunksGL::store(const std::vector<glm::vec4>& trunks) {
    const size_t n = std::min(trunks.size(), size_t(m_options.capacity));
    const std::uint32_t count = std::uint32_t(n);
    glNamedBufferSubData(m_buffer.id(), 4, 4, &count);
    if (n > 0) glNamedBufferSubData(m_buffer.id(), kHeader, GLsizeiptr(n * 16), trunks.data());
    m_count = int(n);
}

bool TrunksGL::update() {
    ++m_framesSinceSearch;
    if (m_imagery.schedule().layout().clipLevels() == 0) return false;
    if (m_cpu) {
        // The search in flight, when done, gives the trunks; the next starts once the level has changed and enough
        // frames have passed, as on the GPU.
        if (m_job.valid()) {
            if (m_job.wait_for(std::chrono::seconds(0)) != std::future_status::ready) return false;
            store(m_job.get());
        }
        if (m_count > 0 && m_framesSinceSearch < m_options.framesBetweenSearches) return false;
        if (m_canopy.slotTags(m_level) == m_searchedTags) return false;
        m_searchedTags = m_canopy.slotTags(m_level);
        m_framesSinceSearch = 0;
        m_job = std::async(std::launch::async, [s = snapshot(), min = m_minRadius, max = m_maxRadius] {
            return findCrownCentres(s, min, max);
        });
        return true;
    }
    if (m_count > 0 && m_framesSinceSearch < m_options.framesBetweenSearches) return false;
    if (m_canopy.slotTags(m_level) == m_searchedTags) return false;
    find();
    return true;
}

int TrunksGL::find() {
    const ClipmapLayout& L = m_imagery.schedule().layout();
    if (L.clipLevels() == 0) {
        m_count = 0;
        return 0;
    }
    m_searchedTags = m_canopy.slotTags(m_level);
    m_framesSinceSearch = 0;
    if (m_cpu) {
        if (m_job.valid()) m_job.get(); // older than this search
        store(findCrownCentres(snapshot(), m_minRadius, m_maxRadius));
        return m_count;
    }
    const std::uint32_t zero = 0;
    glNamedBufferSubData(m_buffer.id(), 4, 4, &zero);
    const TexelRect& w = m_imagery.schedule().window(m_level);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, m_buffer.id());
    glBindImageTexture(0, m_distance.id(), 0, GL_FALSE, 0, GL_READ_WRITE, GL_R32F);
    glBindImageTexture(1, m_column.id(), 0, GL_FALSE, 0, GL_READ_WRITE, GL_RG32F);
    const GLuint groups = GLuint((L.size + 15) / 16);
    const GLuint columnGroups = GLuint((L.size + 63) / 64); // pass 0: 64 columns × 64 rows per group
    for (int pass = 0; pass < 3; ++pass) {
        const gl::ShaderProgram& find = m_find[pass];
        m_imagery.bind(find, 0, "u");
        m_canopy.bind(find, kCanopyUnit);
        find.set("uLevel", m_level);
        glProgramUniform2i(find.id(), find.location("uWindow0"), w.x0, w.y0);
        glProgramUniform2i(find.id(), find.location("uWindow1"), w.x1, w.y1);
        find.set("uMinRadius", m_minRadius);
        find.set("uMaxRadius", m_maxRadius);
        find.set("uCapacity", m_options.capacity);
        find.use();
        if (pass == 0) // an invocation per column and 64 rows (trunk_find.comp)
            glDispatchCompute(columnGroups, columnGroups, 1);
        else
            glDispatchCompute(groups, groups, 1);
        glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT | GL_COMMAND_BARRIER_BIT |
                        GL_BUFFER_UPDATE_BARRIER_BIT);
    }
    std::uint32_t n = 0;
    glGetNamedBufferSubData(m_buffer.id(), 4, 4, &n);
    m_count = int(std::min<std::uint32_t>(n, std::uint32_t(m_options.capacity)));
    return m_count;
}

GeometryFrameStats TrunksGL::draw(const Camera& camera, const ClipmapTerrainRendererGL& terrain, double trunkHeight,
                                  const gl::RenderTarget& target) const {
    if (m_count == 0 || trunkHeight <= 0.0) return {};
    target.bind();
    const double aspect = double(target.width()) / double(target.height());
    const glm::mat4 viewProj(camera.projectionMatrix(aspect, kNearPlane) * camera.viewMatrix());
    // The terrain renderer's build of the program: its elevation clipmap's layout as constants.
    const gl::ShaderProgram& program = terrain.program("trunk.vert", "trunk.frag", {});
    terrain.geometry().bind(program, 8);
    program.set("uViewProj", viewProj);
    const glm::mat3 m(m_imageToLocal);
    glProgramUniformMatrix3fv(program.id(), program.location("uImageToLocal"), 1, GL_FALSE, glm::value_ptr(m));
    program.set("uMetresPerPixel", float(m_metresPerPixel));
    program.set("uTrunkHeight", float(trunkHeight));
    program.set("uRadiusFraction", m_options.radiusFraction);
    program.set("uMinRadius", 0.12f);
    program.set("uMaxRadius", 0.5f);
    program.set("uCapacity", m_options.capacity);
    program.set("uSunDir", glm::vec3(glm::normalize(glm::dvec3(-0.5, 0.6, 0.75))));
    program.set("uEye", glm::vec3(camera.position));
    program.use();
    glBindVertexArray(m_vao.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, m_buffer.id());
    // An instance per trunk found: the count is on the CPU since the search (find() reads it back). Drawn through the
    // buffer's DrawArraysIndirectCommand instead, this stage held the CPU for 6.4 of the canopy view's 12 ms on the
    // NVIDIA H100 (`bench --stages issue`: the GPU's whole frame so far; 0.08 ms when the GPU had finished before it),
    // and the indirect draw was its one draw.
    glDrawArraysInstanced(GL_TRIANGLE_STRIP, 0, kVerticesPerTrunk, m_count);
    glBindVertexArray(0);
    GeometryFrameStats st;
    st.drawCalls = 1;
    st.triangles = std::int64_t(m_count) * kTrianglesPerTrunk;
    return st;
}

std::vector<Trunk> TrunksGL::readTrunks() const {
    std::vector<glm::vec4> raw(static_cast<size_t>(m_count));
    if (m_count > 0) glGetNamedBufferSubData(m_buffer.id(), kHeader, GLsizeiptr(raw.size() * 16), raw.data());
    std::vector<Trunk> out;
    out.reserve(raw.size());
    for (const glm::vec4& r : raw) {
        const glm::dvec3 l = m_imageToLocal * glm::dvec3(r.x, r.y, 1.0);
        out.push_back({glm::dvec2(l), double(r.z) * m_metresPerPixel, int(r.w)});
    }
    return out;
}

} // namespace seasonview
