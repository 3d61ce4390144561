#pragma once
// The static footprints of one geometry-clipmap level (Asirvatham & Hoppe 2005, GPU Gems 2 ch. 2 §2.3), plain C++:
// a level is an n×n vertex grid (n = 2^k - 1, so n - 1 cells per side) made of m×m-vertex blocks (m = (n + 1) / 4),
// ring fix-ups of m×3 vertices where the blocks leave a 2-cell gap, and, around the finer level's square, an
// interior L-shaped trim one cell wide whose corner depends on where the finer level sits. The finest level is
// the full grid. Rectangles are in the level's own cells (0 .. n-1 on each axis, x east, y north).
#include <cstdint>
#include <utility>
#include <vector>

namespace seasonview {

struct GridRect {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0; // half-open cell ranges
    int cellsX() const { return x1 - x0; }
    int cellsY() const { return y1 - y0; }
    int vertices() const { return (cellsX() + 1) * (cellsY() + 1); }
};

/// Which side the finer level leaves its one-cell trim on, per axis (the finer level sits at the other side).
enum class TrimSide { Low, High };

struct RingLayout {
    int n = 255; // vertices per side
    int m = 64;  // vertices per block side

    /// n must be 2^k - 1 with k >= 3 (asserted).
    static RingLayout make(int n);

    /// Block offsets along an axis (cells): 0, m-1, 2m, 3m-1; each block spans m-1 cells.
    int blockOffset(int i) const { return i < 2 ? i * (m - 1) : i * (m - 1) + 2; }

    /// The 12 blocks of a ring level (the 4×4 block grid minus the 4 inner blocks).
    std::vector<GridRect> ringBlocks() const;
    /// The 4 ring fix-ups (m×3 vertices: m-1 by 2 cells) filling the 2-cell gaps between blocks.
    std::vector<GridRect> fixups() const;
    /// The interior trim: a 1-cell column on `x` side and a 1-cell row on `y` side of the 2m×2m-cell hole, sharing
    /// no cell (the row stops where the column starts).
    std::vector<GridRect> trim(TrimSide x, TrimSide y) const;
    /// Where the finer level's (n-1)/2-cell square (in this level's cells) sits for a given trim.
    GridRect finerLevel(TrimSide x, TrimSide y) const;
    /// The finest level as pieces: 16 blocks plus a full fix-up cross.
    std::vector<GridRect> finestPieces() const;
    /// Degenerate (zero-area) triangles along the outer edge that stitch this level to the coarser level's
    /// every-other vertex: (n - 1) / 2 per side, the triangles that collapse when stitchedVertex() moves each odd
    /// outer-edge vertex onto its even neighbour.
    int outerDegenerateTriangles() const { return 4 * ((n - 1) / 2); }
    /// Where vertex (x, y) of a level (cells, 0 .. n-1) is drawn when it is stitched to the coarser level
    /// (terrain_geometry.vert does the same): an odd vertex of the outer edge moves onto its even neighbour
    /// (x - 1 or y - 1), so the outer edge is made of the coarser level's own inner-edge segments, with no T-junction.
    std::pair<int, int> stitchedVertex(int x, int y) const;
};

/// A piece's triangles as indices into its (cellsX + 1) × (cellsY + 1) vertex grid (row-major, x fastest), two per
/// cell, counter-clockwise in (x, y), diagonals alternating like a checkerboard.
std::vector<std::uint32_t> pieceTriangles(int cellsX, int cellsY);

} // namespace seasonview
