#pragma once
// BlockMaps (Cignoni, Di Benedetto, Ganovelli, Gobbetti, Marton, Scopigno 2007, "Ray-Casted BlockMaps for Large Urban
// Models Visualization", §3): a square region of a city as discrete textured vertical prisms on an n × n grid, drawn
// far away by casting rays against it instead of sending its polygons. Plain C++: the data (§3.1), its construction
// from a model's triangles (§3.3) and the CPU ray traversal (§3.2) that the GPU's is checked against.
//
// §3.1 as stored here: per texel a height (16 bits over the block's height range, 0: no building; the paper's 8 bits
// put a flat roof up to half a step of 1/255 of the range off, which moves eaves across pixel centres at an overview), a wall column
// index for boundary texels (those with a lower 4-neighbour, the block's edge counting as lower) and a discrete
// distance field over the empty space (the Chebyshev distance in texels to the nearest building texel) for leaping.
// Each wall column holds `wallTexels` colours from the block's floor to the prism's top, the mean of what its exposed
// sides show (and how much of it is wall rather than the steps of a sloped roof), the mean outward normal of the
// walls its rays met (of its exposed sides where they met none); each texel its roof's normal and its prism's foot
// (the paper's blocks stand on flat ground; here a building may stand higher than the block's floor, and its prisms
// end where it meets the ground), and the part of the texel
// its prism stands on, to a sixteenth of a texel (the paper's prisms fill their texels; here they end where the
// buildings' outlines are, so an overview whose texels are pixels shows the polygons' outlines, not the grid's), with
// a second prism where a street crosses the texel, and a roof plane, not a level top. Roofs store no colour:
// seasonview textures them from the terrain imagery, as it draws the polygon roofs. The ground is not part of a BlockMap: a ray that meets no prism goes on to
// the terrain drawn under it.
#include "CityModel.h"
#include "Result.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <vector>

namespace seasonview::city {

struct AtlasTreeFile;

struct BlockMapOptions {
    int size = 64;       // n: height-map texels per side (the paper's examples: 32; the issue: 64–256)
    int wallTexels = 32; // colours per wall column, from the prism's foot to its top (the paper: 31)
};

struct BlockMap {
    glm::dvec2 origin{0.0};         // local metres: the corner with the smallest x and y
    double texel = 1.0;             // metres per height-map texel
    int size = 0;                   // n
    double zBase = 0.0, zTop = 1.0; // heights are zBase + value · (zTop − zBase) / kHeightSteps
    int wallTexels = 0;
    static constexpr int kHeightSteps = 65535;
    std::vector<std::uint16_t> height;  // n², row-major, row 0 at origin.y
    std::vector<std::uint8_t> distance; // n²: Chebyshev distance in texels to the nearest building texel (0 on one)
    std::vector<std::uint32_t> column;  // n²: 1 + the wall column of a boundary texel, 0 elsewhere
    // Per wall texel RGB and A, the share of its rays that met walls (255) rather than roofs (0: a step of a sloped
    // roof seen from the side, drawn as roof); columns × wallTexels × 4, the lowest first.
    std::vector<std::uint8_t> wallRgba;
    std::vector<glm::vec3> wallNormal;  // per column, unit and horizontal: the met walls' mean (else the sides')
    // Per column 1 where every wall its rays met runs along the grid (across the side they went in by, within
    // 10°): a wall pixel there is shaded by the side its ray enters the texel through, as the polygons shade a
    // corner's two walls each by its own normal; 0 (or empty): by the column's normal (a wall at an angle to the grid,
    // whose steps would otherwise be shaded in stripes).
    std::vector<std::uint8_t> wallOnGrid;
    // Per texel the roof's normal (the highest triangle's, facing up; where the first prism's roofs are of more than
    // one plane, across a ridge, the normal of the plane fitted to them) as x and y in 0..255 for -1..1 (z is implied;
    // within 0.005 of 0 is 0): the roofs are shaded as the polygons' are (the paper's per-texel normals, §3.1), and
    // the texel's (first) prism's top is the plane of that normal through its height at the texel's centre, so a
    // sloped roof is a slope, not steps.
    std::vector<std::uint8_t> roofNormal; // n² × 2
    // Per texel the prism's foot, as heights are stored (0 on an empty texel): a ray below it at the texel passes
    // under the prism (it is in the ground there: the terrain drawn under the block hides it; with no terrain, it
    // goes on to what is behind, as under the polygons; rising into the prism from below, it meets nothing). So walls
    // do not hang below a building that stands higher than the block's lowest. A boundary texel's foot is the lowest
    // triangle over it of the buildings whose roofs lie over it, to the nearest height step; an inner texel's the
    // lowest of its neighbours' of the same buildings. Empty: every foot at zBase.
    std::vector<std::uint16_t> foot;
    // Per texel the part of it its prism stands on, so the prisms end at the buildings' outlines, not at the texels'
    // edges (at an overview a texel is a pixel: whole texels move every outline by up to one): x0 | x1 << 4 | y0 << 8 |
    // y1 << 12, the prism over [x0, x1 + 1] / 16 × [y0, y1 + 1] / 16 of the texel (x, y from its lowest corner).
    // A texel is a building's where any of its roofs lies over it, and its part is the box of what they cover there.
    // kWholeTexel on empty texels and where a roof covers it all; empty vector: every texel whole.
    std::vector<std::uint16_t> rect;
    // A texel whose roofs leave an empty strip across it (two buildings and the gap between them) holds a second
    // prism beyond the strip: its part (as rect) and level top (as heights, 0: none; the first prism is the taller
    // over the parts' centres). Both stand on the texel's foot. Empty vectors: no second prisms.
    std::vector<std::uint16_t> rect2;
    std::vector<std::uint16_t> height2;

