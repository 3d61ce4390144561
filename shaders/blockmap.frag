// A BlockMap ray-cast per pixel (city/BlockMapGL.h; Cignoni et al. 2007 §3.2), the GPU copy of city/BlockMap.cpp's
// traceBlockMap: from where the pixel's ray enters the block's box, texel by texel over the height map (a DDA), a
// texel's prism (its part of the texel, from its foot to its top) hit where the ray enters it (a wall through a side,
// a roof through its top), leaping over empty texels with the distance map to the edge of the empty square it
// guarantees.
// Writes the hit's colour and depth (reversed Z, as the terrain's), so it composes with everything else drawn; a ray
// that meets no prism is discarded (the terrain under the block shows). Positions relative to the block's origin.
// Variant ROOF_IMAGERY: roofs show the terrain's imagery clipmap at the hit's position, as the polygon roofs do
// (city_building.frag's ROOF: the season shown, the blend, the swipe), else one colour.
// Variant FRONT_FACES: drawn over the box's front faces (the eye outside the box): the hit is never nearer than the
// face, so the depth written is at most the face's (reversed Z) and a face already hidden is rejected before the ray
// is cast (ARB_conservative_depth).
#ifdef FRONT_FACES
layout(depth_less) out float gl_FragDepth;
#endif
#ifdef ROOF_IMAGERY
#include "common_clipmap.glsl"
#include "common_roof.glsl" // its variants ROOF_BLEND, SEASONS_COMPLETE
uniform int uHasImagery;
uniform sampler2D uLocalToImage; // RG32F: local -> leaf-on image coordinates in [0,1]
uniform vec2 uLookupMin, uLookupSize;
uniform float uLookupTexels;
uniform mat2 uLookupSlope;
#endif
#include "common_blockmap.glsl"
// Per texel of a map's tile (n² texels from its first, row by row; city/BlockMap.h's BlockMapPacked::tile): x: its
// height in the low 16 bits (0 no building, else zBase + value · (zTop − zBase) / 65535), then a byte each the roof's
// normal's x and y ((v + 1) / 2 · 255; z implied); y: 1 + a boundary texel's wall column (24 bits) and in the top
// byte the Chebyshev distance in texels to the nearest building texel; z: the part of the texel the prism stands on
// (BlockMap::rect: x0 | x1 << 4 | y0 << 8 | y1 << 12, sixteenths), and in the high 16 bits a second prism's
// (BlockMap::rect2) where the texel has one; w: the prism's foot (the low 16 bits, as heights: a ray below it passes
// under the prism) and the second prism's top (the high 16 bits, 0: none; BlockMap::height2).
uniform usamplerBuffer uBmTexels;
// A map's words from its first: its columns' outward normals ((n + 1) / 2, RGB8; A: 1 for walls along the grid),
// then each column's colours (RGBA8, span words): its wallTexels colours (the lowest first), then the same halved
// again and again down to one (level l has (W_{l-1} + 1) / 2, 2×1 box means), for filtering. They lie in pages of 2^BM_PAGE_BITS words anywhere in the
// buffer (city/BlockMapGL.h): the map's first page starts with its page table, a word per page, then its words.
uniform usamplerBuffer uBmWords;
#ifndef BM_PAGE_BITS // log2 of city/BlockMap.h's kBlockMapPageWords (BlockMapPoolGL::buildProgram)
#error "blockmap.frag: BM_PAGE_BITS must be defined"
#endif
uniform float uPixelAngle;      // radians per pixel at the centre of the screen (1 / focal length in pixels)
uniform vec3 uEye;              // local metres
uniform mat4 uViewProj;
uniform vec3 uRoofColour;       // roofs (the renderer textures them from the terrain imagery)
uniform vec3 uSunDir;
// Output what was hit instead of a colour (the tests): (kind, 0, 0, 1) with kind 0.5 a roof, 1 a wall.
uniform int uOutputKind;

in vec3 vWorld;
flat in int vMap;
out vec4 fragColor;

// The map drawn (its record: common_blockmap.glsl), set first in main().
vec2 bmOrigin = vec2(0.0);
float bmMetres = 1.0, bmZBase = 0.0, bmZTop = 1.0; // metres per texel, the height range
int bmTile = 0; // the map's first texel in uBmTexels
int bmFirstWord = 0, bmWallTexels = 1, bmSpan = 1, bmColumns = 0; // bmFirstWord: the words' first after the page table
int bmFirstPage = 0;

