// The elevation clipmap (terrain/GeometryClipmapGL.h binds it): heights at level-0 sample coordinates of the
// elevation grid (i east, j south), from the finest resident level, as the geometry clipmap's vertices and the
// trunks standing on the terrain fetch them.
uniform int uHasElevation;
uniform sampler2DArray uElevClip0;
uniform sampler2DArray uElevCoarse0; // the resident levels, exact, one layer each
uniform isampler2DArray uElevClipTags;
uniform int uElevClipLevels;
uniform float uElevClipSize;
uniform int uElevBlockSize;
uniform int uElevSlotsPerSide;
uniform int uElevLevels;
uniform vec2 uElevLevelSize[24];

bool elevBlockValid(int level, ivec2 t) {
    ivec2 b = t / uElevBlockSize;
    ivec2 slot = b % uElevSlotsPerSide;
    return texelFetch(uElevClipTags, ivec3(slot, level), 0).r == (b.x | (b.y << 16));
}

// Height of level `level`'s sample t (clamped into the level). False when its block is not resident yet.
bool elevTexel(int level, ivec2 t, out float h) {
    t = clamp(t, ivec2(0), ivec2(uElevLevelSize[level]) - 1);
    if (level >= uElevClipLevels) {
        h = texelFetch(uElevCoarse0, ivec3(t, level - uElevClipLevels), 0).r;
        return true;
    }
    if (!elevBlockValid(level, t)) return false;
    int n = int(uElevClipSize);
    h = texelFetch(uElevClip0, ivec3(t % n, level), 0).r;
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

// Height of the DEM's triangulated surface at sample coordinates s (each level-0 cell split along its north-east to
// south-west diagonal, the surface of the reference mesh and of the elevation grid's resampling): the heights of
// levels finer than the DEM. Bilinear from a coarser level while level 0 is not resident there.
float triangulatedAt(vec2 s) {
    if (uHasElevation == 0) return 0.0;
    ivec2 i0 = ivec2(floor(s));
    vec2 f = s - vec2(i0);
    // The triangle holding s: the lower one from sample i0, else the upper one from i0 + (1, 1); one set of fetches
    // for both (no branch: llvmpipe would run both sides).
    bool lower = f.x + f.y <= 1.0;
    ivec2 ia = lower ? i0 : i0 + ivec2(1);
    vec2 fa = lower ? f : 1.0 - f;
    float ha, h10, h01;
    if (elevTexel(0, ia, ha) && elevTexel(0, i0 + ivec2(1, 0), h10) && elevTexel(0, i0 + ivec2(0, 1), h01))
        return lower ? ha + fa.x * (h10 - ha) + fa.y * (h01 - ha) : ha + fa.x * (h01 - ha) + fa.y * (h10 - ha);
    return elevationAt(1, s);
}
