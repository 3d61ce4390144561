#pragma once
// The brute-force reference renderer: the full-resolution DEM as one mesh, the full-resolution imagery of each
// season as plain mipmapped textures (split into array layers when larger than the GL limit). Slow on purpose;
// the clipmap renderers are compared against its images.
#include "Camera.h"
#include "ReferenceMesh.h"
#include "Scene.h"
#include "TerrainMeshGL.h"
#include "gl/GlObjects.h"
#include "gl/RenderTarget.h"
#include "gl/ShaderProgram.h"

#include <glm/vec4.hpp>

#include <cstdint>
#include <array>
#include <filesystem>
#include <memory>
#include <optional>

namespace seasonview {

enum class Season { LeafOn, LeafOff };

/// Sky colour behind the terrain (linear RGBA, 0..1). Tests look for it to find holes.
inline const glm::vec4 kBackgroundColor{0.62f, 0.74f, 0.86f, 1.0f};
/// The ground where neither season has data: a neutral grey, never black (black reads as dark imagery).
inline const glm::vec3 kNoDataColor{0.56f, 0.55f, 0.52f};

struct ReferenceOptions {
    int maxTextureSize = 0; // 0: GL_MAX_TEXTURE_SIZE; smaller values force the tiled path (tests)
    float anisotropy = 16.0f;
    /// The seasons' prepared pyramid level 0 (leaf-on, leaf-off: premultiplied RGBA on the working grid). Required
    /// for a warped scene (Scene::warped()); otherwise the seasons' own files are read.
    std::optional<std::array<std::filesystem::path, 2>> levelZero;
};

struct ReferenceStats {
    std::int64_t triangles = 0;
    int textureLayers = 0;
    int meshStride = 1;
};

class ReferenceRendererGL {
public:
    /// Uploads the mesh and both seasons' imagery. Needs a current GL 4.5 context; errors are file problems.
    static Result<std::unique_ptr<ReferenceRendererGL>> create(const Scene& scene, const ReferenceOptions& options = {});

    /// Draws the scene as seen by `camera` into `target` (cleared first).
    void render(const Camera& camera, Season season, const gl::RenderTarget& target) const;

    const ReferenceStats& stats() const { return m_stats; }

private:
    struct SeasonTexture {
        gl::Texture texture;
        TileLayout layout;
    };
    static SeasonTexture upload(const Image<std::uint8_t>& rgba, int maxSize, float anisotropy);

    gl::ShaderProgram m_program;
    std::unique_ptr<TerrainMeshGL> m_mesh;
    SeasonTexture m_seasons[2];
    int m_imageWidth = 0, m_imageHeight = 0;
    ReferenceStats m_stats;
};

} // namespace seasonview
