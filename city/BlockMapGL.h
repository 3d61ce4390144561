#pragma once
// BlockMaps on the GPU (Cignoni et al. 2007 §3.2), drawn by ray casting in a fragment shader (shaders/blockmap.frag,
// the copy of BlockMap.cpp's traceBlockMap) over their bounding boxes, writing each hit's colour and depth so they
// compose with the terrain and the polygons drawn around them.
//
// BlockMapPoolGL holds every resident map of a city in shared storage, so that any set of them is one instanced draw
// (§4: the paper's renderer draws a frame's BlockMaps as one batch of boxes): per texel its height, distance and roof
// normal in one RGBA8UI array texture and its wall column in an R32UI one, both of tiles n × n texels, a map per tile;
// the wall columns' normals and colours as 32-bit words in one texture buffer, in pages of kBlockMapPageWords taken
// wherever they are free (the map's first page starts with its page table), so maps come and go with no room lost
// between them and nothing moved. A draw's maps are instances whose records (box, tile, first page) come from a
// storage buffer. The storage follows the maps resident: layers and pages are added when none is free, up to a quarter
// more than needed but never past setByteLimit() (the city's capacity less what else it holds); once under three
// quarters of them have been in use for kShrinkAfterFrames frames (at once when the pool is over the limit), the live
// tiles or pages move below a new end and the arrays or buffer are remade that size (copied on the GPU; page tables
// follow). Remaking copies everything kept (on llvmpipe about 0.8 ms a MB), so it is done seldom.
#include "BlockMap.h"
#include "LowestFree.h"
#include "Camera.h"
#include "gl/GlObjects.h"
#include "gl/RenderTarget.h"
#include "gl/ShaderProgram.h"

#include <memory>
#include <vector>

namespace seasonview::city {

class BlockMapPoolGL {
public:
    /// Texture units the pool's textures are bound to: kUnit .. kUnit + kTextures - 1 (past the terrain's, so the
    /// ROOF_IMAGERY program samples the clipmaps on theirs).
    static constexpr int kUnit = 22, kTextures = 3;

    /// The program that draws maps (shaders/blockmap.*): with `roofImagery` its ROOF_IMAGERY variant (bind the
    /// terrain's clipmaps to it: ClipmapTerrainRendererGL::bindTerrain), with `frontFaces` its FRONT_FACES variant
    /// (for boxes the eye is well outside of). A shader that does not build is a bug.
    static Result<gl::ShaderProgram> buildProgram(bool roofImagery, bool frontFaces = false);

    /// A pool for maps of `mapSize`² texels.
    explicit BlockMapPoolGL(int mapSize);
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
    /// Before a frame's `mapsComing` maps of `pagesComing` pages are added: setByteLimit(bytes); the tiles' layers
    /// or the words' pages made fewer when the live and coming maps need under three quarters of them and have for
    /// kShrinkAfterFrames calls in a row, or the pool holds more than `bytes` (the live tiles or pages moved below
    /// first); the words' buffer grown once (as add() grows it) when the pages coming do not fit its free ones.
    Status prepare(std::uint64_t bytes, std::size_t pagesComing, std::size_t mapsComing);
    /// Calls of prepare() (frames) the maps must need under three quarters of the layers (or pages) before they are
    /// made fewer. That copies everything kept into new storage (160 MB of pages in about 125 ms on llvmpipe), and
    /// while the eye moves the maps resident come and go: a dip of a few frames is not worth a copy that the next
    /// rise undoes, and the maps evicted over several frames are given back in one copy, not one a frame.
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
    /// filters the walls' colours), binds the pool; draw() then draws instances, end() restores the state.
    void begin(const gl::ShaderProgram& program, const glm::dmat4& viewProj, const glm::dvec3& eye, double pixelAngle,
               const DrawSettings& settings, bool frontFaces = false) const;
    /// Instances [first, first + count) of setInstances() in one draw call.
    void draw(const gl::ShaderProgram& program, int first, int count) const;
    static void end();

private:
    struct Slot {
        bool live = false;
        glm::dvec2 origin{0.0};
        double texel = 1.0, zBase = 0.0, zTop = 1.0;
        int wallTexels = 1, span = 1, columns = 0;
        std::vector<std::uint32_t> pages; // its pages in the words buffer, in order (the first holds the table)
        int tile = 0;                     // its tile in the arrays (tileAt)
    };
    static constexpr std::size_t kMinPages = 64;
    /// Tile `tile`'s first texel's x and y in the arrays, and its layer; map `handle`'s.
    glm::ivec3 tileAt(int tile) const;
    glm::ivec3 tileOf(int handle) const;
    Status growLayers(int layers);
    /// The arrays made `layers` layers, the live tiles past them moved into free ones below first.
    Status shrinkLayers(int layers);
    /// The words' buffer made at least `need` pages (growing: see add()).
    Status growPages(std::size_t need);
    /// The words' buffer made `pages` pages, its first ones kept (every page in use lies below `pages`).
    Status resizePages(std::size_t pages);
    /// Moves the pages in use at or past `target` to free pages below it (there are enough), updating their maps'
    /// page tables; resizePages(target) then cuts the buffer.
    void movePagesBelow(std::size_t target);
    /// The lowest free page, taken for page `index` of map `handle`.
    std::uint32_t takePage(int handle, std::uint32_t index);
    std::uint64_t tileBytes(int layers) const;

    int m_size = 0;
    int m_tilesPerSide = 1, m_layers = 0;
    gl::Texture m_texels, m_columns;     // 2D arrays of (tilesPerSide · n)² per layer
    gl::Buffer m_wordBuffer;
    gl::Texture m_words;                 // R32UI texture buffer over m_wordBuffer
    std::size_t m_pageCapacity = 0, m_usedPages = 0;
    struct PageOwner {
        int handle = -1;         // -1: free
        std::uint32_t index = 0; // which of its map's pages
    };
    std::vector<PageOwner> m_pageOwner;      // per page of the buffer
    LowestFree m_freePages, m_freeTiles;   // the lowest taken first, so that the top ones empty
    std::uint64_t m_byteLimit = ~std::uint64_t(0);
    int m_underUsedFrames = 0;      // prepare() calls in a row with under three quarters of the layers needed
    int m_pagesUnderUsedFrames = 0; // the same for the pages
    std::vector<Slot> m_slots;
    std::vector<int> m_freeSlots;
    std::size_t m_live = 0;
    gl::Buffer m_instances;
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
