// Terrain draped with the imagery clipmaps (layer 0 leaf-on, layer 1 leaf-off). Variant LEVEL_STATS writes
// (needed level, used level) / 255 for FrameLevelStats instead of a colour; variant CANOPY_LAYER draws one of the
// stacked canopy layers (Ropinski et al. 2007 §4.2): a fragment stays only where its texel belongs to the layer.
#include "common_clipmap.glsl"
#include "common_canopy.glsl"

uniform sampler2DArray uClip0;
uniform sampler2DArray uClip1;
uniform sampler2D uCoarse0;
uniform sampler2D uCoarse1;
// VIEW (defined by the imagery programs, one per view): ImageryView 0 leafon, 1 leafoff, 2 blend, 3 swipe, 4 lod,
// 5 wireframe, 6 levels, 7 relief, 8 canopy (ground: uCanopyGround[1] under the canopy, uCanopyGround[0] elsewhere).
// A compile-time constant so that each program holds only its view's code: llvmpipe executes every side of a
// branch on a uniform under a mask, and the views' code together cost 2-3x one view (docs/performance.md).
#if !defined(LEVEL_STATS) && !defined(CANOPY_LAYER)
#ifndef VIEW
#error "terrain_clipmap.frag: VIEW must be defined (the ImageryView's number)"
#endif
const int uView = VIEW;
#if VIEW == 3 && !defined(SWIPE_SEASON)
#error "terrain_clipmap.frag: the swipe view's programs define SWIPE_SEASON (0 left, leaf-on; 1 right, leaf-off)"
#elif !defined(SWIPE_SEASON)
#define SWIPE_SEASON 0 // not read: only the swipe view's code uses it
#endif
#endif
uniform int uCanopyGround[2]; // season (0 leaf-on, 1 leaf-off) of the ground away from / under the canopy
uniform int uHasCanopy;
uniform float uCanopyBase;    // > 0: stacked layers are drawn, and the ground draws their lowest one (layer 0, on the
                              // ground): leaf-on times this factor where the canopy is
uniform float uCanopyDark;    // colour factor of the lowest layer (the top one is 1)
uniform vec2 uLayerShift;     // level-0 texels per layer (§4.2: "a slight texture coordinate shift")
uniform int uWirePass;   // wireframe view, second pass: the lines in their level's colour
uniform float uShade;    // 0..1: Lambert shading from the terrain's normals (0 = the orthophoto as it is)
uniform vec3 uSunDir;
uniform float uBlend;
uniform float uSwipeX;   // pixels
uniform vec3 uLevelColors[8];
uniform vec3 uNoDataColour; // where neither season has data (imagery/clipmap texels are premultiplied RGBA)

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
out vec4 fragColor;

// Season s (0 leaf-on, 1 leaf-off) where it has data, the other season where it has none, then uNoDataColour: never
// black. The other season is fetched only where s lacks data.
vec3 seasonColour(int s, vec2 p, ClipFootprint f, out int used) {
    vec4 a = s == 0 ? sampleClipmap(uClip0, uCoarse0, p, f, used) : sampleClipmap(uClip1, uCoarse1, p, f, used);
    if (a.a >= 0.999) return a.rgb;
    int other;
    vec4 b = s == 0 ? sampleClipmap(uClip1, uCoarse1, p, f, other) : sampleClipmap(uClip0, uCoarse0, p, f, other);
    return a.rgb + (1.0 - a.a) * (b.rgb + (1.0 - b.a) * uNoDataColour);
}

