// Crown centres at runtime (Ropinski et al. 2007 Fig. 6c; foliage/TrunksGL.h), per clip level region, the GPU
// counterpart of CrownCentres.h: over one toroidal level of the derived canopy layer (common_canopy.glsl; a texel
// is canopy where it belongs to the ground layer, value >= 1), passes 0 and 1 store each canopy texel's Euclidean
// distance to the nearest texel outside the canopy (separably: the nearest along each column, then the nearest
// over the row's columns; clamped at uMaxRadius; -1 where a texel not derived yet could be nearer), pass 2 keeps the
// maxima of that distance
// at least uMinRadius, each the largest within 0.75 × its distance (ties: the first in row order), and appends them
// to the trunk buffer after its head (a DrawArraysIndirectCommand whose instance count is the number found; the CPU
// reads it back and draws that many instances).

// The imagery clipmap's layout (ClipmapGL::bind, its layoutDefines(); common_clipmap.glsl itself needs derivatives).
#include "common_canopy.glsl"

#if PASS == 0
// Pass 0 scans columns: an invocation per column and run of SEGMENT rows (TrunksGL::find dispatches N/64 × N/SEGMENT).
#define SEGMENT 64
layout(local_size_x = 64, local_size_y = 1) in;
#else
layout(local_size_x = 16, local_size_y = 16) in;
#endif

// PASS (0: distances along columns, 1: along rows (the distance), 2: maxima) is a compile-time constant, one program
// each: llvmpipe runs both sides of a branch on a uniform under a mask, so every pass paid for all three.
#ifndef PASS
#error "trunk_find.comp: PASS must be defined"
#endif
const int uPass = PASS;
uniform int uLevel;       // the clip level searched
uniform ivec2 uWindow0;   // its window's first texel (level texels)
uniform ivec2 uWindow1;   // one past its last
uniform float uMinRadius; // texels
uniform int uMaxRadius;   // texels
uniform int uCapacity;

layout(r32f, binding = 0) uniform image2D uDistance; // N×N, toroidal like the level
layout(rg32f, binding = 1) uniform image2D uColumn;  // pass 0: per texel the column's nearest outside / unknown texel

layout(std430, binding = 0) buffer Trunks {
    uint vertexCount;     // DrawArraysIndirectCommand
    uint instanceCount;   // appended centres (may pass uCapacity: the draw ignores those)
    uint first;
    uint baseInstance;
    vec4 trunks[];        // level-0 texel x, y, crown radius in level-0 texels, canopy value
};

bool inWindow(ivec2 q) { return all(greaterThanEqual(q, uWindow0)) && all(lessThan(q, uWindow1)); }

// Where the N×N level stores window texel q (q mod N; the window may start left of or above the image).
ivec2 gWindow0Mod = ivec2(0); // uWindow0 mod N, >= 0 (set first thing in main())
ivec2 stored(ivec2 q) { return clipTexelOf(q - uWindow0 + gWindow0Mod); }

// -1: unknown (outside the window or the level's image, or not derived), else the canopy value.
int valueAt(ivec2 q) {
    if (!inWindow(q) || any(lessThan(q, ivec2(0))) || !canopyBlockValid(uLevel, q)) return -1;
    return int(texelFetch(uCanopyClip, ivec3(stored(q), uLevel), 0).r);
}

float distanceAt(ivec2 q) {
    if (!inWindow(q)) return -1.0;
    return imageLoad(uDistance, stored(q)).r;
}

