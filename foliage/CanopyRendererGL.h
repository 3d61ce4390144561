#pragma once
// The stacked canopy (Ropinski et al. 2007 §4.2): N copies of the terrain's geometry clipmap (one instanced draw per
// piece), copy i lifted to i / (N − 1) of the tree height; a fragment of layer i stays only where the derived canopy
// layer (CanopyClipmapGL.h) says its texel belongs to layer i, coloured with the leaf-on imagery, darker towards the
// lower layers, its texture coordinates shifted slightly per layer. Drawn after the terrain's `canopy` view (whose
// ground shows leaf-off under the crowns), into the same depth buffer.
#include "CanopyClipmapGL.h"
#include "ClipmapTerrainRendererGL.h"

#include <glm/vec2.hpp>

namespace seasonview {

struct CanopyDrawSettings {
    double treeHeight = 15.0;       // metres: the top layer's lift (the scene's tree_height_m)
    float darkest = 0.5f;           // colour factor of the lowest layer (the top layer keeps the leaf-on colour)
    glm::vec2 shift{0.3f, 0.2f};    // texture shift per layer, level-0 texels (§4.2)
    float anisotropy = 8.0f;        // as the terrain's ImagerySettings
    float shading = 0.0f;
    double minLiftPixels = 1.0;     // pieces where the whole stack is shorter than this on screen get no layers
};

class CanopyRendererGL {
public:
    static Result<std::unique_ptr<CanopyRendererGL>> create();

    /// Draws canopy.options().layers layers over the frame `terrain` just rendered into `target`.
    GeometryFrameStats render(const Camera& camera, const ClipmapTerrainRendererGL& terrain, const CanopyClipmapGL& canopy,
                              const CanopyDrawSettings& settings, const gl::RenderTarget& target) const;

private:
    CanopyRendererGL() = default;
    gl::ShaderProgram m_program;
};

} // namespace seasonview
