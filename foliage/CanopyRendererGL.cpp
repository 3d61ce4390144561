#include "CanopyRendererGL.h"

#include "TerrainMeshGL.h" // kNearPlane

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

namespace seasonview {

Result<std::unique_ptr<CanopyRendererGL>> CanopyRendererGL::create() {
    auto r = std::unique_ptr<CanopyRendererGL>(new CanopyRendererGL());
    auto p = gl::ShaderProgram::build("terrain_geometry.vert", "terrain_clipmap.frag", {"CANOPY_LAYER"});
    if (!p) return p.error();
    r->m_program = std::move(*p);
    return r;
}

GeometryFrameStats CanopyRendererGL::render(const Camera& camera, const ClipmapTerrainRendererGL& terrain,
                                            const CanopyClipmapGL& canopy, const CanopyDrawSettings& s,
                                            const gl::RenderTarget& target) const {
    const int layers = canopy.options().layers;
    if (layers < 1 || s.treeHeight <= 0.0) return {};
    target.bind();
    const double aspect = double(target.width()) / double(target.height());
    const glm::dmat4 viewProj = camera.projectionMatrix(aspect, kNearPlane) * camera.viewMatrix();
    terrain.bindTerrain(m_program, viewProj);
    canopy.bind(m_program, kCanopyUnit);
    m_program.set("uCanopyHeight", float(s.treeHeight));
    m_program.set("uCanopyDark", std::clamp(s.darkest, 0.0f, 1.0f));
    m_program.set("uLayerShift", s.shift);
    m_program.set("uClipAniso", std::clamp(s.anisotropy, 1.0f, kMaxAnisotropy));
    const float shade = std::clamp(s.shading, 0.0f, 1.0f);
    m_program.set("uShade", shade);
    m_program.set("uNormals", shade > 0.0f ? 1 : 0);
    m_program.set("uSunDir", glm::vec3(glm::normalize(glm::dvec3(-0.5, 0.6, 0.75))));
    m_program.use();
    // Layer 0 lies on the ground: equal depth wins (reversed Z, GL_GEQUAL), so the lowest layer covers the ground.
    glDepthFunc(GL_GEQUAL);
    // A piece farther (horizontally) than this shows the whole stack below minLiftPixels: no layers there.
    const double pixelsPerRadian = double(target.height()) / (2.0 * std::tan(glm::radians(camera.fovYDeg) / 2.0));
    const double range = s.treeHeight * pixelsPerRadian / std::max(s.minLiftPixels, 1e-3);
    const glm::dvec2 eye(camera.position.x, camera.position.y);
    auto instances = [&](int, glm::dvec2 lo, glm::dvec2 hi) {
        const glm::dvec2 nearest = glm::clamp(eye, lo, hi);
        return glm::length(nearest - eye) <= range ? layers : 0;
    };
    GeometryFrameStats st = terrain.geometry().drawInstanced(m_program, viewProj, s.treeHeight, instances);
    glBindVertexArray(0);
    glDepthFunc(GL_GREATER);
    return st;
}

} // namespace seasonview
