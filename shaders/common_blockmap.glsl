// The maps of a BlockMap pool (city/BlockMapGL.h, BlockMapPoolGL): one record per instance of a draw.
struct BmMap {
    vec4 geo;     // origin x, y (local metres), metres per texel, zBase
    vec4 z;       // zTop, the pair of storage segments it lies in (BlockMapPoolGL::draw)
    ivec4 tile;   // z: the map's first texel in its tile segment (x, y: 0); w: its first word after its page table
    ivec4 wall;   // wallTexels, span (texels a column takes with its halved levels), columns; its first page
    vec4 source;  // a > 0: the levels view, this map's colour, shaded by the face
};
layout(std430, binding = 4) readonly buffer BmMaps { BmMap bmMaps[]; };
uniform int uBmSize; // n: every map of the pool is n × n texels