// Word w of the map (counted from its page table's first): its page through the table, in the first page.
uint bmWord(int w) {
    int page = w >> BM_PAGE_BITS;
    int at = page == 0 ? bmFirstPage : int(texelFetch(uBmWords, (bmFirstPage << BM_PAGE_BITS) + page).r);
    return texelFetch(uBmWords, (at << BM_PAGE_BITS) + (w & ((1 << BM_PAGE_BITS) - 1))).r;
}

uvec4 bmTexelAt(ivec2 c) {
    uint w = texelFetch(uBmTexels, bmTile + c.y * uBmSize + c.x).x;
    return uvec4(w & 255u, (w >> 8) & 255u, (w >> 16) & 255u, w >> 24);
}
// Texel `c`'s words for the traversal (one fetch): its height and roof normal (x: bmTexelAt's bytes 2 and 3 the
// normal), its column and distance (y), its prisms' parts (z), its foot and second prism's top (w).
uvec4 bmStepAt(ivec2 c) { return texelFetch(uBmTexels, bmTile + c.y * uBmSize + c.x); }

// The roof's normal from its stored x and y (city/BlockMap.h, BlockMap::roofNormalAt: within 0.005 of 0 is 0).
vec3 bmNormalOf(uvec2 xy) {
    vec2 rn = vec2(xy) / 255.0 * 2.0 - 1.0;
    rn = mix(rn, vec2(0.0), lessThan(abs(rn), vec2(0.005)));
    return vec3(rn, sqrt(max(1.0 - dot(rn, rn), 1e-6)));
}
// The slope of the roof plane of the texel whose first word is `w` (dz/dx, dz/dy).
vec2 bmRoofSlope(uint w) {
    vec3 n = bmNormalOf(uvec2((w >> 16) & 255u, w >> 24));
    return -n.xy / n.z;
}

const int kNone = 0, kRoof = 1, kWall = 2;

// Column `column`'s colour at height v (0 foot, 1 top) at level `level` of its halved levels, linear between texels.
vec4 bmWallAt(int column, float v, int level) {
    int size = bmWallTexels, offset = 0;
    for (int l = 0; l < level && size > 1; ++l) {
        offset += size;
        size = (size + 1) / 2;
    }
    float x = clamp(v * float(size) - 0.5, 0.0, float(size - 1));
    int j0 = int(floor(x)), j1 = min(j0 + 1, size - 1);
    int base = bmFirstWord + bmColumns + column * bmSpan + offset;
    return mix(unpackUnorm4x8(bmWord(base + j0)), unpackUnorm4x8(bmWord(base + j1)), x - float(j0));
}

// The roof's normal over texel `c`.
vec3 bmRoofNormal(ivec2 c) { return bmNormalOf(bmTexelAt(c).ba); }

#ifdef ROOF_IMAGERY
// The local -> image lookup as city_building.vert does it per vertex, here per pixel.
vec2 bmImageUv(vec2 world) {
    vec2 t = (world - uLookupMin) / uLookupSize;
    vec2 tc = clamp(t, 0.0, 1.0);
    return textureLod(uLocalToImage, (tc * (uLookupTexels - 1.0) + 0.5) / uLookupTexels, 0.0).xy +
           uLookupSlope * (t - tc);
}
#endif

// The ray's direction's derivatives across the screen (dFdx, dFdy of vWorld - uEye), taken in main() before any
// branch: the box's faces are planes, so they hold at every pixel of its quad.
vec3 bmRayDx = vec3(0.0), bmRayDy = vec3(0.0);

// The roof at `hit` (relative to the map's origin; the ray o + t·d met it at t), of normal `n` (its texel's): the
// terrain's imagery there (ROOF_IMAGERY, as the polygon roofs show it, unlit), else one colour lit by `n`. The
// imagery is filtered over the pixel's footprint on the roof's plane, from where the neighbouring pixels' rays meet
// that plane, as a rasteriser's derivatives are a polygon's: the hits' own derivatives jump at a roof's edge (a
// neighbour's ray meets a wall, the ground or nothing), which took the whole roof's edge to a coarse level of the
// imagery, blended with the street around the building.
vec3 bmRoof(vec3 hit, vec3 d, float t, vec3 n) {
#ifdef ROOF_IMAGERY
    if (uHasImagery != 0) {
        vec2 world = hit.xy + bmOrigin;
        vec2 imageUv = bmImageUv(world);
        if (all(greaterThanEqual(imageUv, vec2(0.0))) && all(lessThanEqual(imageUv, vec2(1.0)))) {
            // hit(x) = o + t(x)·d(x) with n·(hit - plane point) = 0: dhit = t·(dd - d·(n·dd)/(n·d)).
            float nd = dot(n, d);
            nd = abs(nd) > 1e-12 ? nd : -1e-12;
            vec3 hx = t * (bmRayDx - d * dot(n, bmRayDx) / nd), hy = t * (bmRayDy - d * dot(n, bmRayDy) / nd);
            vec2 px = (bmImageUv(world + hx.xy) - imageUv) * uLevel0Size;
            vec2 py = (bmImageUv(world + hy.xy) - imageUv) * uLevel0Size;
            return roofImagery(imageUv * uLevel0Size, clipmapFootprintOf(px, py), uRoofColour);
        }
    }
#endif
    return uRoofColour * (0.62 + 0.38 * abs(dot(n, uSunDir)));
}

