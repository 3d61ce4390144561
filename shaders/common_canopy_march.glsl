// The stacked canopy layers intersected per pixel (foliage/CanopyRendererGL.h, CanopyDrawMode::March; Ropinski et
// al. 2007 §4.2's layers, marched instead of rasterised). The top layer's patches record where each pixel's ray
// enters the stack (terrain_clipmap.frag, variant CANOPY_MARCH); a pass over the whole frame marches from there once
// per pixel: the deferred terrain resolve (terrain_resolve.frag, variant CANOPY_MARCH), or with forward shading
// canopy_march.frag. Marching in the top layer's own fragments ran the loop again in every 4 × 4 block each of its
// small triangles touched (llvmpipe: ten fragment invocations per pixel drawn). From the entry, the ray meets layer i
// where it has come down the height between the two, over the terrain's local plane (its normal); the first layer
// whose canopy it meets there is drawn. Include after common_view.glsl.

uniform sampler2D uEntry;         // p, dFdx(p); p.x < 0: no top layer here
uniform sampler2D uEntryFootprint; // dFdy(p), n.xy
uniform sampler2D uEntryRay;      // the local point the ray enters at, its first layer + 256 × its patch's canopy level
uniform vec3 uEye;                // local metres
uniform mat2 uLocalToPixel;       // d(level-0 pixels) / d(local metres)
uniform mat4 uViewProj;
uniform float uCanopyHeight;
uniform float uCrownBase;
uniform int uFirstLayer;

struct CanopyHit {
    bool entered;     // a top layer was drawn here
    int layer;        // the layer met, -1: none
    vec2 p;           // level-0 texel position of the hit (the layer's shift included)
    vec3 at;          // local metres
    ClipFootprint f;  // the entry's footprint, used at the hit
    vec3 n;           // the terrain's normal at the entry
};

CanopyHit canopyMarchAt(ivec2 pixel) {
    CanopyHit h;
    h.layer = -1;
    vec4 e0 = texelFetch(uEntry, pixel, 0);
    h.entered = e0.x >= 0.0;
    // Straight-line code for every pixel (where no top layer was drawn the values come from the cleared record and
    // are not used: h.layer stays -1); only the loops ask for an entry. llvmpipe runs a branch's or a loop's body
    // for every block whether or not a pixel takes it (docs/performance.md, step 23): wrapping this in one saved
    // nothing.
    vec4 e1 = texelFetch(uEntryFootprint, pixel, 0), e2 = texelFetch(uEntryRay, pixel, 0);
    vec2 p = e0.xy;
    vec3 entry = e2.xyz;
    int layerAndLevel = int(e2.w);
    int firstTested = layerAndLevel & 255, canopyLevel = layerAndLevel >> 8;
    h.f = clipmapFootprintOf(e0.zw, e1.xy); // the entry's level and footprint, used at the hit
    h.n = vec3(e1.zw, sqrt(max(1.0 - dot(e1.zw, e1.zw), 0.0)));
    vec3 dir = entry - uEye;
    vec2 grad = h.n.z > 0.2 ? -h.n.xy / h.n.z : vec2(0.0); // terrain slope, metres per metre
    float descent = -dir.z + dot(grad, dir.xy);             // height over the terrain lost per unit of t
    float step = (uCanopyHeight - uCrownBase) / float(max(uCanopyLayers - 1, 1));
    // The points the loop may visit lie on a segment, from layer firstTested to uFirstLayer (or at firstTested
    // alone when the ray does not come down); where the canopy's level is derived over all of it, the loop reads
    // that level directly (and records nothing: its blocks are derived). Each of the two loops below iterates for
    // its own pixels only.
    int last = descent > 0.0 ? uFirstLayer : firstTested;
    float d0 = float(uCanopyLayers - 1 - firstTested) * step, d1 = float(uCanopyLayers - 1 - last) * step;
    vec2 q0 = p + uLocalToPixel * ((d0 > 0.0 ? d0 / descent : 0.0) * dir.xy) + uLayerShift * float(firstTested);
    vec2 q1 = p + uLocalToPixel * ((d1 > 0.0 ? d1 / descent : 0.0) * dir.xy) + uLayerShift * float(last);
    const float slack = 0.01; // level-0 texels: the loop's own rounding of the points between
    bool direct = canopyBoxDerived(min(q0, q1) - slack, max(q0, q1) + slack, canopyLevel);
    bool fallback = h.entered && !direct;
    direct = h.entered && direct;
    // Where it is derived, the points are linear in the layer: one texel of the level per layer, stepped in its
    // own texels (no division, matrix or level arithmetic per layer).
    float toLevel = exp2(-float(canopyLevel));
    ivec2 lastTexel = ivec2(ceil(uLevel0Size * toLevel)) - 1;
    int lowest = descent > 0.0 ? uFirstLayer : uCanopyLayers - 1; // a level ray meets the top layer alone
    vec2 a = q0 * toLevel;                                          // layer firstTested
    vec2 da = descent > 0.0 ? (uLocalToPixel * ((step / descent) * dir.xy) - uLayerShift) * toLevel : vec2(0.0);
    for (int i = firstTested; direct && i >= lowest; --i) {
        ivec2 t = clamp(ivec2(floor(a + float(firstTested - i) * da)), ivec2(0), lastTexel);
        if (int(texelFetch(uCanopyClip, ivec3(clipTexelOf(t), canopyLevel), 0).r) > i) {
            h.layer = i;
            break;
        }
    }
    // Elsewhere layer by layer down from firstTested, reading each layer's canopy where it is derived (and
    // recording the blocks it falls back past): where the ray meets layer i (t along dir; none below once it
    // does not come down to a layer), and whether the canopy there reaches it.
    for (int i = firstTested; fallback && i >= uFirstLayer; --i) {
        float drop = float(uCanopyLayers - 1 - i) * step; // below the top layer
        if (drop > 0.0 && descent <= 0.0) break;
        float t = drop > 0.0 ? drop / descent : 0.0;
        vec2 q = p + uLocalToPixel * (t * dir.xy) + uLayerShift * float(i);
        if (canopyAtNoting(q, canopyLevel) > i) {
            h.layer = i;
            break;
        }
    }
    // The point met, once, after the loops (where none is, h.layer < 0 says so).
    float drop = float(uCanopyLayers - 1 - max(h.layer, 0)) * step;
    float t = drop > 0.0 ? drop / descent : 0.0;
    h.at = entry + t * dir;
    h.p = p + uLocalToPixel * (t * dir.xy) + uLayerShift * float(max(h.layer, 0));
    return h;
}

// The colour factor of the layer met: darker towards the lowest (self-shadowing inside the crown).
float canopyLayerFactor(int layer) { return mix(uCanopyDark, 1.0, float(layer) / float(max(uCanopyLayers - 1, 1))); }

// The depth of the hit (reversed Z, as the terrain's).
float canopyHitDepth(CanopyHit h) {
    vec4 clip = uViewProj * vec4(h.at, 1.0);
    return clip.z / clip.w;
}
