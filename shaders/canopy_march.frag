// The stacked canopy layers intersected per pixel (foliage/CanopyRendererGL.h, CanopyDrawMode::March; Ropinski et
// al. 2007 §4.2's layers, marched instead of rasterised), once per pixel in a pass over the whole frame
// (terrain_resolve.vert). The top layer's patches recorded where each pixel's ray enters the stack
// (terrain_clipmap.frag, variant CANOPY_MARCH): marching in their own fragments ran the loop again in every 4 × 4
// block each of their small triangles touched (llvmpipe: ten fragment invocations per pixel drawn). From the entry,
// the ray meets layer i where it has come down the height between the two, over the terrain's local plane (its
// normal); the first layer whose canopy it meets there is drawn, with its depth. A ray that meets none leaves the
// frame as it was (alpha 0 over blending, the far depth): the terrain drawn next shows there.
#include "common_clipmap.glsl"
#include "common_canopy.glsl"
#include "common_view.glsl"

uniform sampler2D uEntry;     // p, dFdx(p); p.x < 0: no top layer here
uniform sampler2D uFootprint; // dFdy(p), n.xy
uniform sampler2D uRay;       // the local point the ray enters at, its first layer + 256 × its patch's canopy level
uniform vec3 uEye;            // local metres
uniform mat2 uLocalToPixel;   // d(level-0 pixels) / d(local metres)
uniform mat4 uViewProj;
uniform float uCanopyHeight;
uniform float uCrownBase;
uniform int uFirstLayer;
out vec4 fragColor;

void main() {
    ivec2 pixel = ivec2(gl_FragCoord.xy);
    vec4 e0 = texelFetch(uEntry, pixel, 0);
    if (e0.x < 0.0) discard;
    vec4 e1 = texelFetch(uFootprint, pixel, 0), e2 = texelFetch(uRay, pixel, 0);
    vec2 p = e0.xy;
    vec3 entry = e2.xyz;
    int layerAndLevel = int(e2.w);
    int firstTested = layerAndLevel & 255, canopyLevel = layerAndLevel >> 8;
    // Level and footprint from the entry's own derivatives, used at the hit.
    ClipFootprint fm = clipmapFootprintOf(e0.zw, e1.xy);
    vec3 dir = entry - uEye;
    vec3 n = vec3(e1.zw, sqrt(max(1.0 - dot(e1.zw, e1.zw), 0.0)));
    vec2 grad = n.z > 0.2 ? -n.xy / n.z : vec2(0.0); // terrain slope, metres per metre
    float descent = -dir.z + dot(grad, dir.xy);       // height over the terrain lost per unit of t
    float step = (uCanopyHeight - uCrownBase) / float(max(uCanopyLayers - 1, 1));
    int hit = -1;
    vec3 at = entry;
    vec2 pAt = p;
    // Where the ray meets layer i (t along dir; break: it does not come down to that layer).
#define SV_RAY_AT(i, t, q)                                                                                         \
    float drop = float(uCanopyLayers - 1 - (i)) * step; /* below the top layer */                                  \
    if (drop > 0.0 && descent <= 0.0) break;                                                                       \
    float t = drop > 0.0 ? drop / descent : 0.0;                                                                   \
    vec2 q = p + uLocalToPixel * (t * dir.xy) + uLayerShift * float(i);
    // The points the loop may visit lie on a segment, from layer firstTested to uFirstLayer (or at firstTested alone
    // when the ray does not come down); where the canopy's level is derived over all of it, the loop reads that level
    // directly (and records nothing: its blocks are derived). The two loops below run for their own pixels only: a loop
    // ends once no pixel of the block is in it.
    bool direct;
    {
        int last = descent > 0.0 ? uFirstLayer : firstTested;
        float d0 = float(uCanopyLayers - 1 - firstTested) * step, d1 = float(uCanopyLayers - 1 - last) * step;
        vec2 q0 = p + uLocalToPixel * ((d0 > 0.0 ? d0 / descent : 0.0) * dir.xy) + uLayerShift * float(firstTested);
        vec2 q1 = p + uLocalToPixel * ((d1 > 0.0 ? d1 / descent : 0.0) * dir.xy) + uLayerShift * float(last);
        const float slack = 0.01; // level-0 texels: the loop's own rounding of the points between
        direct = canopyBoxDerived(min(q0, q1) - slack, max(q0, q1) + slack, canopyLevel);
    }
    for (int i = firstTested; direct && i >= uFirstLayer; --i) {
        SV_RAY_AT(i, t, q)
        if (canopyAtDerived(q, canopyLevel) > i) {
            hit = i;
            at = entry + t * dir;
            pAt = q;
            break;
        }
    }
    for (int i = firstTested; !direct && i >= uFirstLayer; --i) {
        SV_RAY_AT(i, t, q)
        if (canopyAtNoting(q, canopyLevel) > i) {
            hit = i;
            at = entry + t * dir;
            pAt = q;
            break;
        }
    }
#undef SV_RAY_AT
    if (hit < 0) {
        gl_FragDepth = 0.0; // reversed Z: far, as cleared
        fragColor = vec4(0.0);
        return;
    }
    int used;
    vec3 lc = sampleClipmap(0, pAt, fm, used).rgb;
    lc *= mix(uCanopyDark, 1.0, float(hit) / float(max(uCanopyLayers - 1, 1)));
    if (uShade > 0.0) lc *= mix(1.0, 0.25 + 0.75 * max(dot(n, uSunDir), 0.0), uShade);
    vec4 clip = uViewProj * vec4(at, 1.0);
    gl_FragDepth = clip.z / clip.w;
    fragColor = vec4(lc, 1.0);
}
