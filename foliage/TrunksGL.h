#pragma once
// Trunks at runtime (Ropinski et al. 2007 §4.2, Fig. 6c "additionally integrated trunks"): crown centres and radii
// found in the derived canopy layer of one clip level (maxima of the distance to the nearest texel outside the canopy,
// as CrownCentres.h does offline), so they follow the clipmap's region around the viewer: on a worker thread over a
// copy of the level when the canopy layer is derived on the CPU (CrownSearch.h; update() starts a search and takes
// its trunks when it is done, no frame waits), else on the GPU (shaders/trunk_find.comp, the same centres, its count
// read back); drawn as instanced cylinders (quads facing the eye, shaded as cylinders per fragment)
// (shaders/trunk.vert) from the terrain to the crowns' base with one instanced draw of the count the search read back.
// The offline counterpart is `segment --trees` (CrownCentres.h: distance-transform maxima of the CPU mask).
#include "CanopyClipmapGL.h"
#include "ClipmapTerrainRendererGL.h"
#include "Scene.h"
#include "gl/GlObjects.h"
#include "gl/RenderTarget.h"
#include "gl/ShaderProgram.h"
#include "CrownSearch.h"

#include <glm/mat3x3.hpp>
#include <glm/vec4.hpp>

#include <future>
#include <memory>
#include <optional>
#include <vector>

namespace seasonview {

struct TrunkOptions {
    double texelMetres = 0.5;     // search the finest clip level whose texels are at least this size
    double minCrownRadius = 1.0;  // metres: smaller distance maxima are not crowns (as CrownCentres.h)
    double maxCrownRadius = 8.0;  // metres: the distance search's limit
    int capacity = 16384;         // trunks kept
    float radiusFraction = 0.1f;  // trunk radius / crown radius, clamped to [0.12, 0.5] m
    // update() searches again at most every this many frames (a search covers the whole level: 20 ms on llvmpipe
    // in seasonview_canopy_bench, about 75 ms for the demo's 1024² level while flying); the trunks near the viewer
    // move with the level's window anyway.
    int framesBetweenSearches = 8;
    std::optional<bool> cpuSearch; // search on the CPU (true) or the GPU; unset: where the canopy layer is derived
};

struct Trunk {
    glm::dvec2 local;   // metres, local frame
    double crownRadius; // metres
    int canopyValue;    // layers the centre texel belongs to
};

class TrunksGL {
public:
    static Result<std::unique_ptr<TrunksGL>> create(const Scene& scene, const ClipmapGL& imagery,
                                                    const CanopyClipmapGL& canopy, const TrunkOptions& options = {});

    /// Finds the crown centres of the searched level's current window (after the canopy's update()); returns how
    /// many (a one-integer readback, for the statistics).
    int find();
    /// Once per frame: find() when the searched level's derived blocks changed since the last search and at least
    /// options.framesBetweenSearches frames have passed (else the trunks stand as they are); true when it searched.
    bool update();
    /// Draws the trunks found last, from the terrain up to `trunkHeight` metres, into `target` (depth-tested with
    /// what is there). Returns its triangles and draw calls.
    GeometryFrameStats draw(const Camera& camera, const ClipmapTerrainRendererGL& terrain, double trunkHeight,
                            const gl::RenderTarget& target) const;

    /// The trunks found last (tests, `--trunks` statistics).
    std::vector<Trunk> readTrunks() const;
    int level() const { return m_level; }
    int count() const { return m_count; }
    /// Whether the search runs on the CPU (options().cpuSearch resolved).
    bool searchesOnCpu() const { return m_cpu; }
    ~TrunksGL(); // waits for a search in flight
    TrunksGL(const TrunksGL&) = delete;
    TrunksGL& operator=(const TrunksGL&) = delete;

private:
    // CPU search: the level as it stands now (a copy the worker owns).
    CrownSearchLevel snapshot() const;
    // Stores found centres (at most the capacity) where the draw reads them.
    void store(const std::vector<glm::vec4>& trunks);
    bool m_cpu = false;
    std::future<std::vector<glm::vec4>> m_job;
    TrunksGL(const ClipmapGL& imagery, const CanopyClipmapGL& canopy) : m_imagery(imagery), m_canopy(canopy) {}
    const ClipmapGL& m_imagery;
    const CanopyClipmapGL& m_canopy;
    TrunkOptions m_options;
    gl::ShaderProgram m_find[3]; // trunk_find.comp's passes 0, 1, 2
    gl::Buffer m_buffer;
    gl::VertexArray m_vao;
    glm::dmat3 m_imageToLocal{1.0};
    double m_metresPerPixel = 1.0;
    gl::Texture m_distance; // pass 1's distances, N×N R32F, toroidal like the level
    gl::Texture m_column;   // pass 0's column distances (outside, unknown), N×N RG32F
    float m_minRadius = 1.0f;
    int m_level = 0, m_maxRadius = 2, m_count = 0;
    std::vector<std::int32_t> m_searchedTags; // the level's derived blocks at the last search
    int m_framesSinceSearch = 0;
};

} // namespace seasonview
