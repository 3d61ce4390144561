#pragma once
// Toroidal addressing of one clip level (Tanner et al. 1998): the level's N×N texture holds the window of the
// pyramid level's texels around the level centre, each texel (x, y) stored at (x mod N, y mod N). Moving the window
// only exposes strips; they are uploaded into the same texture without moving anything else. Plain C++.
#include <glm/vec2.hpp>

#include <vector>

namespace seasonview {

/// A half-open texel rectangle [x0, x1) × [y0, y1) in a pyramid level's texel grid (x east, y south).
struct TexelRect {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    int width() const { return x1 - x0; }
    int height() const { return y1 - y0; }
    bool empty() const { return x1 <= x0 || y1 <= y0; }
    long long area() const { return empty() ? 0 : (long long)width() * height(); }
    bool contains(int x, int y) const { return x >= x0 && x < x1 && y >= y0 && y < y1; }
    bool operator==(const TexelRect&) const = default;
};

TexelRect intersect(const TexelRect& a, const TexelRect& b);

/// Positive modulo: the texture coordinate of level texel `v` in a toroidal texture of `size` texels.
inline int wrapTexel(int v, int size) {
    const int m = v % size;
    return m < 0 ? m + size : m;
}

/// The N×N window centred on `centre` (level texel coordinates, may be fractional): its origin is snapped to a
/// multiple of `align` texels (even at least, so level l+1's window can always be aligned with level l's; the
/// clipmap uses its upload block size so windows move in whole blocks).
TexelRect windowAround(glm::dvec2 centre, int size, int align = 2);

/// Texels of `next` not in `previous`: empty when they are equal, `next` whole when they do not overlap, else at
/// most two disjoint rectangles (an L-shape: a full-height column strip and a row strip without the corner).
std::vector<TexelRect> exposedRects(const TexelRect& previous, const TexelRect& next);

/// A piece of a level-texel rectangle and where it goes in the toroidal texture.
struct ToroidalPiece {
    TexelRect source; // level texels
    int destX = 0, destY = 0; // texture texel of source's (x0, y0)
};

/// Splits `rect` (at most size×size) where it crosses the wrap seam of a size×size toroidal texture: 1 to 4 pieces,
/// each contiguous in the texture.
std::vector<ToroidalPiece> toroidalPieces(const TexelRect& rect, int size);

} // namespace seasonview
