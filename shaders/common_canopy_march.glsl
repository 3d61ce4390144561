// The stacked canopy layers intersected per pixel (foliage/CanopyRendererGL.h, CanopyDrawMode::March; Ropinski et
// al. 2007 §4.2's layers, marched instead of rasterised). The top layer's patches record, at half the frame's
// resolution in each axis, the point and plane where the rays enter the stack (terrain_clipmap.frag, variant
// CANOPY_MARCH); a pass over the whole frame marches from there once per pixel: the deferred terrain resolve
// (terrain_resolve.frag, variant CANOPY_MARCH), or with forward shading canopy_march.frag. Each pixel intersects its
// own ray with the plane of the record's texel it lies in (the top layer's triangle there), which gives its entry
// and the entry's screen derivatives exactly where that triangle covers the pixel (a quarter of the record's fragments
// and clears; docs/performance.md). Marching in the top layer's own fragments ran the loop again in every 4 × 4 block
// each of its small triangles touched (llvmpipe: ten fragment invocations per pixel drawn). From the entry, the ray
// meets layer i where it has come down the height between the two, over the terrain's local plane (its normal); the
// first layer whose canopy it meets there is drawn. Include after common_view.glsl.

const int kCanopyEntryScale = 2;  // frame pixels per record texel along each axis (CanopyRendererGL::kEntryScale)
uniform sampler2D uEntry;         // p, the top layer's unit normal xy (its plane); p.x < 0: no top layer here
uniform sampler2D uEntryRay;      // the local point the record's ray enters at, first layer + 256 × canopy level
// The view ray's local direction through window point (x, y): uRay0 + x uRayDx + y uRayDy.
uniform vec3 uRay0, uRayDx, uRayDy;
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
    vec2 dx, dy;      // the entry's screen derivatives of p (its footprint, used at the hit)
    vec3 n;           // the terrain's normal at the entry
};

// Whether the record has a top layer under frame pixel `pixel` (canopy_march.frag skips the others).
bool canopyEntryRecorded(ivec2 pixel) { return texelFetch(uEntry, pixel / kCanopyEntryScale, 0).x >= 0.0; }

CanopyHit canopyMarchAt(ivec2 pixel) {
    CanopyHit h;
    h.layer = -1;
    ivec2 rec = pixel / kCanopyEntryScale;
    vec4 e0 = texelFetch(uEntry, rec, 0), e1 = texelFetch(uEntryRay, rec, 0);
    // Straight-line code for every pixel (where no top layer was drawn the values come from the cleared record and
    // are not used: h.layer stays -1); only the loops ask for an entry. llvmpipe runs a branch's or a loop's body
    // for every block whether or not a pixel takes it (docs/performance.md, step 23): wrapping this in one saved
    // nothing.
    h.n = vec3(e0.zw, sqrt(max(1.0 - dot(e0.zw, e0.zw), 0.0)));
    // This pixel's ray and its neighbours' (one pixel on in x and in y) met with the record texel's plane: the eye is
    // above it (the patches marched see their top from above), so rays that come down meet it at t > 0.
    vec3 ray = uRay0 + (float(pixel.x) + 0.5) * uRayDx + (float(pixel.y) + 0.5) * uRayDy;
    float below = dot(h.n, e1.xyz - uEye); // < 0
    float down = dot(h.n, ray);
    float dn = min(down, -1e-20), dnx = min(dot(h.n, ray + uRayDx), -1e-20), dny = min(dot(h.n, ray + uRayDy), -1e-20);
    h.entered = e0.x >= 0.0 && down < 0.0;
    vec3 entry = uEye + (below / dn) * ray;
    vec2 entryXy = entry.xy;
    vec2 p = e0.xy + uLocalToPixel * (entryXy - e1.xy);
    h.dx = uLocalToPixel * ((uEye.xy + (below / dnx) * (ray.xy + uRayDx.xy)) - entryXy);
    h.dy = uLocalToPixel * ((uEye.xy + (below / dny) * (ray.xy + uRayDy.xy)) - entryXy);
    int layerAndLevel = int(e1.w);
    int firstTested = layerAndLevel & 255, canopyLevel = layerAndLevel >> 8;
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