void main() {
    ivec2 t = ivec2(gl_GlobalInvocationID.xy);
#ifdef CLIP_SIZE
    const int n = CLIP_SIZE; // a constant: llvmpipe's remainders below by a multiply, not lane by lane
#else
    int n = int(uClipSize);
#endif
    gWindow0Mod = (uWindow0 % n + n) % n;
#if PASS == 0
    // Along the column: per texel the nearest texel outside the canopy up or down (0 on one), and the nearest unknown
    // one met before it (farther unknowns cannot come nearer than that outside texel), both clamped past uMaxRadius:
    // the first texel either way that is not canopy decides that way (up first where both lie at one distance).
    // One invocation walks its column's window rows [y0, y0 + SEGMENT) from uMaxRadius before to uMaxRadius after,
    // each texel read once (instead of up to 2 × uMaxRadius reads per canopy texel).
    if (t.x >= n || t.y * SEGMENT >= n) return;
    int x = uWindow0.x + t.x, y0 = uWindow0.y + t.y * SEGMENT;
    const int none = -(1 << 20);
    float far = float(uMaxRadius + 1);
    int value[SEGMENT];   // the texels' values (valueAt)
    int upRow[SEGMENT];   // per texel the row of the nearest non-canopy texel above (none: not within the scan)
    int lastRow = none, lastValue = 0;
    for (int y = y0 - uMaxRadius; y < y0 + SEGMENT; ++y) {
        int v = valueAt(ivec2(x, y));
        if (y >= y0) {
            value[y - y0] = v;
            upRow[y - y0] = lastRow == none ? none : (lastValue == 0 ? lastRow : -1 - lastRow);
        }
        if (v <= 0) {
            lastRow = y;
            lastValue = v;
        }
    }
    lastRow = none;
    for (int y = y0 + SEGMENT - 1 + uMaxRadius; y >= y0; --y) {
        int v = y < y0 + SEGMENT ? value[y - y0] : valueAt(ivec2(x, y));
        if (y < y0 + SEGMENT) {
            float zero = far, unknown = far;
            if (v < 0) {
                zero = -1.0;
            } else if (v == 0) {
                zero = 0.0;
            } else {
                // The events either way within uMaxRadius: distance and whether outside (true) or unknown.
                int u = upRow[y - y0];
                bool upSeen = u != none && (u >= 0 ? y - u : y - (-1 - u)) <= uMaxRadius;
                float du = upSeen ? float(u >= 0 ? y - u : y - (-1 - u)) : far;
                bool upZero = upSeen && u >= 0;
                bool downSeen = lastRow != none && lastRow - y <= uMaxRadius;
                float dd = downSeen ? float(lastRow - y) : far;
                bool downZero = downSeen && lastValue == 0;
                zero = min(upZero ? du : far, downZero ? dd : far);
                // As a walk outward r = 1, 2, ... (up, then down) that stops at the first outside texel: an unknown
                // one counts where it comes before it (up: not after; down: before).
                if (upSeen && !upZero && du <= (downZero ? dd : far)) unknown = min(unknown, du);
                if (downSeen && !downZero && dd < (upZero ? du : far)) unknown = min(unknown, dd);
            }
            imageStore(uColumn, stored(ivec2(x, y)), vec4(zero, unknown, 0.0, 0.0));
        }
        if (v <= 0) {
            lastRow = y;
            lastValue = v;
        }
    }
#else
    if (t.x >= n || t.y >= n) return;
    // The level texel stored at t: the one of the window congruent to t modulo N.
    ivec2 q = uWindow0 + clipTexelOf(t - gWindow0Mod + n);
    if (uPass == 1) {
        // Along the row, over the columns' nearest outside texels (a separable Euclidean distance transform, exact
        // within uMaxRadius): d² = min over dx of dx² + column(x + dx)²; unknown if an unknown texel lies nearer
        // than that (or the row leaves the window within it).
        vec2 c = imageLoad(uColumn, t).rg;
        float d = 0.0;
        if (c.r < 0.0) {
            d = -1.0;
        } else if (c.r > 0.0) {
            float best2 = float(uMaxRadius * uMaxRadius), unknown2 = c.g * c.g;
            best2 = min(best2, c.r * c.r);
            for (int dx = 1; dx <= uMaxRadius && float(dx * dx) < best2; ++dx) {
                for (int side = -1; side <= 1; side += 2) {
                    ivec2 o = q + ivec2(side * dx, 0);
                    if (!inWindow(o)) {
                        unknown2 = min(unknown2, float(dx * dx));
                        continue;
                    }
                    vec2 w = imageLoad(uColumn, stored(o)).rg;
                    if (w.r < 0.0) {
                        unknown2 = min(unknown2, float(dx * dx));
                        continue;
                    }
                    best2 = min(best2, float(dx * dx) + w.r * w.r);
                    unknown2 = min(unknown2, float(dx * dx) + w.g * w.g);
                }
            }
            d = unknown2 < best2 ? -1.0 : sqrt(best2);
        }
        imageStore(uDistance, t, vec4(d));
        return;
    }
    float d = imageLoad(uDistance, t).r;
    float radius = max(0.5, d - 0.5); // the edge lies half a texel before the nearest outside texel's centre
    if (d <= 0.0 || radius < uMinRadius) return;
    // A maximum of its 3 × 3 neighbours first (the same conditions as the window's, which holds them): most canopy
    // texels lie on a slope and stop here with 8 reads; the window's loop then runs only for the few that remain.
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
            if (dx == 0 && dy == 0) continue;
            float w = distanceAt(q + ivec2(dx, dy));
            if (w < 0.0) return;
            bool before = dy < 0 || (dy == 0 && dx < 0);
            if (w > d || (before && w == d)) return;
        }
    int s = max(1, int(ceil(0.75 * d)));
    for (int dy = -s; dy <= s; ++dy)
        for (int dx = -s; dx <= s; ++dx) {
            if (dx == 0 && dy == 0) continue;
            float w = distanceAt(q + ivec2(dx, dy));
            if (w < 0.0) return; // not known there yet: decide when it is
            bool before = dy < 0 || (dy == 0 && dx < 0);
            if (w > d || (before && w == d)) return;
        }
    uint i = atomicAdd(instanceCount, 1u);
    if (int(i) >= uCapacity) return;
    float scale = exp2(float(uLevel));
    trunks[i] = vec4((vec2(q) + 0.5) * scale, radius * scale, float(valueAt(q)));
#endif
}
