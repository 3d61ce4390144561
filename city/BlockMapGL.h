#pragma once
// BlockMaps on the GPU (Cignoni et al. 2007 §3.2), drawn by ray casting in a fragment shader (shaders/blockmap.frag,
// the copy of BlockMap.cpp's traceBlockMap) over their bounding boxes, writing each hit's colour and depth so they
// compose with the terrain and the polygons drawn around them.
//
// BlockMapPoolGL holds every resident map of a city in storage shared by all of them, so that any set of them is a few
// instanced draws (§4: the paper's renderer draws a frame's BlockMaps as one batch of boxes): per texel its height,
// roof normal, distance, wall column, parts of the texel, foot and second prism's top in an RGBA32UI texture buffer
// (BlockMapPacked::tile), n² texels a map (a tile;
// buffers, as texture uploads cost llvmpipe about 17 ms a MB against 1 ms for buffers); the wall columns' normals and
// colours as 32-bit words in another texture buffer, in pages of kBlockMapPageWords taken wherever they are free (the
// map's first page starts with its page table), so maps come and go with no room lost between them. The storage is
// segments that are never resized: tile segments and page segments (a buffer each);
// a map's tile lies in one tile segment and all its pages in one page segment. A draw's maps are instances whose
// records (box, tile, first page) come from a storage buffer; a draw call per pair of segments its maps use.
// When the maps coming do not fit the free room, a segment is added, of what they need and up to half the pool more,
// but never past setByteLimit() (the city's capacity less what else it holds): nothing already resident is copied
// (remaking one store copied all it kept: on llvmpipe about 0.8 ms a MB, 150 ms for a growth on the 10,000-building
// path). Once under three quarters of the tiles (or pages) have been in use for kShrinkAfterFrames frames, or at
// once when the pool is over the limit, segments are given back: an empty one as it is, another after its live maps
// moved into the others' free room (a copy of those maps alone); at kMaxSegments of a kind, the two least used are
// merged into the next one added. That policy is SegmentPool's (plain C++, one for the tiles and one for the pages);
// this class is the GL storage under it and the drawing.
#include "BlockMap.h"
#include "SegmentPool.h"
#include "Camera.h"
#include "gl/GlObjects.h"
#include "gl/RenderTarget.h"
#include "gl/ShaderProgram.h"

#include <memory>
#include <string>
#include <vector>

namespace seasonview::city {

class BlockMapPoolGL {
public:
    /// Texture units the pool's textures are bound to: kUnit .. kUnit + kTextures - 1 (past the terrain's, so the
    /// ROOF_IMAGERY program samples the clipmaps on theirs).
    static constexpr int kUnit = 22, kTextures = 2;

    /// The program that draws maps (shaders/blockmap.*): with `roofImagery` its ROOF_IMAGERY variant (bind the
    /// terrain's clipmaps to it: ClipmapTerrainRendererGL::bindTerrain), with `frontFaces` its FRONT_FACES variant
    /// (for boxes the eye is well outside of). A shader that does not build is a bug.
    /// `defines`: more of the shader's variants (common_roof.glsl's, with `roofImagery`).
    static Result<gl::ShaderProgram> buildProgram(bool roofImagery, bool frontFaces = false,
                                                  std::vector<std::string> defines = {});

    /// A pool for maps of `mapSize`² texels.
    explicit BlockMapPoolGL(int mapSize);
    BlockMapPoolGL(const BlockMapPoolGL&) = delete; // its SegmentPools hold references to its storage
    BlockMapPoolGL& operator=(const BlockMapPoolGL&) = delete;
    int mapSize() const { return m_size; }

    /// Uploads `map` (packed by packBlockMap, or packed here when null); returns its handle. Errors: a map of
    /// another size, the storage past what the GL allows (one line each).
    Result<int> add(const BlockMap& map, const BlockMapPacked* packed = nullptr);
    /// Frees map `handle`'s storage for later maps.
    void remove(int handle);
    std::size_t maps() const { return m_live; }

    /// Whether map `handle`'s box drawn from `eye` needs its back faces (the eye inside it, or within `margin`
    /// metres: its front faces would be clipped by the near plane).
    bool needsBackFaces(int handle, const glm::dvec3& eye, double margin) const;
    glm::dvec3 boxMin(int handle) const;
    glm::dvec3 boxMax(int handle) const;
    /// GPU bytes the pool has allocated.
    std::uint64_t allocatedBytes() const;
    /// GPU bytes its maps take (each map's BlockMapRecord::gpuBytes(): tile and whole pages); the rest of
    /// allocatedBytes() is free room.
    std::uint64_t usedBytes() const;
    /// The most the pool may allocate when it grows (the city's capacity less what else it holds): room beyond
    /// what the maps need is added only within it. It never holds less than its maps need.
    void setByteLimit(std::uint64_t bytes) { m_byteLimit = bytes; }
    /// Before a frame's `mapsComing` maps of `pagesComing` pages are added: setByteLimit(bytes); segments given back
    /// when the live and coming maps have needed under three quarters of the tiles (or pages) for kShrinkAfterFrames
    /// calls in a row, or the pool holds more than `bytes`; a segment added when the free room cannot hold what comes.
    Status prepare(std::uint64_t bytes, std::size_t pagesComing, std::size_t mapsComing);
    /// Calls of prepare() (frames) the maps must need under three quarters of the tiles (or pages) before segments are
    /// given back. Giving one back copies its live maps, and while the eye moves the maps resident come and go: a dip
    /// of a few frames is not worth a copy that the next rise undoes.
    static constexpr int kShrinkAfterFrames = 16;

