// The derived canopy layer of the texture clipmaps (foliage/CanopyClipmapGL.h): the seasonal treetop rule
// (Ropinski et al. 2007 §4.1, foliage_rule.glsl) evaluated once, when a block's texels (and its neighbours') have
// been uploaded, for every canopy layer at once (§4.2: "alter the size k of the neighborhood area based on the
// current height", k growing with the layer). Each texel stores how many layers it belongs to: the highest layer i
// whose k_i × k_i vote is a majority, plus one (0: not a treetop). A canopy fragment then costs one fetch.
//
// One work group: a 32×32 output tile of one block, 16×16 invocations with 2×2 outputs each, its input in shared
// memory with a halo of kSegMaxK / 2 (vote) + kSegTextureHalo (default's texture) texels. Texels outside the level's
// image are the nearest edge texel, exactly as on the CPU.
#include "foliage_rule.glsl"
#include "common_clip_layout.glsl" // the imagery clipmap's layout

layout(local_size_x = 16, local_size_y = 16) in;

const int TILE = 32;
const int VOTE_HALO = SV_SEG_MAX_K / 2;              // 7
const int HALO = VOTE_HALO + SV_SEG_TEXTURE_HALO;    // 10
const int IN = TILE + 2 * HALO;                      // 52: fetched texels
const int SM = IN - 2;                               // 50: 3×3 sums of brightness
const int BITS = TILE + 2 * VOTE_HALO;               // 46: per-texel votes

uniform sampler2DArray uClip;   // leaf-on, leaf-off toroidal levels: season s's level l at s · uClipLayerStride + l
uniform sampler2DArray uCoarse; // the resident coarse pyramids (level uClipLevels): season s at array layer s
uniform int uClipLayerStride;

layout(r8ui, binding = 0) uniform writeonly uimage2DArray uCanopyClipOut;
layout(r8ui, binding = 1) uniform writeonly uimage2D uCanopyCoarseOut;

// Blocks of this dispatch: x, y = block coordinates in level texels / block.
layout(std430, binding = 0) readonly buffer Blocks { ivec4 blocks[]; };
// Equalisation tables (method equalized): on r, g, b, off r, g, b; 256 entries each.
layout(std430, binding = 1) readonly buffer Luts { uint luts[]; };
// Per derived block the largest value of each cell of CELL × CELL texels, a byte each, four cells of a row to a uint
// (blocks[i].w indexes the block's (uBlockSize / CELL)² / 4 uints, each written whole by the work group that owns its
// cells): the renderer draws a patch only with the layers its canopy reaches (CanopyClipmapGL::maxValueOver, read
// back without waiting).
const int CELL = 8;
layout(std430, binding = 2) writeonly buffer CellMax { uint cellMax[]; };
shared uint sCellMax[(TILE / CELL) * (TILE / CELL)];

uniform int uLevel;        // the level derived; uCoarsePass: the coarse base
// COARSE_PASS (0 or 1: read the coarse textures' base, write uCanopyCoarseOut) and METHOD (SegmentationMethod: 0
// pixel, 1 neighborhood, 2 equalized, 3 default) are compile-time constants, one program each: llvmpipe runs both
// sides of a branch on a uniform under a mask, so every method's and both passes' fetches ran for each texel.
#if !defined(COARSE_PASS) || !defined(METHOD)
#error "canopy_derive.comp: COARSE_PASS and METHOD must be defined"
#endif
const int uCoarsePass = COARSE_PASS;
const int uMethod = METHOD;
uniform int uDropThreshold;
// The layers at this level grouped by their k (odd, non-decreasing with the layer; several layers share one k, all of
// them on coarser levels and with the `pixel` method): group g votes over uGroupK[g].x² texels and, where that vote is
// a majority, puts the texel on every layer up to uGroupK[g].y (its last layer + 1). Groups in increasing k; the
// texel's value is that of the last group with a majority, so the loop runs down from the last and stops at the
// first: a texel costs one vote per distinct k at most, not one per layer (16 per texel cost half the derivation).
uniform int uGroups;
uniform ivec2 uGroupK[32];

shared uint sIn[IN * IN];
shared int sSmooth[SM * SM];
shared uint sBits[BITS * BITS];

ivec2 levelSize() {
    if (uCoarsePass != 0) return ivec2(uCoarseSize);
    return ivec2(ceil(uLevel0Size / exp2(float(uLevel))));
}

