// Roofs textured from the terrain's imagery clipmap (Buchholz's thesis §4.8.2), as the terrain's view shows it: the
// season shown, the two blended, or split at the swipe line, a season without data there filled from the other, then
// with the roof's plain colour. For city_building.frag's ROOF and blockmap.frag's ROOF_IMAGERY; include after
// common_clipmap.glsl. Variants: ROOF_BLEND (the blend view: both seasons; otherwise uBlend is not read),
// SEASONS_COMPLETE (both seasons read as they are with no nodata, as the terrain's: no other season to fall back on).
// Chosen at compile time: sampling both seasons and choosing after cost every roof pixel both samplings, and on
// llvmpipe a branch on the pixel's own data around the second sampling did not save it (docs/performance.md, 22).
uniform int uSeason;    // 0 leaf-on, 1 leaf-off
uniform float uBlend;   // ROOF_BLEND: leaf-on mixed with leaf-off by this much
uniform float uSwipeX;  // >= 0, pixels: leaf-on left of it, leaf-off right, a 2-pixel white divider (swipe view)

// The roof's colour at image point p (level-0 texels) with footprint f. Premultiplied imagery.
vec3 roofImagery(vec2 p, ClipFootprint f, vec3 plainColour) {
    if (uSwipeX >= 0.0 && abs(gl_FragCoord.x - uSwipeX) < 1.0) return vec3(1.0);
    int used;
#ifdef ROOF_BLEND
    vec4 on = sampleClipmap(0, p, f, used), off = sampleClipmap(1, p, f, used);
    vec3 onFilled = on.rgb + (1.0 - on.a) * (off.rgb + (1.0 - off.a) * plainColour);
    vec3 offFilled = off.rgb + (1.0 - off.a) * (on.rgb + (1.0 - on.a) * plainColour);
    return mix(onFilled, offFilled, uBlend);
#else
    int s = uSwipeX >= 0.0 ? (gl_FragCoord.x < uSwipeX ? 0 : 1) : uSeason;
    vec4 a = sampleClipmap(s, p, f, used);
#ifdef SEASONS_COMPLETE
    return a.rgb; // alpha 1 everywhere
#else
    vec4 b = sampleClipmap(1 - s, p, f, used);
    return a.rgb + (1.0 - a.a) * (b.rgb + (1.0 - b.a) * plainColour);
#endif
#endif
}
