#include "CanopyDerive.h"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace seasonview {

int canopyLayerK(const SegmentationParams& params, int layers, int topK, int layer, int level) {
    if (params.method == SegmentationMethod::Pixel) return 1;
    const int k = effectiveK(params), n = layers;
    // Ground layer k, top layer topK, odd in between (Ropinski et al. 2007 §4.2: k grows with height).
    const int ki = n > 1 ? k + 2 * int(std::lround(double(topK - k) / 2.0 * double(layer) / double(n - 1))) : k;
    // About the same metres on coarser levels: k / 2^level, rounded down to odd.
    return 2 * int(std::floor(double(ki) / std::exp2(double(level + 1)))) + 1;
}

std::vector<CanopyGroup> canopyGroups(const SegmentationParams& params, int layers, int topK, int level) {
    std::vector<CanopyGroup> groups;
    for (int i = 0; i < layers; ++i) {
        const int k = canopyLayerK(params, layers, topK, i, level);
        if (i + 1 < layers && canopyLayerK(params, layers, topK, i + 1, level) == k) continue;
        groups.push_back({k, i + 1});
    }
    return groups;
}

int canopyDeriveHalo(SegmentationMethod method, const std::vector<CanopyGroup>& groups) {
    int k = 1;
    for (const CanopyGroup& g : groups) k = std::max(k, g.k);
    return k / 2 + (method == SegmentationMethod::Default ? kSegTextureHalo : 0);
}