ivec3 fetch8(int season, ivec2 t) {
    vec4 c;
    if (uCoarsePass != 0) {
        c = texelFetch(uCoarse, ivec3(t, season), 0);
    } else {
        c = texelFetch(uClip, ivec3(clipTexelOf(t), season * uClipLayerStride + uLevel), 0);
    }
    // Premultiplied: a texel partly without data (coarser levels at a data edge) holds the mean colour of its covered
    // part times its coverage. Texels with all their data are exactly as stored.
    ivec3 v = ivec3(round(c.rgb * 255.0));
    int a = int(round(c.a * 255.0));
    v = svUnpremultiply3(v, a);
    if (uMethod == 2) {
        int o = season * 768;
        v = ivec3(luts[o + v.r], luts[o + 256 + v.g], luts[o + 512 + v.b]);
    }
    return v;
}

// Whether both seasons have data at texel t (more than half of it): elsewhere no treetop is derived.
bool hasData(ivec2 t) {
    float a, b;
    if (uCoarsePass != 0) {
        a = texelFetch(uCoarse, ivec3(t, 0), 0).a;
        b = texelFetch(uCoarse, ivec3(t, 1), 0).a;
    } else {
        ivec2 q = clipTexelOf(t);
        a = texelFetch(uClip, ivec3(q, uLevel), 0).a;
        b = texelFetch(uClip, ivec3(q, uClipLayerStride + uLevel), 0).a;
    }
    return int(round(a * 255.0)) >= SV_SEG_MIN_ALPHA && int(round(b * 255.0)) >= SV_SEG_MIN_ALPHA;
}

