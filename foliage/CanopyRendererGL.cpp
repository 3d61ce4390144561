#include "CanopyRendererGL.h"

#include "ReferenceRendererGL.h" // kBackgroundColor
#include "TerrainMeshGL.h"       // kNearPlane, beginTerrainPass
#include "gl/FrameStages.h"

#include <algorithm>
#include <cassert>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
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

double lowestElevationTan(const glm::dvec3& eye, const glm::dvec3& lo, const glm::dvec3& hi, double treeHeight) {
    const double dz = eye.z - (hi.z + treeHeight);
    if (dz <= 0.0) return 0.0;
    const glm::dvec2 e(eye);
    const double horizontal = glm::length(glm::max(glm::abs(glm::dvec2(lo) - e), glm::abs(glm::dvec2(hi) - e)));
    return dz / std::max(horizontal, 1e-9);
}

bool canopyPatchMarches(const glm::dvec3& eye, const glm::dvec3& lo, const glm::dvec3& hi, double treeHeight,
                        double heightMargin) {
    const double descent = lowestElevationTan(eye, lo, hi, treeHeight); // of every ray into the stack
    if (descent <= 0.0) return false;
    const double size = std::max(std::min(hi.x - lo.x, hi.y - lo.y) + 2.0 * std::max(heightMargin, 0.0), 1e-9);
    const double slope = (hi.z - lo.z) / size; // at least the terrain's steepest rise across the box, about
    return descent > slope + 0.05;
}

CanopyLevelBounds::CanopyLevelBounds(const Camera& camera, double pixelsPerRadian, double texelMetres)
    : m_eye(camera.position), m_pixelsPerRadian(pixelsPerRadian), m_texelMetres(std::max(texelMetres, 1e-9)) {}

glm::ivec2 CanopyLevelBounds::levels(const glm::dvec3& lo, const glm::dvec3& hi, int clipLevels) const {
    // One level for the whole patch (like a geometry clipmap level, chosen per region rather than per pixel): the
    // level of the footprint at its centre, d / (ppr sin θ) metres at distance d seen at elevation θ over a
    // horizontal surface, the larger of the two screen-axis derivatives the ground pass takes its level from.
    // The layer shader reads this level, so CanopyClipmapGL::maxValueOver over it bounds what any fragment reads.
    const glm::dvec3 c = (lo + hi) / 2.0;
    const double d = glm::length(c - m_eye);
    const double sinElevation = std::max(std::abs(m_eye.z - c.z) / std::max(d, 1e-9), 0.05);
    const double metres = d / (m_pixelsPerRadian * sinElevation);
    const int l = metres <= m_texelMetres ? 0 : int(std::floor(std::log2(metres / m_texelMetres)));
    const int level = std::clamp(l, 0, clipLevels);
    return {level, level};
}

GeometryFrameStats CanopyRendererGL::renderView(const Camera& camera, const ClipmapTerrainRendererGL& terrain,
                                                ImagerySettings imagery, const CanopyClipmapGL& canopy,
                                                const CanopyDrawSettings& s, const TrunksGL* trunks,
                                                const gl::RenderTarget& target) const {
    GeometryFrameStats st;
    auto add = [&](const GeometryFrameStats& x) {
        st.triangles += x.triangles;
        st.drawCalls += x.drawCalls;
        st.piecesCulled += x.piecesCulled;
        st.levelsDrawn = std::max(st.levelsDrawn, x.levelsDrawn);
    };
    if (s.mode == CanopyDrawMode::March) {
        target.bind();
        beginTerrainPass(kBackgroundColor.r, kBackgroundColor.g, kBackgroundColor.b, kBackgroundColor.a);
        m_entryRecorded = false;
        add(render(camera, terrain, canopy, s, target, CanopyPass::Marched)); // where each pixel's ray enters
        if (!m_entryRecorded) {
            // No layer to march (none above the ground, or no tree height): nothing recorded, nothing to march.
        } else if (imagery.terrain && imagery.view == ImageryView::Canopy &&
                   ClipmapTerrainRendererGL::resolvesDeferred(imagery)) {
            imagery.canopyMarch = &m_marchInput; // the terrain's resolve marches: one full-screen pass for both
        } else {
            add(marchForward(camera, terrain, canopy, target));
        }
        imagery.clear = false;
        gl::markStage("canopy_marched");
    }
    add(terrain.render(camera, imagery, target));
    gl::markStage("terrain");
    add(render(camera, terrain, canopy, s, target, CanopyPass::Rasterised));
    gl::markStage("canopy_layers");
    // Up into the lowest layers, so no gap shows between a trunk and its crown.
    if (trunks) add(trunks->draw(camera, terrain, s.crownBase + 0.1 * (s.treeHeight - s.crownBase), target));
    gl::markStage("trunks");
    return st;
}