void deriveCanopyTexels(const std::uint8_t* on, const std::uint8_t* off, const TexelRect& read, glm::ivec2 levelSize,
                        const TexelRect& out, SegmentationMethod method, const SegmentationStats& stats,
                        const std::vector<CanopyGroup>& groups, std::uint8_t* values) {
    const bool texture = method == SegmentationMethod::Default;
    const int th = texture ? kSegTextureHalo : 0;
    const int halo = canopyDeriveHalo(method, groups), vh = halo - th;
    const int outW = out.width(), outH = out.height();
    const int inW = outW + 2 * halo, inH = outH + 2 * halo;
    const int bw = outW + 2 * vh, bh = outH + 2 * vh;
    thread_local std::vector<int> bright, smooth;
    thread_local std::vector<std::uint8_t> in, bits;
    thread_local std::vector<std::uint32_t> sat;
    in.resize(size_t(inW) * size_t(inH));
    if (texture) bright.resize(in.size());

    // 1. Fetch (canopy_derive.comp step 1): texels beyond the level are its edge texels. default keeps the brightness
    //    r + g + b and the drop test, the others the two §4.1 conditions (bit 0: leaf-on green, bit 1: leaf-off not).
    const int readW = read.width();
    for (int j = 0; j < inH; ++j) {
        const int ty = std::clamp(out.y0 - halo + j, 0, levelSize.y - 1);
        assert(ty >= read.y0 && ty < read.y1);
        for (int i = 0; i < inW; ++i) {
            const int tx = std::clamp(out.x0 - halo + i, 0, levelSize.x - 1);
            assert(tx >= read.x0 && tx < read.x1);
            const size_t at = (size_t(ty - read.y0) * size_t(readW) + size_t(tx - read.x0)) * 4;
            int c[2][3];
            for (int s = 0; s < 2; ++s) {
                const std::uint8_t* p = (s == 0 ? on : off) + at;
                for (int ch = 0; ch < 3; ++ch) {
                    int v = unpremultiply(p[ch], p[3]);
                    if (method == SegmentationMethod::Equalized)
                        v = (s == 0 ? stats.lutOn : stats.lutOff)[size_t(ch)][size_t(v)];
                    c[s][ch] = v;
                }
            }
            const size_t o = size_t(j) * size_t(inW) + size_t(i);
            if (texture) {
                bright[o] = c[0][0] + c[0][1] + c[0][2];
                in[o] = dropAtLeast(c[0][0], c[0][1], c[0][2], c[1][0], c[1][1], c[1][2], stats.dropThreshold) ? 1 : 0;
            } else {
                in[o] = std::uint8_t((greenIsMax(c[0][0], c[0][1], c[0][2]) ? 1 : 0) |
                                     (greenIsMax(c[1][0], c[1][1], c[1][2]) ? 0 : 2));
            }
        }
    }

    // 2-3. Per-texel votes: default's drop on a textured canopy (the 5×5 window of 3×3 brightness sums, exact
    //      integer sums), the others' two conditions as fetched.
    bits.resize(size_t(bw) * size_t(bh));
    if (texture) {
        // Separable sums (the shader slides them down columns; integer sums either way, so the same values): 3 × 3
        // brightness sums, then each 5 × 5 window's sum and sum of squares (25 · 6885² < 2^32).
        constexpr int W = kSegTextureWindow;
        const int sw = inW - 2, sh = inH - 2;
        thread_local std::vector<std::uint32_t> row, rowSq;
        row.resize(size_t(inW) * size_t(inH));
        for (int y = 0; y < inH; ++y) {
            const int* src = bright.data() + size_t(y) * size_t(inW);
            std::uint32_t* dst = row.data() + size_t(y) * size_t(inW);
            for (int x = 0; x < sw; ++x) dst[x] = std::uint32_t(src[x] + src[x + 1] + src[x + 2]);
        }
        smooth.resize(size_t(sw) * size_t(sh));
        for (int y = 0; y < sh; ++y) {
            const std::uint32_t* r0 = row.data() + size_t(y) * size_t(inW);
            const std::uint32_t* r1 = r0 + inW;
            const std::uint32_t* r2 = r1 + inW;
            int* dst = smooth.data() + size_t(y) * size_t(sw);
            for (int x = 0; x < sw; ++x) dst[x] = int(r0[x] + r1[x] + r2[x]);
        }
        // Rows of 5: sums and sums of squares of the smoothed values.
        rowSq.resize(size_t(bw) * size_t(sh));
        row.resize(size_t(bw) * size_t(sh));
        for (int y = 0; y < sh; ++y) {
            const int* src = smooth.data() + size_t(y) * size_t(sw);
            std::uint32_t* s5 = row.data() + size_t(y) * size_t(bw);
            std::uint32_t* q5 = rowSq.data() + size_t(y) * size_t(bw);
            for (int x = 0; x < bw; ++x) {
                std::uint32_t hs = 0, hq = 0;
                for (int dx = 0; dx < W; ++dx) {
                    const std::uint32_t v = std::uint32_t(src[x + dx]);
                    hs += v;
                    hq += v * v;
                }
                s5[x] = hs;
                q5[x] = hq;
            }
        }
        for (int y = 0; y < bh; ++y)
            for (int x = 0; x < bw; ++x) {
                std::uint32_t sum = 0, sumSq = 0;
                for (int dy = 0; dy < W; ++dy) {
                    sum += row[size_t(y + dy) * size_t(bw) + size_t(x)];
                    sumSq += rowSq[size_t(y + dy) * size_t(bw) + size_t(x)];
                }
                const bool drop = in[size_t(y + th) * size_t(inW) + size_t(x + th)] != 0;
                bits[size_t(y) * size_t(bw) + size_t(x)] =
                    defaultTexel(drop, textured(double(W * W), double(sum), double(sumSq))) ? 1 : 0;
            }
    } else {
        for (int y = 0; y < bh; ++y)
            std::copy_n(in.begin() + std::ptrdiff_t(size_t(y) * size_t(inW)), bw,
                        bits.begin() + std::ptrdiff_t(size_t(y) * size_t(bw)));
    }

    // 4. Votes over growing windows from a summed-area table of both counts (a + b · 65536), from the largest k down:
    //    the texel's value is the `top` of the first group with a majority.
    const int satW = bw + 1;
    sat.assign(size_t(satW) * size_t(bh + 1), 0u);
    for (int y = 1; y <= bh; ++y) {
        std::uint32_t run = 0;
        for (int x = 1; x < satW; ++x) {
            const std::uint8_t v = bits[size_t(y - 1) * size_t(bw) + size_t(x - 1)];
            run += std::uint32_t(v & 1u) | (std::uint32_t((v >> 1) & 1u) << 16);
            sat[size_t(y) * size_t(satW) + size_t(x)] = sat[size_t(y - 1) * size_t(satW) + size_t(x)] + run;
        }
    }
    // The windows are nested (all centred on the texel): no smaller window counts more than the largest, so where the
    // largest's count is no majority of the smallest window, no group can have one (open ground: one lookup).
    const int kMin = groups.front().k;
    for (int y = 0; y < outH; ++y)
        for (int x = 0; x < outW; ++x) {
            const int cx = x + vh, cy = y + vh;
            int top = 0;
            for (auto g = groups.rbegin(); g != groups.rend(); ++g) {
                const int r = g->k / 2;
                const int lx = cx - r, ly = cy - r, hx = cx + r + 1, hy = cy + r + 1;
                const std::uint32_t n = sat[size_t(hy) * size_t(satW) + size_t(hx)] -
                                        sat[size_t(ly) * size_t(satW) + size_t(hx)] -
                                        sat[size_t(hy) * size_t(satW) + size_t(lx)] +
                                        sat[size_t(ly) * size_t(satW) + size_t(lx)];
                const int a = int(n & 0xFFFFu), b = int(n >> 16);
                if (texture ? isMajority(a, g->k) : isMajority(a, g->k) && isMajority(b, g->k)) {
                    top = g->top;
                    break;
                }
                if (!isMajority(a, kMin) || (!texture && !isMajority(b, kMin))) break; // nor any smaller window
            }
            if (top > 0) {
                // Both seasons must cover more than half of the texel itself.
                const size_t at = (size_t(out.y0 + y - read.y0) * size_t(readW) + size_t(out.x0 + x - read.x0)) * 4;
                if (on[at + 3] < kSegMinAlpha || off[at + 3] < kSegMinAlpha) top = 0;
            }
            values[size_t(y) * size_t(outW) + size_t(x)] = std::uint8_t(top);
        }
}

} // namespace seasonview
