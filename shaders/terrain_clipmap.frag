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
// The stacked layers intersected per pixel (foliage/CanopyRendererGL.h, CanopyDrawMode::March): this fragment lies on
// the top layer; the ray from the eye through it meets layer i where it has come down the height between the two,
// over the terrain's local plane (its normal).
in vec3 vLocal;
uniform vec3 uEye;            // local metres
uniform mat2 uLocalToPixel;   // d(level-0 pixels) / d(local metres)
uniform mat4 uViewProj;
uniform float uCanopyHeight;
uniform float uCrownBase;
uniform int uFirstLayer;
#endif
#ifdef GBUFFER
// The deferred geometry pass (ClipmapTerrainRendererGL, TerrainShading::Deferred): where the terrain is, its level-0
// position and footprint derivatives, and its normal's x and y (z > 0 on a heightfield); terrain_resolve.frag then
// shades each pixel once. The derivatives are taken here, in the triangle's own quads, so the resolve filters
// exactly as the forward pass does.
layout(location = 0) out vec4 gPosition;  // p, dFdx(p)
layout(location = 1) out vec4 gFootprint; // dFdy(p), n.xy
#else
out vec4 fragColor;
#endif

void main() {
    if (any(lessThan(vImageUv, vec2(0.0))) || any(greaterThan(vImageUv, vec2(1.0)))) discard;
#if !defined(LEVEL_STATS) && !defined(GBUFFER)
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
    {
        // Level and footprint from this pixel's own position (uniform control flow), used at the hit.
        ClipFootprint fm = clipmapFootprint(p);
        int canopyLevel = vCanopyLevels.x;
        canopyNoteRead(p, canopyLevel); // this pass writes gl_FragDepth: its depth test is late anyway
        vec3 dir = vLocal - uEye;
        vec3 n = normalize(vNormal);
        vec2 grad = n.z > 0.2 ? -n.xy / n.z : vec2(0.0); // terrain slope, metres per metre
        float descent = -dir.z + dot(grad, dir.xy);       // height over the terrain lost per unit of t
        float step = (uCanopyHeight - uCrownBase) / float(max(uCanopyLayers - 1, 1));
        int hit = -1;
        vec3 at = vLocal;
        vec2 pAt = p;
        // Where the ray meets layer i (t along dir; false: it does not come down to that layer).
#define SV_RAY_AT(i, t, q)                                                                                         \
    float drop = float(uCanopyLayers - 1 - (i)) * step; /* below the top layer */                                  \
    if (drop > 0.0 && descent <= 0.0) break;                                                                       \
    float t = drop > 0.0 ? drop / descent : 0.0;                                                                   \
    vec2 q = p + uLocalToPixel * (t * dir.xy) + uLayerShift * float(i);
        // The points the loop may visit lie on a segment, from layer vLayer to uFirstLayer (or at vLayer alone when
        // the ray does not come down); where the canopy's level is derived over all of it, the loop reads that level
        // directly. The two loops below run for their own pixels only: a loop ends once no pixel of the block is in it.
        bool direct;
        {
            int last = descent > 0.0 ? uFirstLayer : vLayer;
            float d0 = float(uCanopyLayers - 1 - vLayer) * step, d1 = float(uCanopyLayers - 1 - last) * step;
            vec2 q0 = p + uLocalToPixel * ((d0 > 0.0 ? d0 / descent : 0.0) * dir.xy) + uLayerShift * float(vLayer);
            vec2 q1 = p + uLocalToPixel * ((d1 > 0.0 ? d1 / descent : 0.0) * dir.xy) + uLayerShift * float(last);
            const float slack = 0.01; // level-0 texels: the loop's own rounding of the points between
            direct = canopyBoxDerived(min(q0, q1) - slack, max(q0, q1) + slack, canopyLevel);
        }
        for (int i = vLayer; direct && i >= uFirstLayer; --i) {
            SV_RAY_AT(i, t, q)
            if (canopyAtDerived(q, canopyLevel) > i) {
                hit = i;
                at = vLocal + t * dir;
                pAt = q;
                break;
            }
        }
        for (int i = vLayer; !direct && i >= uFirstLayer; --i) {
            SV_RAY_AT(i, t, q)
            if (canopyAt(q, canopyLevel) > i) {
                hit = i;
                at = vLocal + t * dir;
                pAt = q;
                break;
            }
        }
#undef SV_RAY_AT
        if (hit < 0) discard;
        vec3 lc = sampleClipmap(0, pAt, fm, used).rgb;
        lc *= mix(uCanopyDark, 1.0, float(hit) / float(max(uCanopyLayers - 1, 1)));
        if (uShade > 0.0) lc *= mix(1.0, 0.25 + 0.75 * max(dot(n, uSunDir), 0.0), uShade);
        vec4 clip = uViewProj * vec4(at, 1.0);
        gl_FragDepth = clip.z / clip.w;
        fragColor = vec4(lc, 1.0);
        return;
    }
#endif
#if defined(CANOPY_LAYER) && !defined(CANOPY_MARCH)
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
    gFootprint = vec4(dFdy(p), normalize(vNormal).xy);
#else
    fragColor = vec4(viewColour(p, f, normalize(vNormal), vLevel, used), 1.0);
#endif
}