void main() {
    if (any(lessThan(vImageUv, vec2(0.0))) || any(greaterThan(vImageUv, vec2(1.0)))) discard;
#ifndef LEVEL_STATS
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
        vec3 dir = vLocal - uEye;
        vec3 n = normalize(vNormal);
        vec2 grad = n.z > 0.2 ? -n.xy / n.z : vec2(0.0); // terrain slope, metres per metre
        float descent = -dir.z + dot(grad, dir.xy);       // height over the terrain lost per unit of t
        float step = (uCanopyHeight - uCrownBase) / float(max(uCanopyLayers - 1, 1));
        int hit = -1;
        vec3 at = vLocal;
        vec2 pAt = p;
        for (int i = vLayer; i >= uFirstLayer; --i) {
            float drop = float(uCanopyLayers - 1 - i) * step; // below the top layer
            if (drop > 0.0 && descent <= 0.0) break;           // the ray does not come down to this layer
            float t = drop > 0.0 ? drop / descent : 0.0;
            vec2 q = p + uLocalToPixel * (t * dir.xy) + uLayerShift * float(i);
            if (canopyAt(q, canopyLevel) > i) {
                hit = i;
                at = vLocal + t * dir;
                pAt = q;
                break;
            }
        }
        if (hit < 0) discard;
        vec3 lc = sampleClipmap(uClip0, uCoarse0, pAt, fm, used).rgb;
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
    vec3 lc = sampleClipmap(uClip0, uCoarse0, p, f, used).rgb;
    lc *= mix(uCanopyDark, 1.0, float(vLayer) / float(max(uCanopyLayers - 1, 1)));
    if (uShade > 0.0) lc *= mix(1.0, 0.25 + 0.75 * max(dot(normalize(vNormal), uSunDir), 0.0), uShade);
    fragColor = vec4(lc, 1.0);
    return;
#elif defined(LEVEL_STATS)
    sampleClipmap(uClip0, uCoarse0, p, f, used);
    float needed = clamp(floor(max(f.lambdaIso, 0.0)), 0.0, 254.0);
    fragColor = vec4(needed / 255.0, float(min(used, 254)) / 255.0, 0.0, 1.0);
#else
    vec3 c;
    if (uView == 7) {
        // Terrain only: grey Lambert shading, no imagery fetched.
        fragColor = vec4(vec3(0.15 + 0.8 * max(dot(normalize(vNormal), uSunDir), 0.0)), 1.0);
        return;
    }
    if (uView == 0) {
        c = seasonColour(0, p, f, used);
    } else if (uView == 1) {
        c = seasonColour(1, p, f, used);
    } else if (uView == 2) {
        int u1;
        c = mix(seasonColour(0, p, f, used), seasonColour(1, p, f, u1), uBlend);
    } else if (uView == 3) {
        // Split screen: leaf-on left of uSwipeX, leaf-off right, a 2-pixel white divider.
        // Drawn in two passes, each scissored to its side: SWIPE_SEASON is this pass's season (a constant, so only
        // its sampling is compiled in).
        if (abs(gl_FragCoord.x - uSwipeX) < 1.0) {
            c = vec3(1.0);
        } else {
            c = seasonColour(SWIPE_SEASON, p, f, used);
        }
    } else if (uView == 8) {
        // The ground of the canopy view: leaf-off under the crowns (the trees stand on it as layers), leaf-on
        // elsewhere; both configurable.
        bool under = uHasCanopy != 0 && canopyAt(p, int(floor(max(f.lambdaIso, 0.0)))) > 0;
        if (under && uCanopyBase > 0.0)
            c = uCanopyBase * seasonColour(0, p, f, used);
        else
            c = seasonColour(uCanopyGround[under ? 1 : 0], p, f, used);
    } else if (uView == 4 || uView == 6) {
        // Level colours over the imagery's brightness: the imagery level used (lod, Ropinski 2007 Fig. 2) or
        // the geometry level drawn (levels).
        vec3 img = seasonColour(0, p, f, used);
        float luma = dot(img, vec3(0.299, 0.587, 0.114));
        c = uLevelColors[min(uView == 4 ? used : vLevel, 7)] * (0.45 + 0.55 * luma);
    } else {
        // Wireframe, first pass: the leaf-on imagery dimmed under the lines.
        c = 0.55 * seasonColour(0, p, f, used);
    }
    if (uShade > 0.0) c *= mix(1.0, 0.25 + 0.75 * max(dot(normalize(vNormal), uSunDir), 0.0), uShade);
    fragColor = vec4(c, 1.0);
#endif
}
