// GPU geometry clipmaps (Asirvatham & Hoppe 2005, GPU Gems 2 ch. 2 §2.4): one piece of one level. Vertex grid
// positions are level cells; heights come from the elevation clipmap (R32F, level-0 samples = the elevation
// grid's samples, i east, j south); in the transition region near the level's outer edge heights and normals
// blend towards the coarser level (§2.4.2), reaching it exactly at the edge so neighbouring levels meet.
layout(location = 0) in vec2 aGrid;

uniform mat4 uViewProj;
uniform vec2 uPieceOffset;   // piece origin, level cells
uniform vec2 uLevelOrigin;   // sample coordinates of the level's vertex (0, 0)
uniform float uCell;         // samples per cell, 2^level (below 1 for levels finer than the DEM)
uniform int uLevel;          // DEM level: negative for levels finer than the DEM (the triangulated surface of level 0)
uniform int uDrawnLevel;     // 0 for the finest level drawn (the levels view's colour)
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
// Stacked canopy layers (Ropinski et al. 2007 §4.2, foliage/CanopyRendererGL.h): layer j is lifted to j / (N - 1)
// of the tree height. Layer 0 lies on the ground and is drawn by the ground pass; a piece draws uPieceInstances
// of layers 1 .. N - 1, evenly thinned where its stack is only a few pixels high on screen (instance i is layer
// round((i + 1) (N - 1) / uPieceInstances), the top layer always among them).
uniform float uCanopyHeight;
uniform int uCanopyLayers;
uniform int uPieceInstances;
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
    float h00, h10, h01, h11;
    if (f.x + f.y <= 1.0) {
        if (elevTexel(0, i0, h00) && elevTexel(0, i0 + ivec2(1, 0), h10) && elevTexel(0, i0 + ivec2(0, 1), h01))
            return h00 + f.x * (h10 - h00) + f.y * (h01 - h00);
    } else if (elevTexel(0, i0 + ivec2(1, 1), h11) && elevTexel(0, i0 + ivec2(1, 0), h10) &&
               elevTexel(0, i0 + ivec2(0, 1), h01)) {
        return h11 + (1.0 - f.x) * (h01 - h11) + (1.0 - f.y) * (h10 - h11);
    }
    return elevationAt(1, s);
}

// The surface of geometry level `level` at s as its own grid interpolates it along cell edges: exact at its
// vertices, linear between neighbouring vertices on a grid line. DEM levels: bilinear between that level's
// samples. Levels finer than the DEM: their vertices' triangulated heights, bilinear between them.
float levelSurface(int level, vec2 s) {
    if (level >= 0) return elevationAt(level, s);
    float c = exp2(float(level));
    vec2 q = s / c;
    vec2 i0 = floor(q);
    vec2 f = q - i0;
    float h00 = triangulatedAt(i0 * c);
    float h10 = f.x > 0.0 ? triangulatedAt((i0 + vec2(1.0, 0.0)) * c) : h00;
    float h01 = f.y > 0.0 ? triangulatedAt((i0 + vec2(0.0, 1.0)) * c) : h00;
    float h11 = f.x > 0.0 && f.y > 0.0 ? triangulatedAt((i0 + vec2(1.0)) * c) : h00;
    return mix(mix(h00, h10, f.x), mix(h01, h11, f.x), f.y);
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
    float z = uLevel >= 0 ? elevationAt(uLevel, s) : triangulatedAt(s);
    // Normals from differences at least one DEM sample apart: finer steps would only show the bilinear facets.
    vec3 n = uNormals != 0 ? normalAt(uLevel, s, max(uCell, 1.0)) : vec3(0.0, 0.0, 1.0);
    if (alpha > 0.0) {
        z = mix(z, levelSurface(uLevel + 1, s), alpha);
        if (uNormals != 0) n = mix(n, normalAt(uLevel + 1, s, max(2.0 * uCell, 1.0)), alpha);
    }
#ifdef CANOPY_LAYER
    vLayer = int(round(float((gl_InstanceID + 1) * (uCanopyLayers - 1)) / float(max(uPieceInstances, 1))));
    z += uCanopyHeight * float(vLayer) / float(max(uCanopyLayers - 1, 1));
#endif
    vec2 local = vec2(uGridOrigin.x + s.x * uGridSpacing, uGridOrigin.y - s.y * uGridSpacing);
    vLocal = vec3(local, z);
    vNormal = normalize(n);
    vLevel = uDrawnLevel;
    // 0..1 across the lattice; texel centres at (i + 0.5) / K. Past the lattice the map is extended linearly, not
    // clamped: a coarse triangle reaching far outside must still interpolate image coordinates that cross the
    // image's edge where the edge is, or the discard would cut it in the wrong place.
    vec2 t = (local - uLookupMin) / uLookupSize;
    vec2 tc = clamp(t, 0.0, 1.0);
    vImageUv = textureLod(uLocalToImage, (tc * (uLookupTexels - 1.0) + 0.5) / uLookupTexels, 0.0).xy +
               uLookupSlope * (t - tc);
    gl_Position = uViewProj * vec4(local, z, 1.0);
}
