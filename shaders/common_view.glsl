// The colour of one terrain pixel in view VIEW, from its level-0 position p, footprint f and unit normal n: the
// forward pass (terrain_clipmap.frag) and the deferred resolve (terrain_resolve.frag) share it, so both draw the
// same pixels. Include after common_clipmap.glsl and common_canopy.glsl.
// VIEW (defined by the imagery programs, one per view): ImageryView 0 leafon, 1 leafoff, 2 blend, 3 swipe, 4 lod,
// 5 wireframe, 6 levels, 7 relief, 8 canopy (ground: uCanopyGround[1] under the canopy, uCanopyGround[0] elsewhere).
// A compile-time constant so that each program holds only its view's code: llvmpipe executes every side of a
// branch on a uniform under a mask, and the views' code together cost 2-3x one view (docs/performance.md).
#if defined(LEVEL_STATS) || defined(CANOPY_LAYER) || defined(GBUFFER)
#define VIEW 0 // not read: these variants draw no view's colour
#endif
#ifndef VIEW
#error "common_view.glsl: VIEW must be defined (the ImageryView's number)"
#endif
const int uView = VIEW;
#if VIEW == 3 && !defined(SWIPE_SEASON)
#error "common_view.glsl: the swipe view's programs define SWIPE_SEASON (0 left, leaf-on; 1 right, leaf-off)"
#elif !defined(SWIPE_SEASON)
#define SWIPE_SEASON 0 // not read: only the swipe view's code uses it
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

// canopyAt(p, level) that records the canopy blocks it needed and found not derived (foliage/CanopyClipmapGL.h,
// CanopyOptions::onDemand): the block at `level` under p and each coarser one it falls back past, per level and slot
// (the block's tag); update() derives the blocks recorded. A lookup that finds its block derived records nothing (a
// derived block stays derived while it is resident), so a still frame writes next to nothing. Every such lookup
// records: one in 4 × 4 missed blocks that show in a few pixels only, which then stayed at a coarser level.
layout(std430, binding = 3) buffer CanopyReads { int canopyReads[]; };
int canopyAtNoting(vec2 p, int level) {
    for (int l = max(level, 0); l < uClipLevels; ++l) {
        float s = exp2(float(l));
        ivec2 q = clamp(ivec2(floor(p / s)), ivec2(0), ivec2(ceil(uLevel0Size / s)) - 1);
        if (canopyBlockValid(l, q)) return int(texelFetch(uCanopyClip, ivec3(clipTexelOf(q), l), 0).r);
        ivec2 b = clipBlockOf(q);
        ivec2 slot = clipSlotOf(b);
        canopyReads[(l * uSlotsPerSide + slot.y) * uSlotsPerSide + slot.x] = b.x | (b.y << 16);
    }
    float s = exp2(float(uClipLevels));
    ivec2 q = clamp(ivec2(floor(p / s)), ivec2(0), ivec2(uCoarseSize) - 1);
    return int(texelFetch(uCanopyCoarse, q, 0).r);
}

// Season s (0 leaf-on, 1 leaf-off) where it has data, the other season where it has none, then uNoDataColour: never
// black. The other season is fetched only where s lacks data. seasonColourOf: the same from s's sample `a` at p.
vec3 seasonColourOf(vec4 a, int s, vec2 p, ClipFootprint f) {
#ifdef SEASONS_COMPLETE
    // Both seasons are read as they are, on the working grid, with no pixel marked nodata (ImageryLayer::direct):
    // no other season to fall back on, and llvmpipe would run that sampling under a mask for every pixel.
    return a.rgb;
#endif
    if (a.a >= 0.999) return a.rgb;
    int other;
    vec4 b = sampleClipmap(1 - s, p, f, other);
    return a.rgb + (1.0 - a.a) * (b.rgb + (1.0 - b.a) * uNoDataColour);
}
vec3 seasonColour(int s, vec2 p, ClipFootprint f, out int used) {
    return seasonColourOf(sampleClipmap(s, p, f, used), s, p, f);
}

// Lambert shading of a colour by normal n (uShade 0: none).
vec3 shaded(vec3 c, vec3 n) {
    if (uShade > 0.0) c *= mix(1.0, 0.25 + 0.75 * max(dot(n, uSunDir), 0.0), uShade);
    return c;
}

// `level`: the geometry level drawn (the levels view's colour); `used` receives the imagery level used.
vec3 viewColour(vec2 p, ClipFootprint f, vec3 n, int level, out int used) {
    used = 0;
    // Terrain only: grey Lambert shading, no imagery fetched.
    if (uView == 7) return vec3(0.15 + 0.8 * max(dot(n, uSunDir), 0.0));
    vec3 c;
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
        int canopyLevel = int(floor(max(f.lambdaIso, 0.0)));
        bool under = uHasCanopy != 0 && canopyAtNoting(p, canopyLevel) > 0;
        // One seasonColour call: the season is per-pixel data here, a layer index into the one array both seasons
        // share (common_clipmap.glsl), so only the season shown is sampled.
        bool base = under && uCanopyBase > 0.0;
        c = (base ? uCanopyBase : 1.0) * seasonColour(base ? 0 : uCanopyGround[under ? 1 : 0], p, f, used);
    } else if (uView == 4 || uView == 6) {
        // Level colours over the imagery's brightness: the imagery level used (lod, Ropinski 2007 Fig. 2) or
        // the geometry level drawn (levels).
        vec3 img = seasonColour(0, p, f, used);
        float luma = dot(img, vec3(0.299, 0.587, 0.114));
        c = uLevelColors[min(uView == 4 ? used : level, 7)] * (0.45 + 0.55 * luma);
    } else {
        // Wireframe, first pass: the leaf-on imagery dimmed under the lines.
        c = 0.55 * seasonColour(0, p, f, used);
    }
    return shaded(c, n);
}