float bmTop(uint value) { return bmZBase + float(value) * (bmZTop - bmZBase) / 65535.0; }
bool bmOutside(ivec2 c) { return any(lessThan(c, ivec2(0))) || any(greaterThanEqual(c, ivec2(uBmSize))); }

void main() {
    BmMap m = bmMaps[vMap];
    bmOrigin = m.geo.xy;
    bmMetres = m.geo.z;
    bmZBase = m.geo.w;
    bmZTop = m.z.x;
    bmTile = m.tile.z;
    bmFirstWord = m.tile.w;
    bmWallTexels = m.wall.x;
    bmSpan = m.wall.y;
    bmColumns = m.wall.z;
    bmFirstPage = m.wall.w;
    bmRayDx = dFdx(vWorld);
    bmRayDy = dFdy(vWorld);
    vec3 o = vec3(uEye.xy - bmOrigin, uEye.z);
    vec3 d = vWorld - uEye;
    // No component exactly 0 (the slabs divide by them); a nudge far below a texel.
    d = mix(d, vec3(1e-12), equal(d, vec3(0.0)));
    float side = float(uBmSize) * bmMetres;
    vec3 ta = (vec3(0.0, 0.0, bmZBase) - o) / d, tb = (vec3(side, side, bmZTop) - o) / d;
    vec3 tmin = min(ta, tb), tmax = max(ta, tb);
    float t0 = max(max(tmin.x, tmin.y), max(tmin.z, 0.0)), t1 = min(min(tmax.x, tmax.y), tmax.z);
    if (t0 > t1) discard;
    int enterAxis = t0 == 0.0 ? -1 : t0 == tmin.x ? 0 : t0 == tmin.y ? 1 : 2;
    if (enterAxis == 2 && d.z > 0.0) discard; // from under the block's floor
    ivec2 stp = ivec2(d.x > 0.0 ? 1 : -1, d.y > 0.0 ? 1 : -1);
    ivec2 up = max(stp, ivec2(0));
    vec2 delta = bmMetres / abs(d.xy);
    ivec2 c = clamp(ivec2(floor((o.xy + t0 * d.xy) / bmMetres)), ivec2(0), ivec2(uBmSize - 1));
    int face = enterAxis == 0 ? (stp.x > 0 ? 0 : 1) : enterAxis == 1 ? (stp.y > 0 ? 2 : 3) : enterAxis == 2 ? 4 : -1;
    vec2 nextT = (vec2(c + up) * bmMetres - o.xy) / d.xy;
    float tCell = t0;
    int kind = kNone;
    float tHit = 0.0;
    float top = 0.0;
    for (int it = 0; it < 4 * uBmSize + 8 && kind == kNone; ++it) {
        float tOut = min(min(nextT.x, nextT.y), t1);
        uvec4 texel = bmStepAt(c);
        uint value = texel.x & 0xFFFFu, second = texel.w >> 16;
        if (value > 0u) {
            float foot = bmTop(texel.w & 0xFFFFu);
            // A ray above the texel's highest roof point all through it (over the roofs, the rooftop band's grazing
            // rays) meets nothing there: on to the next texel without the prisms' tests.
            vec2 slope = bmRoofSlope(texel.x);
            float highest = max(bmTop(value) + 0.5 * bmMetres * (abs(slope.x) + abs(slope.y)), bmTop(second));
            if (min(o.z + tCell * d.z, o.z + tOut * d.z) <= highest) {
                // The ray against each prism's box in the texel (the second's where it has one): a part's sides
                // bound it where they lie inside the texel (a whole texel: the texel's, where the ray is already),
                // then its foot and top. axis: that of the face it enters by, -1 the one it entered the texel by. The
                // nearest prism entered counts.
                float tBest = 1e30;
                int axisBest = -1;
                for (int k = 0; k < (second > 0u ? 2 : 1); ++k) {
                    uint part = k == 0 ? texel.z & 0xFFFFu : texel.z >> 16;
                    float prismTop = bmTop(k == 0 ? value : second);
                    vec2 lo = vec2(part & 15u, (part >> 8) & 15u) / 16.0;
                    vec2 hi = vec2(((part >> 4) & 15u) + 1u, ((part >> 12) & 15u) + 1u) / 16.0;
                    float tEnter = tCell, tExit = tOut;
                    int axis = -1;
                    for (int a = 0; a < 2; ++a) {
                        bool inc = d[a] > 0.0;
                        float enterBound = inc ? lo[a] : hi[a], exitBound = inc ? hi[a] : lo[a];
                        if (enterBound > 0.0 && enterBound < 1.0) {
                            float t = ((float(c[a]) + enterBound) * bmMetres - o[a]) / d[a];
                            if (t > tEnter) {
                                tEnter = t;
                                axis = a;
                            }
                        }
                        if (exitBound > 0.0 && exitBound < 1.0)
                            tExit = min(tExit, ((float(c[a]) + exitBound) * bmMetres - o[a]) / d[a]);
                    }
                    // The foot (up through it: axis 3), then the top: the roof's plane through prismTop at the
                    // texel's centre (the second prism's level), z <= prismTop + slope · (p - centre), entered through
                    // it a roof.
                    float tFoot = (foot - o.z) / d.z;
                    if (d.z > 0.0 && tFoot > tEnter) {
                        tEnter = tFoot;
                        axis = 3;
                    }
                    if (d.z < 0.0) tExit = min(tExit, tFoot);
                    vec2 planeSlope = k == 0 ? slope : vec2(0.0);
                    float num = prismTop + dot(planeSlope, o.xy - (vec2(c) + 0.5) * bmMetres) - o.z;
                    float den = d.z - dot(planeSlope, d.xy);
                    if (den < 0.0 && num / den > tEnter) {
                        tEnter = num / den;
                        axis = 2;
                    }
                    if (den > 0.0) tExit = min(tExit, num / den);
                    if (den == 0.0 && num < 0.0) tExit = -1e30;
                    if (tEnter <= tExit && tEnter < tBest) {
                        tBest = tEnter;
                        axisBest = axis;
                        top = prismTop;
                    }
                }
                if (tBest < 1e30) {
                    // Rising into a prism from below its foot (from under the ground) the ray meets nothing; below it,
                    // it passes under the prism (in the ground there).
                    if (axisBest == 3) break;
                    if (axisBest == 0) face = stp.x > 0 ? 0 : 1;
                    else if (axisBest == 1) face = stp.y > 0 ? 2 : 3;
                    else if (axisBest == 2) face = 4;
                    kind = face == 4 ? kRoof : kWall;
                    tHit = tBest;
                    break;
                }
            }
        } else {
            int r = int(texel.y >> 24) - 1; // the distance
            if (r >= 1) {
                // Every texel within r of this one is empty: on to where the ray leaves that square.
                vec2 ex = (vec2(c + stp * r + up) * bmMetres - o.xy) / d.xy;
                float tExit = min(ex.x, ex.y);
                if (tExit >= t1) break;
                if (ex.x <= ex.y) {
                    int y = clamp(int(floor((o.y + tExit * d.y) / bmMetres)), c.y - r, c.y + r);
                    c = ivec2(c.x + stp.x * (r + 1), y);
                    face = stp.x > 0 ? 0 : 1;
                } else {
                    int x = clamp(int(floor((o.x + tExit * d.x) / bmMetres)), c.x - r, c.x + r);
                    c = ivec2(x, c.y + stp.y * (r + 1));
                    face = stp.y > 0 ? 2 : 3;
                }
                if (bmOutside(c)) break;
                tCell = tExit;
                nextT = (vec2(c + up) * bmMetres - o.xy) / d.xy;
                continue;
            }
        }
        if (tOut >= t1) break;
        if (nextT.x <= nextT.y) {
            c.x += stp.x;
            tCell = nextT.x;
            nextT.x += delta.x;
            face = stp.x > 0 ? 0 : 1;
        } else {
            c.y += stp.y;
            tCell = nextT.y;
            nextT.y += delta.y;
            face = stp.y > 0 ? 2 : 3;
        }
        if (bmOutside(c)) break;
    }
    if (kind == kNone) discard;
    vec3 hit = o + tHit * d;
    vec4 clip = uViewProj * vec4(hit.xy + bmOrigin, hit.z, 1.0);
    gl_FragDepth = clip.z / clip.w;
    if (uOutputKind != 0) {
        fragColor = vec4(kind == kRoof ? 0.5 : 1.0, 0.0, 0.0, 1.0);
        return;
    }
    // A wall's colour and how much of it is wall (the rest: the steps of a sloped roof, drawn as roof).
    float wallShare = 0.0;
    vec3 wall = vec3(0.0);
    vec3 roofNormal = bmRoofNormal(c), faceNormal = roofNormal;
    if (kind == kWall) {
        int column = max(int(texelFetch(uBmTexels, bmTile + c.y * uBmSize + c.x).y & 0xFFFFFFu) - 1, 0);
        float v = clamp((hit.z - bmZBase) / max(top - bmZBase, 1e-6), 0.0, 1.0);
        // The wall texels a pixel spans vertically: filtered from the column's halved levels (trilinear), so a
        // far facade shows its mean, not a few of its texels. Seen from above or below at an elevation e, a pixel
        // spans 1 / cos e times its width up a vertical wall, whichever way the wall faces (cos e floored at 1/4).
        float metresPerPixel = tHit * length(d) * uPixelAngle;
        float dz = d.z / length(d);
        metresPerPixel /= sqrt(max(1.0 - dz * dz, 0.0625));
        float lod = log2(max(1.0, float(bmWallTexels) / max(top - bmZBase, 1e-3) * metresPerPixel));
        int l0 = int(floor(lod));
        vec4 w = mix(bmWallAt(column, v, l0), bmWallAt(column, v, l0 + 1), fract(lod));
        uint normalWord = bmWord(bmFirstWord + column);
        vec3 n = unpackUnorm4x8(normalWord).xyz * 2.0 - 1.0;
        // Walls along the grid: shaded by the side the ray came in by (a corner's two walls each by its own).
        bool onGrid = (normalWord >> 24) != 0u && face >= 0 && face < 4;
        if (onGrid)
            n = face == 0 ? vec3(-1.0, 0.0, 0.0) : face == 1 ? vec3(1.0, 0.0, 0.0) : face == 2 ? vec3(0.0, -1.0, 0.0)
                                                                                           : vec3(0.0, 1.0, 0.0);
        // Along a wall on the grid, linear between this column and the next one along the wall the hit is nearer
        // to, where that texel's same side is a wall at this height: the paper lays a building's columns side by
        // side along its outline, so its texture lookup interpolates between neighbouring columns (Cignoni et al.
        // 2007 §3.3); here each column is a texel's, so its neighbour is found in the height map. Walls at an angle
        // to the grid keep their own column's colour.
        if (onGrid) {
            int along = face < 2 ? 1 : 0;
            float f = hit[along] / bmMetres - float(c[along]) - 0.5;
            ivec2 next = c;
            next[along] += f < 0.0 ? -1 : 1;
            ivec2 outward = ivec2(n.xy);
            if (!bmOutside(next)) {
                uvec4 tn = bmStepAt(next);
                int nextColumn = int(tn.y & 0xFFFFFFu) - 1;
                float nextTop = bmTop(tn.x & 0xFFFFu);
                bool exposed = true; // the next texel's side: nothing in front of it as high as the hit
                ivec2 front = next + outward;
                if (!bmOutside(front)) {
                    uint h = bmStepAt(front).x & 0xFFFFu;
                    exposed = h == 0u || bmTop(h) < hit.z;
                }
                if (nextColumn >= 0 && (tn.x & 0xFFFFu) > 0u && nextTop >= hit.z && exposed) {
                    float nv = clamp((hit.z - bmZBase) / max(nextTop - bmZBase, 1e-6), 0.0, 1.0);
                    w = mix(w, mix(bmWallAt(nextColumn, nv, l0), bmWallAt(nextColumn, nv, l0 + 1), fract(lod)), abs(f));
                }
            }
        }
        wallShare = w.a;
        wall = w.rgb * (0.62 + 0.38 * abs(dot(n, uSunDir))); // as city_building.frag lights faces
        if (wallShare >= 0.5) faceNormal = n;
    }
    vec3 roof = vec3(0.0);
    if (wallShare < 1.0) roof = bmRoof(hit, d, tHit, roofNormal);
    fragColor = vec4(mix(roof, wall, wallShare), 1.0);
    if (m.source.a > 0.0) fragColor = vec4(m.source.rgb * (0.62 + 0.38 * abs(dot(faceNormal, uSunDir))), 1.0);
}
