#include "GeometryClipmapLayout.h"

#include <algorithm>

#include <cassert>
#include <cstddef>

namespace seasonview {

RingLayout RingLayout::make(int n) {
    assert(n >= 7 && ((n + 1) & n) == 0 && "RingLayout::make(): n must be 2^k - 1, k >= 3");
    return RingLayout{n, (n + 1) / 4};
}

std::vector<GridRect> RingLayout::ringBlocks() const {
    std::vector<GridRect> out;
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) {
            if ((i == 1 || i == 2) && (j == 1 || j == 2)) continue; // the hole
            out.push_back({blockOffset(i), blockOffset(j), blockOffset(i) + m - 1, blockOffset(j) + m - 1});
        }
    return out;
}

std::vector<GridRect> RingLayout::fixups() const {
    const int c = 2 * (m - 1); // the gap between blocks 1 and 2
    const int far = blockOffset(3);
    return {{c, 0, c + 2, m - 1}, {c, far, c + 2, far + m - 1}, {0, c, m - 1, c + 2}, {far, c, far + m - 1, c + 2}};
}

GridRect RingLayout::finerLevel(TrimSide x, TrimSide y) const {
    const int lo = m - 1;         // the hole starts here and spans 2m cells
    const int size = (n - 1) / 2; // 2m - 1 cells: one less than the hole, the trim takes the rest
    const int fx = x == TrimSide::Low ? lo + 1 : lo, fy = y == TrimSide::Low ? lo + 1 : lo;
    return {fx, fy, fx + size, fy + size};
}

std::vector<GridRect> RingLayout::trim(TrimSide x, TrimSide y) const {
    const int lo = m - 1, hi = 3 * m - 1;
    const int col = x == TrimSide::Low ? lo : hi - 1; // the 1-cell column, full height of the hole
    const int row = y == TrimSide::Low ? lo : hi - 1;
    const GridRect column{col, lo, col + 1, hi};
    const GridRect rowRect = x == TrimSide::Low ? GridRect{lo + 1, row, hi, row + 1} : GridRect{lo, row, hi - 1, row + 1};
    return {column, rowRect};
}

std::vector<GridRect> RingLayout::finestPieces() const {
    std::vector<GridRect> out;
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i)
            out.push_back({blockOffset(i), blockOffset(j), blockOffset(i) + m - 1, blockOffset(j) + m - 1});
    const int c = 2 * (m - 1);
    out.push_back({c, 0, c + 2, n - 1});     // vertical bar of the cross, full height
    out.push_back({0, c, c, c + 2});         // horizontal bar, west of it
    out.push_back({c + 2, c, n - 1, c + 2}); // and east of it
    return out;
}

std::pair<int, int> RingLayout::stitchedVertex(int x, int y) const {
    const int last = n - 1;
    if ((x == 0 || x == last) && y % 2 == 1) --y;
    if ((y == 0 || y == last) && x % 2 == 1) --x;
    return {x, y};
}

std::vector<std::uint32_t> pieceTriangles(int cellsX, int cellsY) {
    std::vector<std::uint32_t> idx;
    idx.reserve(std::size_t(cellsX) * std::size_t(cellsY) * 6);
    const int w = cellsX + 1;
    // In columns of kStrip cells, row by row within each: llvmpipe shades the vertices of each run of 1024 indices
    // once (Mesa's draw module, vsplit), so a run should span few vertices: a 13-cell column's 13 rows of 14 × 14
    // vertices rather than 2.7 rows of a 63-cell piece's 64-vertex rows.
    constexpr int kStrip = 13;
    for (int x0 = 0; x0 < cellsX; x0 += kStrip)
        for (int y = 0; y < cellsY; ++y)
            for (int x = x0; x < std::min(x0 + kStrip, cellsX); ++x) {
                const auto a = std::uint32_t(y * w + x), b = a + 1, c = a + std::uint32_t(w), d = c + 1;
                // Diagonals alternate so the mesh is symmetric (no directional bias in relief).
                if ((x + y) % 2 == 0) idx.insert(idx.end(), {a, b, d, a, d, c});
                else idx.insert(idx.end(), {a, b, c, b, d, c});
            }
    return idx;
}

} // namespace seasonview
