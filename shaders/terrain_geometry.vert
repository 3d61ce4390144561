// GPU geometry clipmaps (Asirvatham & Hoppe 2005, GPU Gems 2 ch. 2 §2.4): one piece of one level. Vertex grid
// positions are level cells; heights come from the elevation clipmap (R32F, level-0 samples = the elevation
// grid's samples, i east, j south); in the transition region near the level's outer edge heights and normals
// blend towards the coarser level (§2.4.2), reaching it exactly at the edge so neighbouring levels meet.
layout(location = 0) in vec2 aGrid;

uniform mat4 uViewProj;
uniform vec2 uPieceOffset;   // piece origin, level cells
uniform vec2 uLevelOrigin;   // sample coordinates of the level's vertex (0, 0)
uniform float uCell;         // samples per cell, 2^level
uniform int uLevel;
uniform vec2 uLevelCentre;   // sample coordinates of the level's centre
uniform float uHalfCells;    // (n - 1) / 2
uniform float uTransitionWidth; // cells (n / 10)
uniform int uBlendToCoarser; // 0 for the coarsest level
uniform vec2 uGridOrigin;    // local position of sample (0, 0)
uniform float uGridSpacing;  // metres per sample
uniform sampler2D uLocalToImage; // RG32F: local -> leaf-on image coordinates in [0,1]
uniform vec2 uLookupMin, uLookupSize; // lattice point i of K at uLookupMin + uLookupSize * i / (K - 1)
uniform float uLookupTexels;          // K
uniform mat2 uLookupSlope;            // d(image uv) / d(t) over the whole lattice: extrapolates past its edge

uniform int uNormals;        // 0: skip the normals (no view needs them)
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

#ifdef CANOPY_LAYER
// Stacked canopy layers (Ropinski et al. 2007 §4.2, foliage/CanopyRendererGL.h): instance i is layer i, lifted to
// i / (N - 1) of the tree height.
uniform float uCanopyHeight;
uniform int uCanopyLayers;
flat out int vLayer;
#endif

invariant gl_Position; // layer 0 lies exactly on the ground and must land on the same depth

out vec2 vImageUv;
out vec3 vNormal;
out vec3 vLocal;
flat out int vLevel;

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
    for (int l = min(level, uElevLevels - 1); l < uElevLevels; ++l) {
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

// Unnormalised normal (local frame, z up) from central differences `step` samples apart at level `level`.
vec3 normalAt(int level, vec2 s, float step) {
    float hx = elevationAt(level, s + vec2(step, 0.0)) - elevationAt(level, s - vec2(step, 0.0));
    float hy = elevationAt(level, s - vec2(0.0, step)) - elevationAt(level, s + vec2(0.0, step)); // j runs south
    return vec3(-hx, -hy, 2.0 * step * uGridSpacing);
}

void main() {
    vec2 cell = aGrid + uPieceOffset;
    vec2 s = uLevelOrigin + cell * uCell;
    vec2 d = abs(s - uLevelCentre) / uCell;
    vec2 a = clamp((d - (uHalfCells - uTransitionWidth - 1.0)) / uTransitionWidth, 0.0, 1.0);
    float alpha = uBlendToCoarser != 0 ? max(a.x, a.y) : 0.0;
    float z = elevationAt(uLevel, s);
    vec3 n = uNormals != 0 ? normalAt(uLevel, s, uCell) : vec3(0.0, 0.0, 1.0);
    if (alpha > 0.0) {
        z = mix(z, elevationAt(uLevel + 1, s), alpha);
        if (uNormals != 0) n = mix(n, normalAt(uLevel + 1, s, 2.0 * uCell), alpha);
    }
#ifdef CANOPY_LAYER
    vLayer = gl_InstanceID;
    z += uCanopyHeight * float(gl_InstanceID) / float(max(uCanopyLayers - 1, 1));
#endif
    vec2 local = vec2(uGridOrigin.x + s.x * uGridSpacing, uGridOrigin.y - s.y * uGridSpacing);
    vLocal = vec3(local, z);
    vNormal = normalize(n);
    vLevel = uLevel;
    // 0..1 across the lattice; texel centres at (i + 0.5) / K. Past the lattice the map is extended linearly, not
    // clamped: a coarse triangle reaching far outside must still interpolate image coordinates that cross the
    // image's edge where the edge is, or the discard would cut it in the wrong place.
    vec2 t = (local - uLookupMin) / uLookupSize;
    vec2 tc = clamp(t, 0.0, 1.0);
    vImageUv = textureLod(uLocalToImage, (tc * (uLookupTexels - 1.0) + 0.5) / uLookupTexels, 0.0).xy +
               uLookupSlope * (t - tc);
    gl_Position = uViewProj * vec4(local, z, 1.0);
}