void main() {
    const ivec4 blk = blocks[gl_WorkGroupID.z];
    const ivec2 size = levelSize();
    const ivec2 tileOrigin = blk.xy * uBlockSize + ivec2(gl_WorkGroupID.xy) * TILE;
    const int lid = int(gl_LocalInvocationIndex);
    const bool texture = uMethod == 3;
    if (lid < (TILE / CELL) * (TILE / CELL)) sCellMax[lid] = 0u;

    // 1. Fetch: default keeps brightness r+g+b (bits 0..9) and the drop test (bit 15); the others the two §4.1
    //    conditions (bit 0: leaf-on green, bit 1: leaf-off not green).
    for (int i = lid; i < IN * IN; i += 256) {
        ivec2 t = clamp(tileOrigin - HALO + ivec2(i % IN, i / IN), ivec2(0), size - 1);
        ivec3 on = fetch8(0, t), off = fetch8(1, t);
        uint v;
        if (texture) {
            v = uint(on.r + on.g + on.b) | (svDropAtLeast(on, off, uDropThreshold) ? 0x8000u : 0u);
        } else {
            v = (svGreenIsMax(on) ? 1u : 0u) | (svGreenIsMax(off) ? 0u : 2u);
        }
        sIn[i] = v;
    }
    barrier();
    // 2. default: 3×3 sums of brightness, down each column (half a column per invocation): each row's 3-sum is read
    //    once and kept for the two sums below it (3 reads a sum instead of 9: the derivation 12 % faster on llvmpipe).
    if (texture) {
        const int HALF_SM = (SM + 1) / 2;
        for (int task = lid; task < 2 * SM; task += 256) {
            int x = task % SM, y0 = (task / SM) * HALF_SM, y1 = min(y0 + HALF_SM, SM);
#define SV_ROW3(y) \
    int((sIn[(y) * IN + x] & 0x7FFFu) + (sIn[(y) * IN + x + 1] & 0x7FFFu) + (sIn[(y) * IN + x + 2] & 0x7FFFu))
            int h0 = SV_ROW3(y0), h1 = SV_ROW3(y0 + 1);
            for (int y = y0; y < y1; ++y) {
                int h2 = SV_ROW3(y + 2);
                sSmooth[y * SM + x] = h0 + h1 + h2;
                h0 = h1;
                h1 = h2;
            }
#undef SV_ROW3
        }
    }
    barrier();
    // 3. Per-texel votes (default: drop on a textured canopy, its 5×5 window of 3×3 sums). The window's sum and sum
    //    of squares slide down each column (half a column per invocation): each row of the window is summed once,
    //    added on entering and taken off on leaving. Integer sums, exact (25 · 6885² < 2^32), as on the CPU.
    if (texture) {
        const int W = SV_SEG_TEXTURE_WINDOW, HALF = (BITS + 1) / 2;
        for (int task = lid; task < 2 * BITS; task += 256) {
            int x = task % BITS, y0 = (task / BITS) * HALF, y1 = min(y0 + HALF, BITS);
            uint rowS[W], rowQ[W];
            uint sum = 0u, sumSq = 0u;
            for (int y = y0; y < y1 + W - 1; ++y) { // smoothed rows y0 .. y1 + W - 2
                uint hs = 0u, hq = 0u;
                for (int dx = 0; dx < W; ++dx) {
                    uint v = uint(sSmooth[y * SM + x + dx]);
                    hs += v;
                    hq += v * v;
                }
                int slot = (y - y0) % W;
                if (y - y0 >= W) {
                    sum -= rowS[slot];
                    sumSq -= rowQ[slot];
                }
                rowS[slot] = hs;
                rowQ[slot] = hq;
                sum += hs;
                sumSq += hq;
                int oy = y - (W - 1); // the vote texel whose window ends on this row
                if (oy < y0) continue;
                uint centre = sIn[(oy + SV_SEG_TEXTURE_HALO) * IN + x + SV_SEG_TEXTURE_HALO];
                bool t = svTextured(double(W * W), double(sum), double(sumSq));
                sBits[oy * BITS + x] = svDefaultTexel((centre & 0x8000u) != 0u, t) ? 1u : 0u;
            }
        }
    } else {
        for (int i = lid; i < BITS * BITS; i += 256)
            sBits[i] = sIn[(i / BITS + SV_SEG_TEXTURE_HALO) * IN + i % BITS + SV_SEG_TEXTURE_HALO];
    }
    barrier();
    // 4. Votes over growing windows: the highest layer whose k × k window has a majority. Window counts from a
    //    summed-area table of the votes (four reads per window whatever k), kept in sIn, which is free now: both
    //    counts packed in one uint (a + b · 65536; each is at most BITS² < 65536, so packed sums and differences are
    //    exact). Row prefix sums, then column prefix sums; entry (y, x) sums the votes above and left of it.
    const int SAT = BITS + 1;
    for (int y = lid; y < SAT; y += 256) {
        uint run = 0u;
        sIn[y * SAT] = 0u;
        for (int x = 1; x < SAT; ++x) {
            if (y > 0) {
                uint v = sBits[(y - 1) * BITS + x - 1];
                run += (v & 1u) | (((v >> 1) & 1u) << 16);
            }
            sIn[y * SAT + x] = run;
        }
    }
    barrier();
    for (int x = lid; x < SAT; x += 256) {
        uint run = 0u;
        for (int y = 0; y < SAT; ++y) {
            run += sIn[y * SAT + x];
            sIn[y * SAT + x] = run;
        }
    }
    barrier();
    for (int o = 0; o < 4; ++o) {
        ivec2 out2 = ivec2(gl_LocalInvocationID.xy) * 2 + ivec2(o & 1, o >> 1);
        ivec2 g = tileOrigin + out2;
        if (any(greaterThanEqual(g, size))) {
            // Past the image, in the last block of a row or column: no canopy (the trunks' search reads whole blocks).
            if (uCoarsePass == 0) imageStore(uCanopyClipOut, ivec3(clipTexelOf(g), uLevel), uvec4(0u));
            continue;
        }
        int top = 0; // default: votes; others: leaf-on green (a), leaf-off not green (b)
        ivec2 c = out2 + VOTE_HALO;
        for (int g = uGroups - 1; g >= 0; --g) {
            int k = uGroupK[g].x, r = k / 2;
            ivec2 lo = c - r, hi = c + r + 1; // SAT corners
            uint n = sIn[hi.y * SAT + hi.x] - sIn[lo.y * SAT + hi.x] - sIn[hi.y * SAT + lo.x] + sIn[lo.y * SAT + lo.x];
            int a = int(n & 0xFFFFu), b = int(n >> 16);
            if (texture ? svIsMajority(a, k) : svIsMajority(a, k) && svIsMajority(b, k)) {
                top = uGroupK[g].y;
                break;
            }
        }
        if (top > 0 && !hasData(g)) top = 0;
        if (top > 0) atomicMax(sCellMax[(out2.y / CELL) * (TILE / CELL) + out2.x / CELL], uint(top));
        if (uCoarsePass != 0) {
            imageStore(uCanopyCoarseOut, g, uvec4(uint(top)));
        } else {
            imageStore(uCanopyClipOut, ivec3(clipTexelOf(g), uLevel), uvec4(uint(top)));
        }
    }
    // 5. The tile's cell maxima: one uint per row of its TILE / CELL (= 4) cells.
    barrier();
    if (lid < TILE / CELL) {
        uint word = 0u;
        for (int i = 0; i < TILE / CELL; ++i) word |= min(sCellMax[lid * (TILE / CELL) + i], 255u) << (8 * i);
        const int cellsPerSide = uBlockSize / CELL, wordsPerRow = cellsPerSide / (TILE / CELL);
        const int row = int(gl_WorkGroupID.y) * (TILE / CELL) + lid;
        cellMax[blk.w * cellsPerSide * wordsPerRow + row * wordsPerRow + int(gl_WorkGroupID.x)] = word;
    }
}
