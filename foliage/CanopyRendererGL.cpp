#include "CanopyRendererGL.h"

#include "TerrainMeshGL.h" // kNearPlane

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

namespace seasonview {

int canopyPieceLayers(const glm::dvec3& eye, double pixelsPerRadian, const glm::dvec3& lo, const glm::dvec3& hi,
                      const CanopyDrawSettings& s, int maxLayers) {
    // The stack over a point at horizontal distance r and height dz below the eye spans about
    // H · ppr · r / (r² + dz²) pixels (a vertical segment of height H seen from distance d = √(r² + dz²),
    // foreshortened by r / d); its largest value over the box decides.
    const glm::dvec2 e(eye), lo2(lo), hi2(hi);
    const double rmin = glm::length(glm::clamp(e, lo2, hi2) - e);
    const double rmax = glm::length(glm::max(glm::abs(lo2 - e), glm::abs(hi2 - e)));
    const double dz = std::max({0.0, eye.z - (hi.z + s.treeHeight), lo.z - eye.z});
    const double r = std::clamp(dz, rmin, rmax); // r / (r² + dz²) is largest at r = dz
    const double stack = r + dz <= 0.0 ? 1e9 : s.treeHeight * pixelsPerRadian * r / (r * r + dz * dz);
    if (stack < s.minLiftPixels || maxLayers < 1) return 0;
    return std::clamp(int(std::ceil(stack / std::max(s.pixelsPerLayer, 1e-3))), 1, maxLayers);
}

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
    const int first = s.crownBase > 0.0 ? 0 : 1; // on the ground, layer 0 is the ground pass's
    if (layers - first < 1 || s.treeHeight <= 0.0) return {};
    target.bind();
    const double aspect = double(target.width()) / double(target.height());
    const glm::dmat4 viewProj = camera.projectionMatrix(aspect, kNearPlane) * camera.viewMatrix();
    terrain.bindTerrain(m_program, viewProj);
    canopy.bind(m_program, kCanopyUnit);
    m_program.set("uCanopyHeight", float(s.treeHeight));
    m_program.set("uCrownBase", float(std::clamp(s.crownBase, 0.0, s.treeHeight)));
    m_program.set("uFirstLayer", first);
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
    const double pixelsPerRadian = double(target.height()) / (2.0 * std::tan(glm::radians(camera.fovYDeg) / 2.0));
    // Texels a layer's fragment may reach past its piece: the per-layer shift of the top layer, and one.
    const double reach = std::max(std::abs(s.shift.x), std::abs(s.shift.y)) * double(layers) + 1.0;
    auto instances = [&](int, glm::dvec3 lo, glm::dvec3 hi) {
        int top = layers - 1; // the highest layer any texel under the piece belongs to
        if (s.scene) {
            glm::dvec2 pmin(1e300), pmax(-1e300);
            for (const glm::dvec2 c : {glm::dvec2(lo), glm::dvec2(hi), glm::dvec2(lo.x, hi.y), glm::dvec2(hi.x, lo.y)}) {
                const glm::dvec2 p = s.scene->localToImagePixel(c);
                pmin = glm::min(pmin, p);
                pmax = glm::max(pmax, p);
            }
            top = canopy.maxValueOver(pmin - reach, pmax + reach) - 1;
        }
        if (top < first) return 0;
        const int n = canopyPieceLayers(camera.position, pixelsPerRadian, lo, hi, s, top - first + 1);
        m_program.set("uPieceTop", top);
        return n;
    };
    GeometryFrameStats st = terrain.geometry().drawInstanced(m_program, viewProj, s.treeHeight, instances);
    glBindVertexArray(0);
    glDepthFunc(GL_GREATER);
    return st;
}

} // namespace seasonview
