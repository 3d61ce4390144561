#pragma once
// The multiresolution texture-atlas tree on disk and in memory (Buchholz & Döllner 2005; thesis §4.3, §4.5, §4.8.1).
//
// One file holds up to two trees (RGB and RGBA textures, thesis §4.2) plus the triangles the trees do not texture
// (roofs drawn with the terrain imagery, §4.8.2, and untextured triangles). Per tree: the nodes (bounds,
// minDistance, level, a contiguous triangle range, §4.8.1, and where the node's atlas lies in the file), the
// triangles' vertices (position, original texture coordinates, root-atlas coordinates, §4.5.4) and the original
// texture table. Atlases are stored compressed, each with its whole mip chain; everything but the atlases is
// small and read whole by `AtlasTreeFile::open`.
#include "CityModel.h"
#include "Result.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace seasonview::city {

/// How node atlases are stored in the file (chosen by measurement, see city/README.md).
enum class AtlasFormat : std::uint32_t {
    Bc = 0,      // BC1 (RGB) / BC3 (RGBA) blocks, uploaded as they are: 6:1 (4:1) and no decoding
    Deflate = 1, // lossless RGB(A) bytes through libdeflate, decoded on load
};
const char* atlasFormatName(AtlasFormat f);

/// A vertex of a tree triangle. Positions are metres in the file's local frame; `uv` the original texture
/// coordinates (texture units); `root` the coordinates in the root atlas (§4.5.4): the atlas of a node at level k
/// is sampled at fract(root · 2^k).
struct TreeVertex {
    glm::vec3 position{0.0f};
    glm::vec2 uv{0.0f};
    glm::vec2 root{0.0f};
};

/// One node (§4.3, Fig. 25). Children are node indices, -1 where there is none; an inner node has four, whose
/// quadrants of its atlas are 0 bottom-left, 1 bottom-right, 2 top-left, 3 top-right (§4.5.4). Its triangles are
/// [first, first + count) of the tree's triangle list (§4.8.1: depth-first order makes every node's range
/// contiguous).
struct AtlasNode {
    glm::vec3 boundsMin{0.0f}, boundsMax{0.0f};
    float minDistance = 0.0f; // metres, for the tree's build screen width and fov at 1 pixel per texel
    std::int32_t level = 0;
    std::int32_t parent = -1;
    std::array<std::int32_t, 4> children{-1, -1, -1, -1};
    std::uint32_t first = 0, count = 0;
    std::uint64_t atlasOffset = 0, atlasBytes = 0; // 0 bytes: an empty node (no triangles, a blank atlas)
    std::uint32_t atlasCrc = 0;                    // CRC-32 of the atlas's bytes in the file (checked when read)
    /// Leaves: the original textures their triangles use (indices into the tree's texture table) and the bytes
    /// they take decoded, for paging (§4.6).
    std::vector<std::uint32_t> textures;
    std::uint64_t textureBytes = 0;

    bool leaf() const { return children[0] < 0; }
};

/// One tree: RGB or RGBA textures.
struct AtlasTreeData {
    bool alpha = false;
    std::vector<AtlasNode> nodes;            // nodes[0] is the root
    std::vector<TreeVertex> vertices;        // 3 per triangle, in §4.8.1 order
    std::vector<std::uint32_t> triangleTexture; // per triangle: index into the file's texture table
    std::vector<std::uint32_t> triangleBuilding;
};

/// Triangles outside the trees: roofs (drawn with the terrain's imagery clipmap) and untextured ones.
struct PlainTriangles {
    std::vector<glm::vec3> positions; // 3 per triangle
    std::vector<Surface> surface;     // per triangle
    std::vector<std::uint32_t> building; // per triangle
};

/// Build parameters (thesis §4.2) and what the build measured.
struct AtlasTreeInfo {
    int atlasSize = 512;          // A
    int border = 8;               // b, texels
    double dmin = 0.0;            // metres (after the critical-triangle adjustment)
    double tpp = 1.0;             // τ the tree was built for: at a node's minDistance a texel covers τ pixels
    int screenWidth = 1920;       // pixels the minDistances assume
    double fovXDeg = 90.0;        // horizontal field of view the minDistances assume
    AtlasFormat format = AtlasFormat::Bc;
    Crs crs;
    glm::dvec2 origin{0.0};
    bool sceneFrame = false;
    std::string source;
};

/// The in-memory index of a tree file: everything except the atlas pixels.
struct AtlasTreeFile {
    // 2: the CRS as its identifier (EPSG:N or WKT), not an EPSG number; 3: CRC-32 of the index and of every atlas.
    static constexpr std::uint32_t kVersion = 3;
    std::string path;
    AtlasTreeInfo info;
    std::vector<CityTexture> textures;   // original textures (paths as the model gave them)
    std::vector<int> textureChannels;    // 3 or 4
    std::vector<glm::ivec2> textureSizes;
    std::vector<AtlasTreeData> trees;    // RGB first, then RGBA (either may be absent)
    PlainTriangles plain;

    /// Reads the index; one-line errors for a missing, truncated, foreign or newer-version file.
    static Result<AtlasTreeFile> open(const std::string& path);
    /// A node's atlas, decoded to RGBA8 rows bottom-up (level 0 only, atlasSize² × 4 bytes); blank for an empty node.
    Result<std::vector<std::uint8_t>> readAtlasRgba(int tree, int node) const;
    /// A node's atlas as stored (compressed blob).
    Result<std::vector<std::uint8_t>> readAtlasBlob(int tree, int node) const;
};

/// The file's triangles as a model in the frame its positions are in (after placement in a scene: the scene's), each
/// tree triangle with its original texture and coordinates, the plain ones untextured (texture -1), the textures as
/// the file lists them: what BlockMaps are built from (buildCityBlockMaps), so they match the triangles drawn.
CityModel modelOfTree(const AtlasTreeFile& file);

/// Bytes of mip level `level` of an atlas of `size`² texels in `format` as decoded for upload (BC: blocks).
std::uint64_t atlasLevelBytes(AtlasFormat format, bool alpha, int size, int level);
/// Mip levels stored per atlas: down to 4×4 (one BC block).
int atlasLevels(int size);

} // namespace seasonview::city