    int columns() const { return int(wallNormal.size()); }
    std::uint16_t heightAt(int x, int y) const { return height[std::size_t(y) * std::size_t(size) + std::size_t(x)]; }
    /// A stored height (height, height2, foot) in metres.
    double metresOf(std::uint16_t value) const { return zBase + double(value) * (zTop - zBase) / kHeightSteps; }
    /// The top of the prism at texel (x, y) in metres (zBase where there is none).
    double topAt(int x, int y) const { return metresOf(heightAt(x, y)); }
    /// The top of texel (x, y)'s second prism in metres (zBase where there is none).
    double top2At(int x, int y) const { return metresOf(height2At(x, y)); }
    /// The foot of the prism at texel (x, y) in metres.
    double footAt(int x, int y) const {
        return foot.empty() ? zBase : metresOf(foot[std::size_t(y) * std::size_t(size) + std::size_t(x)]);
    }
    /// The roof's normal at texel (x, y), as stored (roofNormal).
    glm::dvec3 roofNormalAt(int x, int y) const;
    /// The slope of the texel's roof plane: dz/dx, dz/dy.
    glm::dvec2 roofSlopeAt(int x, int y) const {
        const glm::dvec3 r = roofNormalAt(x, y);
        return -glm::dvec2(r.x, r.y) / r.z;
    }
    static constexpr std::uint16_t kWholeTexel = 0xF0F0; // x0 = y0 = 0, x1 = y1 = 15
    std::uint16_t rectAt(int x, int y) const {
        return rect.empty() ? kWholeTexel : rect[std::size_t(y) * std::size_t(size) + std::size_t(x)];
    }
    std::uint16_t height2At(int x, int y) const {
        return height2.empty() ? 0 : height2[std::size_t(y) * std::size_t(size) + std::size_t(x)];
    }
    std::uint16_t rect2At(int x, int y) const {
        return rect2.empty() ? kWholeTexel : rect2[std::size_t(y) * std::size_t(size) + std::size_t(x)];
    }
};

/// A texel's part (BlockMap::rect) as fractions of the texel: lo = (x0, y0) / 16, hi = (x1 + 1, y1 + 1) / 16.
struct TexelPart {
    glm::dvec2 lo{0.0}, hi{1.0};
};
inline TexelPart texelPart(std::uint16_t r) {
    return {{double(r & 15u) / 16.0, double((r >> 8) & 15u) / 16.0},
            {double(((r >> 4) & 15u) + 1u) / 16.0, double(((r >> 12) & 15u) + 1u) / 16.0}};
}

/// What a triangle shows at a point (its barycentric coordinates): e.g. its texture there.
using TriangleColour = std::function<glm::dvec3(std::size_t triangle, const glm::dvec3& barycentric)>;

/// Builds the BlockMap of the square [origin, origin + side]² from `model`'s triangles (§3.3): each texel's height is
/// the highest triangle that is not vertical over the texel's centre (roofs, and any other surface facing up or
/// down); a boundary texel's wall column is what horizontal rays see going into the texel through each exposed side
/// (four across the side, at each column texel's height where the neighbour is lower), averaged over its sides, each
/// ray taking the colour of the first triangle it meets (`colour`, 0..1 RGB); a column texel no ray saw takes the
/// nearest one seen below or above it, a column that saw nothing the mean wall colour of the block. The block's
/// height range is that of the triangles in it. Errors: a size outside 2..4096, wallTexels outside 1..1024, a
/// side that is not positive.
Result<BlockMap> buildBlockMap(const CityModel& model, glm::dvec2 origin, double side, const BlockMapOptions& options,
                               const TriangleColour& colour);
/// The same from the triangles `candidates` (indices into model.triangles) only: those over the square among them.
Result<BlockMap> buildBlockMap(const CityModel& model, const std::vector<std::uint32_t>& candidates, glm::dvec2 origin,
                               double side, const BlockMapOptions& options, const TriangleColour& colour);

/// A city's BlockMaps (§4: "a quadtree hierarchy of finer and finer BlockMap representations"): a quadtree of squares
/// over the model's footprint, its leaves `map.size · leafTexel` metres wide, every node with triangles a BlockMap
/// of `map.size`² texels (empty nodes none), the root first, level by level. Wall colours from the model's textures
/// (read through a TextureCache of `cacheBytes`, sampled over √2 of the map's texels in each texture, what a pixel
/// covers where the map is drawn; untextured triangles the city's plain colour).
struct CityBlockMapSettings {
    BlockMapOptions map;
    double leafTexel = 1.0; // metres per texel of the finest BlockMaps
    std::uint64_t cacheBytes = std::uint64_t(512) << 20;
    /// The atlas tree the model is of (modelOfTree(*atlasTree), its tree triangles first): a wall's colour is then
    /// read through the tree's atlases (the "through the atlas tree's textures"), from the node the atlas
    /// mode draws where the map is drawn (the coarsest whose texels are no wider than √2 of the map's), with that
    /// atlas's compression and filtering (over 1.7 times that, measured: buildCityBlockMaps), so a map and the atlases
    /// it stands in for show the same walls; where even the leaves' atlases are coarser, the original texture. Null: the model's own textures. Atlases are read through an LRU cache of
    /// `cacheBytes` / 2.
    const AtlasTreeFile* atlasTree = nullptr;
    std::function<void(double, const char*)> progress; // 0..1 as maps are built, and the stage
};
struct CityBlockMapReport {
    std::size_t maps = 0;
    int depth = 0;            // levels below the root
    double rootSide = 0.0;    // metres
    std::size_t columns = 0;  // wall columns, all maps
    std::uint64_t fileBytes = 0;
    std::uint64_t textureReads = 0;
    std::uint64_t atlasReads = 0; // atlases decoded (settings.atlasTree), re-reads after eviction included
};
/// Builds the city's BlockMaps and writes them to `out` (writeBlockMaps). Errors: a texture that cannot be read (one
/// line naming it), a model with no triangles, bad settings, the file not written.
Result<CityBlockMapReport> buildCityBlockMaps(const CityModel& model, const CityBlockMapSettings& settings,
                                              const std::filesystem::path& out);

struct BlockMapHit {
    enum class Kind { None, Roof, Wall };
    Kind kind = Kind::None;
    double t = 0.0;             // along the ray: point = origin + t · direction
    glm::dvec3 point{0.0};      // local metres
    glm::ivec2 texel{-1};       // the height-map texel hit
    glm::dvec3 normal{0.0};     // the face's: (0, 0, 1) on a roof, ±x or ±y on a wall
    int column = -1;            // a wall's column (its texel's)
    double v = 0.0;             // a wall's height in its column, 0 at the foot, 1 at the top
    int texelsVisited = 0;      // texels the traversal looked at (the leaping's effect)
};

/// Casts a ray (origin and direction in local metres, direction not zero) against the BlockMap's prisms (§3.2): the
/// nearest roof or wall it meets at t > 0 inside the block's box [origin, origin + n · texel]² × [zBase, zTop],
/// found by stepping texel by texel along the ray's path over the height map (Amanatides & Woo 1987), a texel's prisms
/// (each its part of the texel, BlockMap::rect and rect2, from its foot to its roof plane or level top) hit where the
/// ray enters the nearest: through its top a roof, through a side a wall (below its foot the ray passes under the
/// prism; rising into it from below, it meets nothing). `leap`: over empty texels the distance map moves the ray to the
/// edge of the empty square around it in one step (§3.2's space leaping); false steps every texel (the reference). A
/// ray that leaves the box, or reaches its floor, meets nothing (the terrain is drawn under the block); a ray that starts
/// inside a prism hits it at once.
BlockMapHit traceBlockMap(const BlockMap& map, const glm::dvec3& origin, const glm::dvec3& direction, bool leap = true);

/// BlockMap files: "SVBLOCKM", a version, the maps' count, then per map its header and data and a CRC-32 of both;
/// written under a temporary name and renamed. Reading checks everything (sizes within bounds, every column index
/// within the columns, the CRCs, nothing after the last map) and refuses a truncated, damaged or foreign file with
/// one line naming it.
Status writeBlockMaps(const std::filesystem::path& path, const std::vector<BlockMap>& maps);

/// The same file written map by map (a city's maps need not all be in memory): open() starts the temporary file,
/// add() appends a map, finish() writes the count and renames it into place. Destroyed unfinished, it leaves nothing.
class BlockMapWriter {
public:
    static Result<BlockMapWriter> open(const std::filesystem::path& path);
    Status add(const BlockMap& map);
    Status finish();
    std::uint32_t count() const { return m_count; }
    std::uint64_t bytes() const { return m_bytes; }
    BlockMapWriter(BlockMapWriter&&) noexcept;
    BlockMapWriter& operator=(BlockMapWriter&&) noexcept;
    ~BlockMapWriter();

private:
    BlockMapWriter();
    struct File;
    std::unique_ptr<File> m_file;
    std::filesystem::path m_path, m_tmp;
    std::uint32_t m_count = 0;
    std::uint64_t m_bytes = 0;
    std::vector<std::uint8_t> m_countBytes;
    bool m_done = false;
};
/// Texels a wall column takes with its halved levels (BlockMapGL): W, then (W + 1) / 2, ... down to 1.
int wallSpan(int wallTexels);

/// A map as BlockMapPoolGL stores it. Plain C++, so the pager's loader thread packs it and the GL thread only uploads.
struct BlockMapPacked {
    int span = 1; // wallSpan(wallTexels)
    /// n² × 4 words, row-major (BlockMapPoolGL's tiles): the texel's height (the low 16 bits) and roof normal's x and
    /// y (as BlockMap stores them, a byte each); its wall column (BlockMap::column, 24 bits) and distance (the top
    /// byte); its part and its second prism's (BlockMap::rect, rect2: the low and high 16 bits); its foot and second
    /// prism's top (BlockMap::foot, height2: the low and high 16 bits).
    std::vector<std::uint32_t> tile;
    /// 32-bit words: each column's outward normal ((n + 1) / 2 as RGB8 in bytes 0..2) and on-the-grid flag (byte 3,
    /// BlockMap::wallOnGrid), then each column's `span`
    /// RGBA8 colours: its wallTexels colours (the lowest first), then the same halved again and again down to one
    /// (level l has (W_{l-1} + 1) / 2 colours, 2×1 box means), for filtering.
    std::vector<std::uint32_t> words;
};
BlockMapPacked packBlockMap(const BlockMap& map);

/// BlockMapPoolGL keeps each map's words in pages of this many (shaders/blockmap.frag, BM_PAGE_BITS), wherever pages
/// are free; the first starts with the map's page table, one word per page.
constexpr std::size_t kBlockMapPageWords = 1024;
/// Pages a map of `words` words takes, its page table included.
constexpr std::size_t blockMapPages(std::size_t words) {
    return words == 0 ? 0 : (words + kBlockMapPageWords - 2) / (kBlockMapPageWords - 1);
}

/// Reads every map of a file (BlockMapFile::open, then read() of each).
Result<std::vector<BlockMap>> readBlockMaps(const std::filesystem::path& path);

/// One map's record in a BlockMap file: its header, and where its data lies.
struct BlockMapRecord {
    glm::dvec2 origin{0.0};
    double texel = 1.0, zBase = 0.0, zTop = 1.0;
    int size = 0, wallTexels = 0, columns = 0;
    std::uint64_t offset = 0, bytes = 0; // the record (header, data, CRC) in the file
    double side() const { return double(size) * texel; }
    /// Bytes of the map once uploaded (BlockMapPoolGL: height, distance, roof normal, column, foot and parts per
    /// texel, each wall column's normal and colours with their halved levels, in whole pages with their page table).
    std::uint64_t gpuBytes() const;
};

/// A BlockMap file opened for reading its maps one at a time (a city's need not fit in memory): open() reads and
/// checks every record's header and that the records fill the file exactly; read() reads one map and checks its CRC.
/// Either refuses a truncated, damaged or foreign file with one line naming it.
class BlockMapFile {
public:
    static Result<BlockMapFile> open(const std::filesystem::path& path);
    const std::vector<BlockMapRecord>& records() const { return m_records; }
    /// Map `k` (thread-safe: each call reads through its own stream).
    Result<BlockMap> read(std::size_t k) const;
    const std::filesystem::path& path() const { return m_path; }

private:
    std::filesystem::path m_path;
    std::vector<BlockMapRecord> m_records;
};

/// The quadtree of a city's BlockMaps (buildCityBlockMaps: the root first, then level by level; squares without
/// triangles have no map), recovered from the maps' squares: node k is record k.
struct BlockMapQuadtree {
    struct Node {
        int level = 0;
        glm::ivec2 cell{0};          // the square's column and row at its level
        std::int32_t parent = -1;
        std::array<std::int32_t, 4> children{-1, -1, -1, -1}; // quadrant dx + 2·dy; -1: no map (no triangles there)
    };
    glm::dvec2 origin{0.0};
    double rootSide = 0.0;
    int depth = 0;
    std::vector<Node> nodes;
    /// Errors (one line naming the file): no maps, a map whose square is not a node of the root's quadtree, a node
    /// twice, a node whose parent has no map, maps of different sizes.
    static Result<BlockMapQuadtree> of(const BlockMapFile& file);
};

} // namespace seasonview::city