void CanopyRendererGL::ensureEntry(const gl::RenderTarget& target) const {
    const glm::ivec2 size = entrySize(target);
    if (m_entryFramebuffer && m_entrySize == size) return;
    m_entryFramebuffer = gl::Framebuffer::create();
    m_entryDepth = gl::Renderbuffer::create();
    glNamedRenderbufferStorage(m_entryDepth.id(), GL_DEPTH_COMPONENT32F, size.x, size.y);
    for (int i = 0; i < 2; ++i) {
        m_entry[i] = gl::Texture::create(GL_TEXTURE_2D);
        glTextureStorage2D(m_entry[i].id(), 1, GL_RGBA32F, size.x, size.y);
        glTextureParameteri(m_entry[i].id(), GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        glTextureParameteri(m_entry[i].id(), GL_TEXTURE_MAG_FILTER, GL_NEAREST);
        glNamedFramebufferTexture(m_entryFramebuffer.id(), GLenum(GL_COLOR_ATTACHMENT0 + i), m_entry[i].id(), 0);
    }
    glNamedFramebufferRenderbuffer(m_entryFramebuffer.id(), GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, m_entryDepth.id());
    const GLenum buffers[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
    glNamedFramebufferDrawBuffers(m_entryFramebuffer.id(), 2, buffers);
    assert(glCheckNamedFramebufferStatus(m_entryFramebuffer.id(), GL_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE &&
           "CanopyRendererGL: incomplete entry framebuffer");
    m_entrySize = size;
    if (!m_emptyVao) m_emptyVao = gl::VertexArray::create();
    for (int i = 0; i < 2; ++i) m_marchInput.entry[i] = m_entry[i].id();
}

GeometryFrameStats CanopyRendererGL::marchForward(const Camera& camera, const ClipmapTerrainRendererGL& terrain,
                                                  const CanopyClipmapGL& canopy, const gl::RenderTarget& target) const {
    target.bind();
    const double aspect = double(target.width()) / double(target.height());
    const glm::dmat4 viewProj = camera.projectionMatrix(aspect, kNearPlane) * camera.viewMatrix();
    const gl::ShaderProgram& marcher = terrain.program("terrain_resolve.vert", "canopy_march.frag", {"VIEW 0"});
    terrain.bindTerrain(marcher, viewProj);
    canopy.bind(marcher, kCanopyUnit);
    for (int i = 0; i < 2; ++i) glBindTextureUnit(GLuint(kCanopyEntryUnit + i), m_entry[i].id());
    marcher.set("uEntry", kCanopyEntryUnit);
    marcher.set("uEntryRay", kCanopyEntryUnit + 1);
    marcher.set("uClipAniso", m_marchAnisotropy);
    marcher.set("uShade", m_marchShade);
    marcher.set("uSunDir", glm::vec3(glm::normalize(glm::dvec3(-0.5, 0.6, 0.75))));
    m_marchInput.setUniforms(marcher);
    marcher.use();
    // Every pixel with an entry is written: the hit's colour and depth, or, where the ray meets no layer, the far
    // depth under a colour of alpha 0 (blended away), so the terrain drawn next shows there.
    glDepthFunc(GL_ALWAYS);
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glBindVertexArray(m_emptyVao.id());
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glDisable(GL_BLEND);
    glBindVertexArray(0);
    glDepthFunc(GL_GREATER);
    for (int i = 0; i < 2; ++i) glBindTextureUnit(GLuint(kCanopyEntryUnit + i), 0);
    GeometryFrameStats st;
    st.drawCalls = 1;
    return st;
}

Result<std::unique_ptr<CanopyRendererGL>> CanopyRendererGL::create() {
    // The programs are the terrain renderer's (ClipmapTerrainRendererGL::program): built for its clipmaps' layouts.
    return std::unique_ptr<CanopyRendererGL>(new CanopyRendererGL());
}

GeometryFrameStats CanopyRendererGL::render(const Camera& camera, const ClipmapTerrainRendererGL& terrain,
                                            const CanopyClipmapGL& canopy, const CanopyDrawSettings& s,
                                            const gl::RenderTarget& target, CanopyPass pass) const {
    const int layers = canopy.options().layers;
    const int first = s.crownBase > 0.0 ? 0 : 1; // on the ground, layer 0 is the ground pass's
    if (layers - first < 1 || s.treeHeight <= 0.0) return {};
    target.bind();
    const double aspect = double(target.width()) / double(target.height());
    const glm::dmat4 viewProj = camera.projectionMatrix(aspect, kNearPlane) * camera.viewMatrix();
    const bool march = pass == CanopyPass::Marched;
    if (march && s.mode != CanopyDrawMode::March) return {};
    const float shade = std::clamp(s.shading, 0.0f, 1.0f);
    // NORMALS is a compile-time constant (shaders/terrain_geometry.vert): the layers with and without shading. The
    // march's record without takes the plane its rays are intersected over from each triangle's own
    // (terrain_clipmap.frag): the vertex normals cost four height fetches a vertex.
    const std::string normals = std::string("NORMALS ") + (shade > 0.0f ? "1" : "0");
    const gl::ShaderProgram& program =
        march ? terrain.program("terrain_geometry.vert", "terrain_clipmap.frag",
                                {"CANOPY_LAYER", "CANOPY_MARCH", normals})
              : terrain.program("terrain_geometry.vert", "terrain_clipmap.frag", {"CANOPY_LAYER", normals});
    // The record is drawn at 1 / kEntryScale of the target's resolution: its texel (i, j) covers the frame's pixels
    // kEntryScale i .. kEntryScale (i + 1) - 1 (and likewise in y), past the frame's edge for an odd size.
    const glm::ivec2 entry = entrySize(target);
    glm::dmat4 toEntry(1.0);
    toEntry[0][0] = double(target.width()) / double(kEntryScale * entry.x);
    toEntry[1][1] = double(target.height()) / double(kEntryScale * entry.y);
    toEntry[3][0] = toEntry[0][0] - 1.0;
    toEntry[3][1] = toEntry[1][1] - 1.0;
    const glm::dmat4 drawnViewProj = march ? toEntry * viewProj : viewProj;
    terrain.bindTerrain(program, drawnViewProj);
    canopy.bind(program, kCanopyUnit);
    if (march) {
        // The top layer's patches record where each pixel's ray enters the stack, into their own targets and depth
        // buffer (the terrain's geometry pass still needs the ground under them); a full-screen pass marches.
        ensureEntry(target);
        glBindFramebuffer(GL_FRAMEBUFFER, m_entryFramebuffer.id());
        glViewport(0, 0, entry.x, entry.y);
        const float none[4] = {-1.0f, -1.0f, 0.0f, 0.0f};
        glClearNamedFramebufferfv(m_entryFramebuffer.id(), GL_COLOR, 0, none);
        const float far = 0.0f; // reversed Z
        glClearNamedFramebufferfv(m_entryFramebuffer.id(), GL_DEPTH, 0, &far);
        m_entryRecorded = true;
    }
    program.set("uCanopyHeight", float(s.treeHeight));
    program.set("uCrownBase", float(std::clamp(s.crownBase, 0.0, s.treeHeight)));
    program.set("uCanopyDark", std::clamp(s.darkest, 0.0f, 1.0f));
    program.set("uLayerShift", s.shift);
    program.set("uClipAniso", std::clamp(s.anisotropy, 1.0f, kMaxAnisotropy));
    program.set("uShade", shade);
    program.set("uSunDir", glm::vec3(glm::normalize(glm::dvec3(-0.5, 0.6, 0.75))));
    program.set("uFirstLayer", first);
    program.set("uEye", glm::vec3(camera.position));
    // Local metres -> leaf-on pixels, linearised under the camera (exact for projected scenes).
    glm::dmat2 toPixel(1.0);
    if (s.scene) {
        const glm::dvec2 c = glm::clamp(glm::dvec2(camera.position), s.scene->localMin, s.scene->localMax);
        const glm::dvec2 p0 = s.scene->localToImagePixel(c);
        toPixel = glm::dmat2(s.scene->localToImagePixel(c + glm::dvec2(1.0, 0.0)) - p0,
                             s.scene->localToImagePixel(c + glm::dvec2(0.0, 1.0)) - p0);
    }
    program.set("uLocalToPixel", glm::mat2(toPixel));
    program.use();
    // Layer 0 lies on the ground: equal depth wins (reversed Z, GL_GEQUAL), so the lowest layer covers the ground.
    glDepthFunc(GL_GEQUAL);
    const double pixelsPerRadian = double(target.height()) / (2.0 * std::tan(glm::radians(camera.fovYDeg) / 2.0));
    // Texels a layer's fragment may reach past its patch: the per-layer shift of the top layer, and one.
    const double reach = std::max(std::abs(s.shift.x), std::abs(s.shift.y)) * double(layers) + 1.0;
    const double texelMetres = s.scene ? s.scene->gsd : 1.0;
    const CanopyLevelBounds levelBounds(camera, pixelsPerRadian, texelMetres);
    const int clipLevels = canopy.clipLevels();
    const double stackHeight = s.treeHeight - std::clamp(s.crownBase, 0.0, s.treeHeight);
    auto instances = [&](int level, glm::dvec3 lo, glm::dvec3 hi, std::vector<glm::ivec2>& out) {
        // In march mode each patch is drawn by one of the two passes. The patch's heights reach two of its level's
        // cells past it (GeometryClipmapGL's culling boxes).
        if (s.mode == CanopyDrawMode::March &&
            canopyPatchMarches(camera.position, lo, hi, s.treeHeight, 2.0 * terrain.geometry().cellMetres(level)) != march)
            return;
        int top = layers - 1; // the highest layer any texel the patch's fragments read belongs to
        glm::ivec2 levels(0, 255);
        if (s.scene) {
            glm::dvec2 pmin(1e300), pmax(-1e300);
            for (const glm::dvec2 c : {glm::dvec2(lo), glm::dvec2(hi), glm::dvec2(lo.x, hi.y), glm::dvec2(hi.x, lo.y)}) {
                const glm::dvec2 p = s.scene->localToImagePixel(c);
                pmin = glm::min(pmin, p);
                pmax = glm::max(pmax, p);
            }
            levels = levelBounds.levels(lo, glm::dvec3(hi.x, hi.y, hi.z + s.treeHeight), clipLevels);
            double marchReach = 0.0; // level-0 pixels a ray entering the patch's top may travel down the stack
            if (march) {
                // Horizontal metres per metre of descent, at most over the box (the eye's lowest elevation angle
                // to it); rays nearly level with the top reach far, and such patches look at everything.
                const double descent = lowestElevationTan(camera.position, lo, hi, s.treeHeight);
                marchReach = descent > 1e-6 ? std::min(stackHeight / descent / texelMetres * 1.25, 1e6) : 1e6;
            }
            top = canopy.maxValueOver(pmin - reach - marchReach, pmax + reach + marchReach, levels.x, levels.y) - 1;
            // The rasterised layers read levels.x over the box: recorded here, as their shader records nothing (a
            // fragment shader writing a buffer loses the early depth test the layers drawn top first rely on).
            if (!march) canopy.noteRead(levels.x, pmin - reach, pmax + reach);
        }
        if (top < first) return;
        const int packed = levels.x | (std::min(levels.y, 255) << 8);
        if (march) {
            out.push_back({top, packed}); // one fragment per pixel: the march starts at the top reachable layer
            return;
        }
        const int n = canopyPieceLayers(camera.position, pixelsPerRadian, lo, hi, s, top - first + 1);
        const int span = top - first;
        // Top first; thinned evenly, the top layer always among them.
        for (int j = 0; j < n; ++j)
            out.push_back({n <= 1 ? top : first + int(std::lround(double((n - 1 - j) * span) / double(n - 1))), packed});
    };
    GeometryFrameStats st = terrain.geometry().drawPatches(program, drawnViewProj, s.treeHeight, instances);
    if (march) {
        target.bind();
        // What the march (common_canopy_march.glsl) needs besides the terrain's bindings, for whichever pass marches.
        const float canopyHeight = float(s.treeHeight), crownBase = float(std::clamp(s.crownBase, 0.0, s.treeHeight));
        const float dark = std::clamp(s.darkest, 0.0f, 1.0f);
        const glm::vec2 shift = s.shift;
        const glm::vec3 eye(camera.position);
        const glm::mat2 localToPixel(toPixel);
        // The view ray through window point (x, y), local metres: towards the point of a plane parallel to the
        // image's (here NDC depth 1, the near plane), affine in x and y.
        const glm::dmat4 inverse = glm::inverse(viewProj);
        auto towards = [&](double x, double y) {
            const glm::dvec4 q = inverse * glm::dvec4(2.0 * x / double(target.width()) - 1.0,
                                                      2.0 * y / double(target.height()) - 1.0, 1.0, 1.0);
            return glm::dvec3(q) / q.w - camera.position;
        };
        const glm::vec3 ray0(towards(0.0, 0.0)), rayDx(towards(1.0, 0.0) - towards(0.0, 0.0)),
            rayDy(towards(0.0, 1.0) - towards(0.0, 0.0));
        m_marchInput.setUniforms = [=](const gl::ShaderProgram& p) {
            p.set("uCanopyHeight", canopyHeight);
            p.set("uCrownBase", crownBase);
            p.set("uCanopyDark", dark);
            p.set("uLayerShift", shift);
            p.set("uFirstLayer", first);
            p.set("uEye", eye);
            p.set("uLocalToPixel", localToPixel);
            p.set("uRay0", ray0);
            p.set("uRayDx", rayDx);
            p.set("uRayDy", rayDy);
        };
        m_marchAnisotropy = std::clamp(s.anisotropy, 1.0f, kMaxAnisotropy);
        m_marchShade = shade;
    }
    glBindVertexArray(0);
    glDepthFunc(GL_GREATER);
    return st;
}

} // namespace seasonview
