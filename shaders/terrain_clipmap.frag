// Terrain draped with the imagery clipmaps (layer 0 leaf-on, layer 1 leaf-off). Variant LEVEL_STATS writes
// (needed level, used level) / 255 for FrameLevelStats instead of a colour; variant CANOPY_LAYER draws one of the
// stacked canopy layers (Ropinski et al. 2007 §4.2): a fragment stays only where its texel belongs to the layer.
#include "common_clipmap.glsl"
#include "common_canopy.glsl"
#include "common_view.glsl"

in vec2 vImageUv;
in vec3 vNormal;
flat in int vLevel;
#ifdef CANOPY_LAYER
flat in int vLayer;
flat in ivec2 vCanopyLevels; // the canopy levels this patch may read (CanopyRendererGL bounds its layers by them)
#endif
#ifdef CANOPY_MARCH
// Where the rays enter the stacked layers (foliage/CanopyRendererGL.h, CanopyDrawMode::March), at half the frame's
// resolution: this fragment lies on the top layer, whose plane here each frame pixel of the texel meets its own ray
// with (common_canopy_march.glsl). The march runs from there once per frame pixel, however small the triangles.
in vec3 vLocal;
#endif
#ifdef GBUFFER
// The deferred geometry pass (ClipmapTerrainRendererGL, TerrainShading::Deferred): where the terrain is, its level-0
// position and footprint derivatives, and its normal's x and y (z > 0 on a heightfield); terrain_resolve.frag then
// shades each pixel once. The derivatives are taken here, in the triangle's own quads, so the resolve filters
// exactly as the forward pass does.
layout(location = 0) out vec4 gPosition;  // p, dFdx(p)
layout(location = 1) out vec4 gFootprint; // dFdy(p), n.xy
#ifdef GBUFFER_DEPTH
layout(location = 2) out float gDepth;    // the depth: the canopy view's marching resolve writes it back
#endif
// GBUFFER_DEPTH_PACKED (the same without normals, NORMALS 0): gFootprint = (dFdy(p), depth, 0).
#elif defined(CANOPY_MARCH)
layout(location = 0) out vec4 eEntry;     // p, the plane's unit normal xy
layout(location = 1) out vec4 eRay;       // the local point the ray enters at, the first layer it tests + 256 × the
                                          // canopy level its patch reads
#else
out vec4 fragColor;
#endif

void main() {
    if (any(lessThan(vImageUv, vec2(0.0))) || any(greaterThan(vImageUv, vec2(1.0)))) discard;
#if !defined(LEVEL_STATS) && !defined(GBUFFER) && !defined(CANOPY_MARCH)
    if (uWirePass != 0) {
        fragColor = vec4(uLevelColors[min(vLevel, 7)], 1.0);
        return;
    }
#endif
    vec2 p = vImageUv * uLevel0Size;
    int used;
#if defined(CANOPY_LAYER) && !defined(CANOPY_MARCH)
    p += uLayerShift * float(vLayer);
#endif
#ifdef CANOPY_MARCH
#if NORMALS
    vec3 n = normalize(vNormal); // shaded crowns: the smooth normal, also the plane's (off the triangle's by a little)
#else
    // The triangle's own plane: the vertices' normals are not computed (4 height fetches a vertex) where the crowns
    // are not shaded.
    vec3 facet = cross(dFdx(vLocal), dFdy(vLocal));
    vec3 n = normalize(facet.z < 0.0 ? -facet : facet);
#endif
    eEntry = vec4(p, n.xy);
    eRay = vec4(vLocal, float(vLayer + 256 * vCanopyLevels.x));
#else
#ifdef CANOPY_LAYER
    // The canopy at the level the footprint asks for (its isotropic level, computed alone: most layer fragments
    // stop here), within the levels the patch's layers were chosen for: one fetch, then the leaf-on colour only for
    // kept fragments, darker towards the ground (self-shadowing inside the crown).
    float lambdaIso = log2(max(max(length(dFdx(p)), length(dFdy(p))), 1e-8));
    int canopyLevel = clamp(int(floor(max(lambdaIso, 0.0))), vCanopyLevels.x, vCanopyLevels.y);
    if (canopyAt(p, canopyLevel) <= vLayer) discard;
#endif
    ClipFootprint f = clipmapFootprint(p);
#ifdef CANOPY_LAYER
    vec3 lc = sampleClipmap(0, p, f, used).rgb;
    lc *= mix(uCanopyDark, 1.0, float(vLayer) / float(max(uCanopyLayers - 1, 1)));
    if (uShade > 0.0) lc *= mix(1.0, 0.25 + 0.75 * max(dot(normalize(vNormal), uSunDir), 0.0), uShade);
    fragColor = vec4(lc, 1.0);
    return;
#elif defined(LEVEL_STATS)
    sampleClipmap(0, p, f, used);
    float needed = clamp(floor(max(f.lambdaIso, 0.0)), 0.0, 254.0);
    fragColor = vec4(needed / 255.0, float(min(used, 254)) / 255.0, 0.0, 1.0);
#elif defined(GBUFFER)
    gPosition = vec4(p, dFdx(p));
#ifdef GBUFFER_DEPTH_PACKED
    gFootprint = vec4(dFdy(p), gl_FragCoord.z, 0.0);
#else
    gFootprint = vec4(dFdy(p), normalize(vNormal).xy);
#endif
#ifdef GBUFFER_DEPTH
    gDepth = gl_FragCoord.z;
#endif
#else
    fragColor = vec4(viewColour(p, f, normalize(vNormal), vLevel, used), 1.0);
#endif
#endif // CANOPY_MARCH
}
