#pragma once
// Draws a texture-atlas tree file (AtlasTree.h) in a scene: the tree's triangles with node atlases chosen by
// AtlasTraversal and paged by AtlasPager under a byte capacity (Buchholz's thesis §4.4, §4.6), or with their
// original textures, or with one dummy texture (`--city atlas|original|flat`); roofs with the terrain's imagery
// clipmap of the current season (§4.8.2); untextured triangles in one colour. Upload and draw only: the choices are
// the plain-C++ classes'.
#include "AtlasPager.h"
#include "AtlasTraversal.h"
#include "AtlasTree.h"
#include "BlockMapGL.h"
#include "BlockMapTraversal.h"
#include "Camera.h"
#include "ClipmapTerrainRendererGL.h"
#include "NodeOcclusion.h"
#include "Scene.h"
#include "gl/GlObjects.h"
#include "gl/RenderTarget.h"
#include "gl/ShaderProgram.h"

#include <map>
#include <set>
#include <memory>
#include <optional>
#include <string>

namespace seasonview::city {

/// Blockmap: the atlas tree near, BlockMaps far (BlockMapTraversal.h: the switch by projected error).
enum class CityMode { Atlas, Original, Flat, BlockMap };
std::optional<CityMode> parseCityMode(const std::string& name);
const char* cityModeName(CityMode m);

/// How BC atlases reach the GPU: compressed (S3TC, as stored: 1/6 of the bytes, sampled natively by GPUs), decoded to
/// RGB(A)8 on upload (what software rasterisers sample fastest: llvmpipe decodes BC at every texel fetch, which cost
/// the atlas mode 8 % of its frame time), or auto: decoded on a software rasteriser or without S3TC, else compressed.
/// Deflate atlases are always uploaded decoded. The pager counts the bytes as uploaded.
enum class AtlasUpload { Auto, Compressed, Decoded };
std::optional<AtlasUpload> parseAtlasUpload(const std::string& name); // "auto", "compressed", "decoded"
const char* atlasUploadName(AtlasUpload u);

/// Blockmap mode: how the maps seen at a grazing angle (those the near field may hide, each tested with an occlusion
/// query on its box first) are drawn. Conditional: each on its own under conditional rendering, so the GPU skips a
/// hidden one without the CPU waiting (a draw call each). Readback: the answers read on the CPU (one wait for the GPU)
/// and the visible ones drawn with the others in one instanced draw; on a software rasteriser the conditional draws
/// wait for the answers too, and each of them costs a draw call's setup on the issuing thread. Auto: readback on a
/// software rasteriser, else conditional. The same maps are drawn either way.
enum class MapOcclusion { Auto, Conditional, Readback };
std::optional<MapOcclusion> parseMapOcclusion(const std::string& name); // "auto", "conditional", "readback"
const char* mapOcclusionName(MapOcclusion m);

/// How the city follows the terrain's view. The roofs show the terrain's imagery (thesis §4.8.2: roofs are textured
/// from it): one season, the two blended, or split at the swipe line. The levels view shows what drew each pixel.
struct CityView {
    int season = 0;       // 0 leaf-on, 1 leaf-off
    float blend = -1.0f;  // >= 0: leaf-on mixed with leaf-off by this much (the blend view)
    float swipe = -1.0f;  // >= 0: leaf-on left of this fraction of the width, leaf-off right (the swipe view)
    bool imagery = true;  // false: one colour (the relief view shows no imagery)
    // Each pixel in the colour of what drew it (kSourceColours): an atlas, an original texture, a plain triangle, or
    // a BlockMap (lighter for a coarser one), shaded by its face.
    bool sources = false;
};
/// The colours of sources (apart from the terrain's level colours): atlas white, original brown, plain dark grey,
/// BlockMaps of the finest level deep purple (coarser ones lighter).
inline constexpr float kSourceColours[4][3] = {{0.95f, 0.95f, 0.95f}, {0.55f, 0.35f, 0.2f}, {0.35f, 0.35f, 0.35f}, {0.5f, 0.1f, 0.55f}};
/// The city's view for a terrain view: roofs leaf-off for leafoff, the ground elsewhere's season for the canopy view,
/// the blend and the swipe as the terrain draws them, no imagery for relief, leaf-on otherwise (lod, wireframe show
/// the leaf-on imagery under their colours); the levels view shows the sources.
CityView cityViewFor(const ImagerySettings& s);

/// Moves a tree's positions (read in its own CRS) into the scene's local frame, and with `placeOnTerrain` sets each
/// building's lowest vertex on the lowest ground under it; a tree already in the scene's frame is left as it is.
/// What CityRendererGL::create() does to the file it draws.
void placeInSceneFrame(const Scene& scene, AtlasTreeFile& file, bool placeOnTerrain);

struct CitySettings {
    CityMode mode = CityMode::Atlas;
    double tpp = 1.0;                              // pixels per texel (§4.5.2), adjustable per frame
    std::uint64_t capacityBytes = 256ull << 20;    // resident atlases and original textures (GPU bytes)
    std::uint64_t uploadBytesPerFrame = 16ull << 20;
    bool threaded = true;                          // background loader (false: loads inside update())
    CityView view;                                 // the roofs' imagery, the sources (cityViewFor the terrain's view)
    bool placeOnTerrain = true;                    // a model in its own CRS: each building set on the scene's DEM
    float anisotropy = 8.0f;                       // the samplers' maximum anisotropy (render/bench --aniso)
    AtlasUpload upload = AtlasUpload::Auto;        // BC atlases: compressed or decoded on upload
    bool occlusion = true;                         // atlas, blockmap: occlusion queries on node and map boxes (draw())
    bool flushFirst = true;                        // update() first hands the GPU what is queued (glFlush)
    MapOcclusion mapOcclusion = MapOcclusion::Auto; // blockmap mode: the tested maps' draws (MapOcclusion)
    // Blockmap mode: the city's BlockMaps (a file of buildCityBlockMaps over the tree's triangles as placed in the
    // scene: prepareCityBlockMaps) and the pixels a map's texel may cover where it is drawn instead of polygons.
    std::string blockMaps;
    double blockMapErrorPx = 1.0;
    // Blockmap mode, measuring pops: draw() keeps the last frame's switches between polygons and maps and between
    // map levels (BlockMapTraversal::cut's `previous`) instead of making this frame's (which it otherwise remembers).
    bool holdSwitches = false;
};

/// Per-frame counters (the issue's: nodes drawn, texture binds, draw calls, blocks resident, bytes, loader queue).
struct CityFrameStats {
    std::int64_t triangles = 0;
    int drawCalls = 0;
    int textureBinds = 0;
    int atlasNodes = 0;            // atlases drawn
    int originalLeaves = 0;        // leaves drawn with their originals
    int coarserThanWanted = 0;     // nodes drawn with a coarser atlas while finer data loads
    int missingOriginals = 0;      // original mode: triangle runs drawn flat because their texture is not resident
    int occludedNodes = 0;         // atlas mode with occlusion: nodes in view found hidden, not drawn
    int occlusionQueries = 0;      // box queries issued (the deferred nodes' and the end-of-frame ones)
    int occlusionWaits = 0;        // rounds in which the frame waited for query answers
    std::size_t blocksResident = 0;
    std::uint64_t residentBytes = 0;
    // What the pagers' requests would take whole, and what of it fits the capacity (PagerStats::requestedBytes,
    // idealBytes): requested above ideal is a view that wants more than the capacity holds.
    std::uint64_t requestedBytes = 0, idealBytes = 0;
    std::size_t loaderQueue = 0;
    std::uint64_t uploadedBytes = 0; // this frame
    double uploadMs = 0;             // this frame's update(): GL uploads of arriving blocks and deletes of evicted ones
    double waitMs = 0;               // draw(): waiting for occlusion query answers (the GPU catching up)
    std::size_t evictedBlocks = 0;   // this frame
    int blockMaps = 0;               // blockmap mode: maps drawn
    int blockMapsNotResident = 0;    // blockmap mode: maps the view wants that are loading (polygons stand in)
    // blockmap mode: GPU bytes the maps' pool has allocated (BlockMapPoolGL: its segments of tiles and of wall
    // words). The pager counts each resident map's own bytes (residentBytes); this is above them by the pool's
    // free tiles and words.
    std::uint64_t blockMapPoolBytes = 0;
    // blockmap mode, this frame: bytes of resident maps the pool copied (segments given back or merged; growing copies
    // none).
    std::uint64_t blockMapMovedBytes = 0;
    // GL storage held (atlases, original textures whole or while their parts arrive, the BlockMaps' pool): what
    // residentBytes accounts for (never above the capacity), and the pool's free tiles and words, which are not
    // (blockMapPoolBytes).
    std::uint64_t allocatedBytes = 0;
};

class CityRendererGL {
public:
    /// Opens the tree and uploads its geometry in the scene's local frame (converted from the tree's CRS when it
    /// differs; buildings set on the DEM when settings.placeOnTerrain and the tree is not in the scene's frame).
    static Result<std::unique_ptr<CityRendererGL>> create(const Scene& scene, const std::string& treePath,
                                                          const CitySettings& settings);
    ~CityRendererGL();

