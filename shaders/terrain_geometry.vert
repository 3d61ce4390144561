// GPU geometry clipmaps (Asirvatham & Hoppe 2005, GPU Gems 2 ch. 2 §2.4): one piece of one level. Vertex grid
// positions are level cells; heights come from the elevation clipmap (R32F, level-0 samples = the elevation
// grid's samples, i east, j south); in the transition region near the level's outer edge heights and normals
// blend towards the coarser level (§2.4.2), reaching it exactly at the edge so neighbouring levels meet.
#include "common_elevation.glsl"

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

// NORMALS 0 or 1 (defined by every program): 0 skips the normals (no view needs them). A compile-time constant, not
// a uniform: llvmpipe runs both sides of a branch on a uniform under an execution mask, so a uniform that switches
// work off saves nothing there (docs/performance.md).
#ifndef NORMALS
#error "terrain_geometry.vert: NORMALS must be defined (0 or 1)"
#endif
const int uNormals = NORMALS;

#ifdef CANOPY_LAYER
// Stacked canopy layers (Ropinski et al. 2007 §4.2, foliage/CanopyRendererGL.h): layer j is lifted to
// base + (H - base) j / (N - 1), H the tree height, base 0 or the crowns' base over trunks. On the ground layer 0
// is drawn by the ground pass. The rings are drawn as small patches (GeometryClipmapGL::drawPatches), one instance
// per patch and layer: aInstance = (patch origin in level cells, layer, canopy levels the fragments may read:
// lowest | highest << 8), only the layers the canopy under the patch reaches, thinned where its stack is only a few
// pixels high on screen, each draw's instances top layer first (early depth tests spare the lower layers).
layout(location = 1) in ivec4 aInstance;
uniform float uCanopyHeight;
uniform float uCrownBase;
uniform int uCanopyLayers;
flat out int vLayer;
flat out ivec2 vCanopyLevels;
#endif

invariant gl_Position; // layer 0 lies exactly on the ground and must land on the same depth

out vec2 vImageUv;
out vec3 vNormal;
out vec3 vLocal;
flat out int vLevel;

// Unnormalised normal (local frame, z up) from central differences `step` samples apart at level `level`.
vec3 normalAt(int level, vec2 s, float step) {
    float hx = surfaceAt(level, s + vec2(step, 0.0)) - surfaceAt(level, s - vec2(step, 0.0));
    float hy = surfaceAt(level, s - vec2(0.0, step)) - surfaceAt(level, s + vec2(0.0, step)); // j runs south
    return vec3(-hx, -hy, 2.0 * step * uGridSpacing);
}

void main() {
#ifdef CANOPY_LAYER
    vec2 cell = aGrid + vec2(aInstance.xy);
#else
    vec2 cell = aGrid + uPieceOffset;
#endif
    if (uBlendToCoarser != 0) {
        // The outer edge meets the coarser level's inner edge, which has a vertex at every other one of this
        // level's (§2.4.2). Each odd vertex of the outer edge is moved onto its even neighbour: the two triangles
        // beside it on the edge collapse to degenerate ones, the rest fan from the even vertex, and the edge is
        // made of the coarser level's own edges with bit-identical end points. No T-junction is left, so the
        // rasteriser's fill rule closes the seam exactly. (The odd vertex lies on that edge anyway: the transition
        // gives it the coarser level's height, interpolated.)
        float last = 2.0 * uHalfCells;
        if ((cell.x == 0.0 || cell.x == last) && mod(cell.y, 2.0) == 1.0) cell.y -= 1.0;
        if ((cell.y == 0.0 || cell.y == last) && mod(cell.x, 2.0) == 1.0) cell.x -= 1.0;
    }
    vec2 s = uLevelOrigin + cell * uCell;
    vec2 d = abs(s - uLevelCentre) / uCell;
    vec2 a = clamp((d - (uHalfCells - uTransitionWidth - 1.0)) / uTransitionWidth, 0.0, 1.0);
    float alpha = uBlendToCoarser != 0 ? max(a.x, a.y) : 0.0;
    // Levels finer than the DEM take the DEM's triangulated surface, which is linear along every grid line of such
    // a level (the cells' diagonals cross those lines only at vertices): a coarser level's edge is that surface
    // between two vertices computed alike, so these levels need no blend to meet it, the DEM's level 0 included.
    float z = surfaceAt(uLevel, s);
    // Normals from differences at least one DEM sample apart: finer steps would only show the bilinear facets.
    vec3 n = uNormals != 0 ? normalAt(uLevel, s, max(uCell, 1.0)) : vec3(0.0, 0.0, 1.0);
    if (alpha > 0.0) {
        // At alpha 1 exactly the coarser level's height, bit for bit: mix() may round (z + (c - z) * 1 != c), and
        // the outer edge's vertices must land where the coarser level's own vertices do or a pixel centre on the
        // shared edge falls between the two.
        // (For a level finer than the DEM, surfaceAt(uLevel + 1) is the triangulated surface again: z itself.)
        const float coarse = surfaceAt(uLevel + 1, s);
        z = alpha >= 1.0 ? coarse : mix(z, coarse, alpha);
        if (uNormals != 0) n = mix(n, normalAt(uLevel + 1, s, max(2.0 * uCell, 1.0)), alpha);
    }
#ifdef CANOPY_LAYER
    vLayer = aInstance.z;
    vCanopyLevels = ivec2(aInstance.w & 255, aInstance.w >> 8);
#ifdef CANOPY_MARCH
    z += uCanopyHeight; // the top layer, where the fragment's ray enters the stack (vLayer: the first layer it tests)
#else
    z += uCrownBase + (uCanopyHeight - uCrownBase) * float(vLayer) / float(max(uCanopyLayers - 1, 1));
#endif
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
