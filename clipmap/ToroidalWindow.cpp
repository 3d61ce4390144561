#include "ToroidalWindow.h"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace seasonview {

TexelRect intersect(const TexelRect& a, const TexelRect& b) {
    TexelRect r{std::max(a.x0, b.x0), std::max(a.y0, b.y0), std::min(a.x1, b.x1), std::min(a.y1, b.y1)};
    if (r.empty()) return TexelRect{};
    return r;
}

TexelRect windowAround(glm::dvec2 centre, int size, int align) {
    assert(size > 0 && align >= 2 && align % 2 == 0 && size % align == 0 && "windowAround(): bad size or alignment");
    // Even origins: level l+1's texel x covers level l's texels 2x, 2x+1, so aligned windows nest exactly.
    const double a = align;
    const int ox = align * int(std::floor((centre.x - 0.5 * size) / a + 0.5));
    const int oy = align * int(std::floor((centre.y - 0.5 * size) / a + 0.5));
    return TexelRect{ox, oy, ox + size, oy + size};
}

std::vector<TexelRect> exposedRects(const TexelRect& previous, const TexelRect& next) {
    if (next.empty()) return {};
    const TexelRect common = intersect(previous, next);
    if (common.empty()) return {next};
    std::vector<TexelRect> out;
    // Column strip(s) over the full height of `next`, then the row strip(s) between them.
    if (next.x0 < common.x0) out.push_back({next.x0, next.y0, common.x0, next.y1});
    if (common.x1 < next.x1) out.push_back({common.x1, next.y0, next.x1, next.y1});
    if (next.y0 < common.y0) out.push_back({common.x0, next.y0, common.x1, common.y0});
    if (common.y1 < next.y1) out.push_back({common.x0, common.y1, common.x1, next.y1});
    return out;
}

std::vector<ToroidalPiece> toroidalPieces(const TexelRect& rect, int size) {
    assert(rect.width() <= size && rect.height() <= size && "toroidalPieces(): rectangle larger than the texture");
    std::vector<ToroidalPiece> out;
    if (rect.empty()) return out;
    const int dx = wrapTexel(rect.x0, size), dy = wrapTexel(rect.y0, size);
    const int w0 = std::min(rect.width(), size - dx), h0 = std::min(rect.height(), size - dy);
    const int xs[2][3] = {{rect.x0, rect.x0 + w0, dx}, {rect.x0 + w0, rect.x1, 0}};
    const int ys[2][3] = {{rect.y0, rect.y0 + h0, dy}, {rect.y0 + h0, rect.y1, 0}};
    for (const auto& y : ys)
        for (const auto& x : xs) {
            const TexelRect s{x[0], y[0], x[1], y[1]};
            if (!s.empty()) out.push_back({s, x[2], y[2]});
        }
    return out;
}

} // namespace seasonview