    /// Paging for a view (call once per frame before draw): requests, evictions, uploads within the budget. With
    /// settings().flushFirst it begins with glFlush, so that the GPU draws what was issued before (the terrain)
    /// while the CPU pages and issues the city: a driver that keeps a frame's commands until the swap or glFinish
    /// would run the two one after the other.
    void update(const Camera& camera, int width, int height);
    /// Loads everything the view wants before returning (stills).
    void complete(const Camera& camera, int width, int height);
    /// Forgets what occlusion queries answered (a still from a new camera: its first draw() then tests every node
    /// before drawing it, nearest first; otherwise nodes new in view would be drawn untested).
    void resetOcclusion();
    /// Draws into `target` (depth-tested against what is there: draw after the terrain). `terrain` textures the
    /// roofs (null: roofs in one colour).
    ///
    /// Atlas mode with settings().occlusion, Coherent Hierarchical Culling (Bittner et al. 2004; Wimmer & Bittner
    /// 2005, GPU Gems 2 ch. 6) on the atlas tree: (1) the traversal draws the nodes known visible, and the nodes new
    /// in view or newly refined untested; (2) the nodes in view found hidden lately are tested nearest first with
    /// occlusion queries on their boxes against the depth drawn so far, one wait per round, and the visible ones
    /// drawn (their subtrees may defer more); while nothing is known (resetOcclusion(), the first frame) every node
    /// is tested before it is drawn, in rounds of the 8, 16, 32, ... nearest so that near nodes hide far ones;
    /// (3) at the end the drawn nodes' boxes are queried against the frame's depth (each node again every 4th
    /// frame), read at the next update() if they are in, else at the next draw(), which waits. A node is skipped
    /// only when its box is hidden now, so once what the view wants is resident the picture is the one without
    /// occlusion culling (tested frame by frame); while atlases load, a refinement waits only for the visible
    /// children's, and nodes found hidden are paged as Culled. The nodes drawn and the triangles fall to what the view can see.
    CityFrameStats draw(const Camera& camera, const ClipmapTerrainRendererGL* terrain, const gl::RenderTarget& target);