    struct Instance {
        int handle = 0;
        glm::vec4 sourceColour{0.0f}; // a > 0: the levels view, this map's colour
    };
    /// The maps the next draws pick from (uploaded: one buffer write per frame).
    void setInstances(const std::vector<Instance>& instances);

    struct DrawSettings {
        glm::vec3 roofColour{0.6f, 0.55f, 0.5f};
        bool outputKind = false; // colour (kind, 0, 0, 1): 0.5 a roof, 1 a wall (tests)
    };
    /// Sets what a frame's maps share and the state (into the bound target; `pixelAngle`: radians per pixel, which
    /// filters the walls' colours), binds the instances' records; draw() then binds each pair of segments' storage and
    /// draws instances, end() restores the state.
    void begin(const gl::ShaderProgram& program, const glm::dmat4& viewProj, const glm::dvec3& eye, double pixelAngle,
               const DrawSettings& settings, bool frontFaces = false) const;
    /// Instances [first, first + count) of setInstances(): a draw call per pair of segments they use (returned).
    int draw(const gl::ShaderProgram& program, int first, int count) const;
    static void end();

    /// Segments of each kind at most: the two least used are merged into the next (each pair of segments a draw's
    /// maps lie in is a draw call).
    static constexpr int kMaxSegments = SegmentPool::kMaxSegments;
    /// Bytes of resident maps copied within the pool so far (segments given back or merged; growing copies none).
    std::uint64_t movedBytes() const { return m_movedBytes; }
    /// Tile and page segments held (tests).
    int tileSegments() const { return m_tiles.segments(); }
    int pageSegments() const { return m_pages.segments(); }

private:
    struct Slot {
        bool live = false;
        glm::dvec2 origin{0.0};
        double texel = 1.0, zBase = 0.0, zTop = 1.0;
        int wallTexels = 1, span = 1, columns = 0;
    };
    // The GL side of a SegmentPool: a buffer and a texture buffer over it per segment, `unitBytes` a unit (a map's
    // tile, or a page); moving an owner copies its units (and, for pages, writes its page table where they now are).
    struct Segments : SegmentPool::Storage {
        struct Segment {
            gl::Buffer buffer;
            gl::Texture texture;
        };
        GLenum format = GL_R32UI;
        std::uint64_t unitBytes = 4;
        bool pageTables = false;
        std::uint64_t* movedBytes = nullptr;
        std::vector<Segment> segments;
        Status addSegment(std::size_t units) override;
        void moveOwner(int owner, int fromSegment, const std::vector<std::uint32_t>& from, int toSegment,
                       const std::vector<std::uint32_t>& to) override;
        void eraseSegment(int segment) override;
        /// `pages`' numbers at the start of the first of them, in `segment` (the map's page table).
        void writePageTable(int segment, const std::vector<std::uint32_t>& pages) const;
    };
    static constexpr std::size_t kMinPages = 64;
    static constexpr std::size_t kMinTiles = 16;
    static constexpr int kPairStride = 256; // an instance's pair of segments: tile segment × this + page segment
    std::uint64_t tileBytes(std::uint64_t tiles) const;
    static std::uint64_t pageBytes(std::uint64_t pages);
    std::size_t pagesPerMap() const; // the live maps' pages on average, rounded up (1 with none)
    /// Room for `tiles` (`pages`) more (SegmentPool::grow), with what the limit allows beyond them: room for whole
    /// maps, each extra tile with the pages a map takes on average (free tiles without pages for their maps, or pages
    /// without tiles, would be room lost under the limit).
    Status growTiles(std::size_t tiles);
    Status growPages(std::size_t pages);

    int m_size = 0;
    std::uint64_t m_movedBytes = 0;
    Segments m_tileStore, m_pageStore;
    SegmentPool m_tiles, m_pages; // owners: the maps' handles
    std::uint64_t m_byteLimit = ~std::uint64_t(0);
    int m_underUsedFrames = 0;      // prepare() calls in a row with under three quarters of the tiles needed
    int m_pagesUnderUsedFrames = 0; // the same for the pages
    std::vector<Slot> m_slots;
    std::vector<int> m_freeSlots;
    std::size_t m_live = 0;
    gl::Buffer m_instances;
    std::vector<int> m_instancePair; // per instance of setInstances(): tile segment × kPairStride + page segment
    gl::VertexArray m_vao;
};

/// One map in a pool of its own, drawn alone (tests, tools).
class BlockMapGL {
public:
    using DrawSettings = BlockMapPoolGL::DrawSettings;
    /// Errors: the storage past the GL's limits; the shaders do not build (a bug).
    static Result<std::unique_ptr<BlockMapGL>> create(const BlockMap& map);
    /// Draws into `target` over what it holds, depth-tested (reversed Z, GL_GREATER) and writing depth. Returns the
    /// draw calls (1).
    int draw(const Camera& camera, const gl::RenderTarget& target, const DrawSettings& settings) const;
    int draw(const Camera& camera, const gl::RenderTarget& target) const { return draw(camera, target, DrawSettings{}); }

private:
    BlockMapGL() = default;
    gl::ShaderProgram m_program;
    std::unique_ptr<BlockMapPoolGL> m_pool;
};

} // namespace seasonview::city
