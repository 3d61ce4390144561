#pragma once
// The brute-force reference geometry: every DEM sample covering the imagery as one vertex (or a fine flat grid when
// the scene has no DEM), with leaf-on image coordinates per vertex. No LOD on purpose: later renderers are measured
// against images made from it.
#include "Scene.h"

#include <cstdint>
#include <vector>

namespace seasonview {

struct ReferenceVertex {
    float x, y, z; // local frame, metres
    float u, v;    // leaf-on image coordinates normalised to [0,1] (u east, v south); outside: no imagery
};

struct ReferenceMesh {
    std::vector<ReferenceVertex> vertices;
    std::vector<std::uint32_t> indices; // triangles
    int columns = 0, rows = 0;          // vertex grid
    int stride = 1;                     // DEM samples per vertex step (> 1 only for DEMs past `maxVertices`)
};

/// Builds the mesh of `scene`. With a DEM: the DEM's own samples (converted into the local frame) over the imagery
/// extent plus one sample of margin; the fragment stage discards what lies outside the imagery. Without: a flat
/// grid of `flatCells`² cells over the image. DEMs larger than `maxVertices` samples are decimated by an integer
/// stride (reported in `stride`).
ReferenceMesh buildReferenceMesh(const Scene& scene, int flatCells = 64, std::int64_t maxVertices = 64ll << 20);

/// Layout of an image split into the layers of a 2D array texture no larger than `maxSize` per side. Tiles overlap
/// by one border texel on each side so bilinear filtering is seamless across tile edges.
struct TileLayout {
    int tileWidth = 0, tileHeight = 0; // texels per layer, borders included
    int step = 0;                      // image pixels between tile origins (square tiles); 0: a single tile
    int border = 0;                    // 0 for a single tile, else 1
    int tilesX = 1, tilesY = 1;
    int layers() const { return tilesX * tilesY; }
};
TileLayout computeTileLayout(int imageWidth, int imageHeight, int maxSize);

} // namespace seasonview