    CitySettings& settings() { return m_settings; }
    /// settings().mapOcclusion resolved against this GL (Auto: readback on a software rasteriser).
    MapOcclusion mapOcclusionUsed() const {
        if (m_settings.mapOcclusion != MapOcclusion::Auto) return m_settings.mapOcclusion;
        return m_software ? MapOcclusion::Readback : MapOcclusion::Conditional;
    }
    /// Whether BlockMaps were opened (created in blockmap mode): the mode may then switch between blockmap and atlas.
    bool hasBlockMaps() const { return m_bmTraversal != nullptr; }
    /// Whether BC atlases are uploaded decoded (settings().upload resolved against this GL).
    bool decodesAtlases() const { return m_decodeBc; }
    const AtlasTreeFile& file() const { return m_file; }
    /// The first block that could not be read or decoded (an atlas of the tree, an original texture), as one line
    /// naming its file; empty when none. Such a block is never drawn: a still or a bench that meets one stops, the
    /// viewer says so.
    std::string readError() const;
    std::size_t triangles() const;

private:
    CityRendererGL() = default;
    AtlasView view(const Camera& camera, int width, int height) const;
    void apply(int tree, AtlasPager::Frame&& frame);
    void uploadAtlas(int tree, const LoadedBlock& b);
    void uploadTexture(const LoadedBlock& b);
    /// Mip levels 1.. of an original texture (or of one band's rows): the loader's box mips.
    void uploadMips(const gl::Texture& tex, const LoadedBlock& b);
    struct PendingQuery { std::size_t tree; std::uint32_t node; std::size_t query; std::uint64_t frame; };
    /// The end-of-frame queries of the last draw() into m_occlusion: waiting for them (draw()), or only if they are
    /// all answered already (update()).
    void collectQueries(bool wait);
    /// One occlusion query per node box, depth-tested against what is drawn, writing nothing.
    void queryBoxes(std::size_t tree, const std::vector<std::uint32_t>& nodes, const glm::mat4& viewProj,
                    std::vector<PendingQuery>& out);
    // create()'s stages.
    Status buildPrograms();
    void createGeometry();
    void createSamplers();
    Status createPagers(const std::string& treePath);
    // draw()'s passes.
    struct DrawState;
    struct AtlasPass;
    void setBuildingUniforms(const gl::ShaderProgram& p, const DrawState& ds, float alphaCut) const;
    /// The levels view's colour of source `source` (kSourceColours), alpha 0 in other views.
    glm::vec4 sourceColour(int source) const;
    void drawFlat(std::size_t tree, DrawState& ds);
    void drawOriginal(std::size_t tree, DrawState& ds);
    void drawAtlas(std::size_t tree, DrawState& ds, bool occlusion);
    void issueDraws(const AtlasTraversalResult& result, AtlasPass& pass, DrawState& ds);
    /// The plain triangles; blockmap mode: those `cut` does not cover.
    void drawPlain(DrawState& ds, const ClipmapTerrainRendererGL* terrain, int targetWidth, const BlockMapCut* cut);
    // Blockmap mode.
    bool blockMapsOn() const { return m_bmTraversal && m_settings.mode == CityMode::BlockMap; }
    Status openBlockMaps();
    /// The cut of the view: with every map resident (`ideal`, for paging) or with those that are.
    BlockMapCut blockMapCut(const AtlasView& v, bool ideal) const;
    /// The traversals skip what `cut` covers (an empty cut: nothing).
    void coverWith(const BlockMapCut* cut);
    /// Tree 0's requests with the maps' (blockmap mode: from `ideal`, the view's cut with every map resident), in
    /// priority order.
    std::vector<BlockRequest> requestsWithBlockMaps(std::vector<BlockRequest> requests, const AtlasView& v,
                                                    const BlockMapCut& ideal) const;
    void drawBlockMaps(const BlockMapCut& cut, DrawState& ds, const ClipmapTerrainRendererGL* terrain, int targetWidth);
    void setRoofImagery(const gl::ShaderProgram& p, const DrawState& ds, const ClipmapTerrainRendererGL* terrain,
                        int targetWidth) const;
    std::uint64_t allocatedBytes() const;

