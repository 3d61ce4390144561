// The elevation clipmap (terrain/GeometryClipmapGL.h binds it): heights at level-0 sample coordinates of the
// elevation grid (i east, j south), from the finest resident level, as the geometry clipmap's vertices and the
// trunks standing on the terrain fetch them.
#include "common_intdiv.glsl"

uniform int uHasElevation;
uniform sampler2DArray uElevClip;
uniform sampler2DArray uElevCoarse; // the resident levels, exact, one layer each
uniform isampler2DArray uElevClipTags;
uniform int uElevClipLevels;
uniform float uElevClipSize;
uniform int uElevBlockSize;
uniform int uElevSlotsPerSide;
uniform int uElevLevels;
uniform vec2 uElevLevelSize[24];

// For a sample t >= 0 of a level: its block, its block's slot and where the N×N level stores it. Built for one
// elevation clipmap (GeometryClipmapGL::layoutDefines), its layout is compile-time constants: llvmpipe divides by a
// constant with a multiply and a shift, by a uniform lane by lane (common_intdiv.glsl).
#ifdef ELEV_CLIP_BLOCK_SIZE
ivec2 elevBlockOf(ivec2 t) { return ivec2(uvec2(t) / uint(ELEV_CLIP_BLOCK_SIZE)); }
ivec2 elevSlotOf(ivec2 b) { return ivec2(uvec2(b) % uint(ELEV_CLIP_SLOTS_PER_SIDE)); }
ivec2 elevTexelOf(ivec2 t) { return ivec2(uvec2(t) % uint(ELEV_CLIP_SIZE)); }
#else
ivec2 elevBlockOf(ivec2 t) { return svDiv(t, uElevBlockSize); }
ivec2 elevSlotOf(ivec2 b) { return svMod(b, uElevSlotsPerSide); }
ivec2 elevTexelOf(ivec2 t) { return svMod(t, int(uElevClipSize)); }
#endif

bool elevBlockValid(int level, ivec2 t) {
    ivec2 b = elevBlockOf(t);
    ivec2 slot = elevSlotOf(b);
    return texelFetch(uElevClipTags, ivec3(slot, level), 0).r == (b.x | (b.y << 16));
}

// Height of level `level`'s sample t (clamped into the level). False when its block is not resident yet.
bool elevTexel(int level, ivec2 t, out float h) {
    h = 0.0; // defined when not resident: callers may weight it by 0
    t = clamp(t, ivec2(0), ivec2(uElevLevelSize[level]) - 1);
    if (level >= uElevClipLevels) {
        h = texelFetch(uElevCoarse, ivec3(t, level - uElevClipLevels), 0).r;
        return true;
    }
    if (!elevBlockValid(level, t)) return false;
    h = texelFetch(uElevClip, ivec3(elevTexelOf(t), level), 0).r;
    return true;
}

// Height at sample coordinates s (level-0 samples), from level `level` or the first coarser level resident there:
// bilinear between that level's samples (exact at its own samples).
float elevationAt(int level, vec2 s) {
    if (uHasElevation == 0) return 0.0;
    for (int l = clamp(level, 0, uElevLevels - 1); l < uElevLevels; ++l) {
        vec2 q = s / exp2(float(l));
        ivec2 i0 = ivec2(floor(q));
        vec2 f = q - vec2(i0);
        float h00, h10 = 0.0, h01 = 0.0, h11 = 0.0;
        bool ok = elevTexel(l, i0, h00);
        if (f.x > 0.0) ok = ok && elevTexel(l, i0 + ivec2(1, 0), h10);
        if (f.y > 0.0) ok = ok && elevTexel(l, i0 + ivec2(0, 1), h01);
        if (f.x > 0.0 && f.y > 0.0) ok = ok && elevTexel(l, i0 + ivec2(1, 1), h11);
        if (!ok) continue;
        return mix(mix(h00, h10, f.x), mix(h01, h11, f.x), f.y);
    }
    return 0.0;
}

// The surface a geometry clipmap level's vertices take at sample coordinates s (level-0 samples): for a DEM level
// (level >= 0), whose vertices lie on its samples, that sample's height; for a level finer than the DEM (level < 0),
// the DEM's triangulated surface (each level-0 cell split along its north-east to south-west diagonal, the surface of
// the reference mesh and of the elevation grid's resampling). Both as one triangle of level max(level, 0): its corner
// ia and the neighbours i0 + (1, 0), i0 + (0, 1), weighted by fa (0 at a sample, so exactly the sample's height).
// One fetch pattern for both kinds: llvmpipe runs both sides of a branch under a mask. Where a texel with a weight is
// not resident, the same triangle at the next coarser resident level.
float surfaceAt(int level, vec2 s) {
    if (uHasElevation == 0) return 0.0;
    // A loop, not a fallback call after the first try: llvmpipe leaves a loop once no lane is left in it, where it
    // would run the code after an `if` for every lane.
    for (int l = clamp(level, 0, uElevLevels - 1); l < uElevLevels; ++l) {
        vec2 q = s / exp2(float(l));
        ivec2 i0 = ivec2(floor(q));
        vec2 f = q - vec2(i0);
        bool lower = f.x + f.y <= 1.0;
        ivec2 ia = lower ? i0 : i0 + ivec2(1);
        vec2 fa = lower ? f : 1.0 - f;
        float ha, h10, h01;
        bool okA = elevTexel(l, ia, ha);
        bool ok10 = elevTexel(l, i0 + ivec2(1, 0), h10);
        bool ok01 = elevTexel(l, i0 + ivec2(0, 1), h01);
        // The texel on x's side weights fa.x in the lower triangle and fa.y in the upper one.
        float wx = lower ? fa.x : fa.y, wy = lower ? fa.y : fa.x;
        if (okA && (wx == 0.0 || ok10) && (wy == 0.0 || ok01))
            return lower ? ha + fa.x * (h10 - ha) + fa.y * (h01 - ha) : ha + fa.x * (h01 - ha) + fa.y * (h10 - ha);
    }
    return 0.0;
}