    AtlasTreeFile m_file;
    CitySettings m_settings;
    bool m_software = false; // a software rasteriser (gl::currentIsSoftwareRenderer at creation)
    // Blockmap mode (declared before the pagers, which read the file on their thread).
    std::unique_ptr<BlockMapFile> m_bmFile;
    std::unique_ptr<BlockMapQuadtree> m_bmTree;
    std::unique_ptr<BlockMapTraversal> m_bmTraversal;
    BlockMapTriangleOrder m_bmRoofOrder, m_bmOtherOrder; // the plain roofs and the other plain triangles
    std::unique_ptr<BlockMapPoolGL> m_bmPool;    // every resident map
    std::map<std::uint32_t, int> m_blockMaps;   // resident maps: node -> its handle in m_bmPool
    std::uint64_t m_bmMovedReported = 0;        // m_bmPool->movedBytes() at the last frame's stats
    BlockMapCut m_lastCut; // the last draw()'s (not kept while holdSwitches)
    // Over the boxes' back faces, over their front faces; [1] the blend view's (roofVariant()).
    gl::ShaderProgram m_bmPrograms[2], m_bmFrontPrograms[2];
    std::vector<gl::Query> m_bmQueries;              // the maps' box queries, reused every frame
    std::vector<std::unique_ptr<AtlasTraversal>> m_traversals;
    std::vector<std::unique_ptr<AtlasPager>> m_pagers;
    std::vector<gl::Buffer> m_vbo;       // per tree: TreeVertex
    std::vector<gl::VertexArray> m_vao;
    gl::Buffer m_plainVbo;
    gl::VertexArray m_plainVao;
    std::size_t m_plainRoofs = 0, m_plainOthers = 0;
    std::vector<std::map<std::uint32_t, gl::Texture>> m_atlases; // per tree: node -> texture
    std::map<std::uint32_t, gl::Texture> m_textures;             // original textures (shared by both trees)
    // Original textures paged in parts (AtlasPager: over twice an atlas's bytes) while some part is missing: the
    // texture with the parts' rows uploaded so far; it moves to m_textures, mipmapped, once all are in.
    struct PartialTexture {
        gl::Texture texture;
        std::set<std::uint16_t> parts;
        int total = 0;
    };
    std::map<std::uint32_t, PartialTexture> m_partialTextures;
    gl::Texture m_dummy;
    gl::Sampler m_atlasSampler, m_repeatSampler, m_clampSampler;
    gl::ShaderProgram m_atlasProgram, m_originalProgram, m_flatProgram, m_plainProgram;
    gl::ShaderProgram m_roofPrograms[2]; // [1] the blend view's (roofVariant())
    // The roofs' imagery programs (shaders/common_roof.glsl) are built per view kind: 1 the blend view (both seasons
    // sampled), 0 the others (the season shown, the other only where the scene's seasons may lack data).
    bool m_seasonsComplete = false; // both seasons read as they are, no nodata (SEASONS_COMPLETE)
    std::vector<std::string> roofDefines(int variant) const;
    int roofVariant() const;
    bool m_decodeBc = false; // BC atlases decoded to RGB(A)8 on upload
    std::uint64_t m_frame = 0, m_frameUploaded = 0, m_frameEvicted = 0;
    double m_frameUploadMs = 0;
    std::string m_uploadError; // the first atlas whose blob did not decode on upload
    std::unique_ptr<AtlasPager> m_originalPager; // original mode: pages the originals the view shows
    // Occlusion culling (atlas mode): the answers and the policy per tree, the queries.
    std::vector<std::unique_ptr<NodeOcclusion>> m_occlusion;
    std::vector<gl::Query> m_queries;                // GL_ANY_SAMPLES_PASSED_CONSERVATIVE, reused every frame
    std::size_t m_queriesUsed = 0;
    std::vector<PendingQuery> m_frameEndQueries;     // step (3), answered at the next update() or draw()
    gl::Buffer m_boxVbo, m_boxIbo;
    gl::VertexArray m_boxVao;
    gl::ShaderProgram m_boxProgram;
};

} // namespace seasonview::city
