// A BlockMap ray-cast per pixel (city/BlockMapGL.h; Cignoni et al. 2007 §3.2), the GPU copy of city/BlockMap.cpp's
// traceBlockMap: from where the pixel's ray enters the block's box, texel by texel over the height map (a DDA), a
// texel hit where the ray is at or below its top (a wall if it entered through a side, a roof where it comes down
// through the top), leaping over empty texels with the distance map to the edge of the empty square it guarantees.
// Writes the hit's colour and depth (reversed Z, as the terrain's), so it composes with everything else drawn; a ray
// that meets no prism is discarded (the terrain under the block shows). Positions relative to the block's origin.
uniform usampler2D uBmHeight;   // n × n: 0 no building, else zBase + value · (zTop − zBase) / 255
uniform usampler2D uBmDistance; // n × n: Chebyshev distance in texels to the nearest building texel
uniform usampler2D uBmColumn;   // n × n: 1 + a boundary texel's wall column
uniform sampler2D uBmWall;      // the columns in rows of uBmColumnsPerRow, each uBmWallTexels colours, the foot's first
uniform sampler2D uBmNormal;    // a column's outward normal, (n + 1) / 2, at (column mod perRow, column / perRow)
uniform int uBmColumnsPerRow;
uniform int uBmWallTexels;
uniform vec2 uBmOrigin;         // local metres
uniform float uBmTexel;
uniform int uBmSize;
uniform float uBmZBase, uBmZTop;
uniform vec3 uEye;              // local metres
uniform mat4 uViewProj;
uniform vec3 uRoofColour;       // roofs (the renderer textures them from the terrain imagery)
uniform vec3 uSunDir;
// Output what was hit instead of a colour (the tests): (kind, 0, 0, 1) with kind 0.5 a roof, 1 a wall.
uniform int uOutputKind;

in vec3 vWorld;
out vec4 fragColor;

const int kNone = 0, kRoof = 1, kWall = 2;

float bmTop(uint value) { return uBmZBase + float(value) * (uBmZTop - uBmZBase) / 255.0; }
bool bmOutside(ivec2 c) { return any(lessThan(c, ivec2(0))) || any(greaterThanEqual(c, ivec2(uBmSize))); }

void main() {
    vec3 o = vec3(uEye.xy - uBmOrigin, uEye.z);
    vec3 d = vWorld - uEye;
    // No component exactly 0 (the slabs divide by them); a nudge far below a texel.
    d = mix(d, vec3(1e-12), equal(d, vec3(0.0)));
    float side = float(uBmSize) * uBmTexel;
    vec3 ta = (vec3(0.0, 0.0, uBmZBase) - o) / d, tb = (vec3(side, side, uBmZTop) - o) / d;
    vec3 tmin = min(ta, tb), tmax = max(ta, tb);
    float t0 = max(max(tmin.x, tmin.y), max(tmin.z, 0.0)), t1 = min(min(tmax.x, tmax.y), tmax.z);
    if (t0 > t1) discard;
    int enterAxis = t0 == 0.0 ? -1 : t0 == tmin.x ? 0 : t0 == tmin.y ? 1 : 2;
    if (enterAxis == 2 && d.z > 0.0) discard; // from under the block's floor
    ivec2 stp = ivec2(d.x > 0.0 ? 1 : -1, d.y > 0.0 ? 1 : -1);
    ivec2 up = max(stp, ivec2(0));
    vec2 delta = uBmTexel / abs(d.xy);
    ivec2 c = clamp(ivec2(floor((o.xy + t0 * d.xy) / uBmTexel)), ivec2(0), ivec2(uBmSize - 1));
    int face = enterAxis == 0 ? (stp.x > 0 ? 0 : 1) : enterAxis == 1 ? (stp.y > 0 ? 2 : 3) : enterAxis == 2 ? 4 : -1;
    vec2 nextT = (vec2(c + up) * uBmTexel - o.xy) / d.xy;
    float tCell = t0;
    int kind = kNone;
    float tHit = 0.0;
    float top = 0.0;
    for (int it = 0; it < 4 * uBmSize + 8 && kind == kNone; ++it) {
        float tOut = min(min(nextT.x, nextT.y), t1);
        uint value = texelFetch(uBmHeight, c, 0).r;
        if (value > 0u) {
            top = bmTop(value);
            if (o.z + tCell * d.z <= top) {
                kind = face == 4 ? kRoof : kWall;
                tHit = tCell;
                break;
            }
            if (o.z + tOut * d.z <= top) {
                kind = kRoof;
                tHit = (top - o.z) / d.z;
                face = 4;
                break;
            }
        } else {
            int r = int(texelFetch(uBmDistance, c, 0).r) - 1;
            if (r >= 1) {
                // Every texel within r of this one is empty: on to where the ray leaves that square.
                vec2 ex = (vec2(c + stp * r + up) * uBmTexel - o.xy) / d.xy;
                float tExit = min(ex.x, ex.y);
                if (tExit >= t1) break;
                if (ex.x <= ex.y) {
                    int y = clamp(int(floor((o.y + tExit * d.y) / uBmTexel)), c.y - r, c.y + r);
                    c = ivec2(c.x + stp.x * (r + 1), y);
                    face = stp.x > 0 ? 0 : 1;
                } else {
                    int x = clamp(int(floor((o.x + tExit * d.x) / uBmTexel)), c.x - r, c.x + r);
                    c = ivec2(x, c.y + stp.y * (r + 1));
                    face = stp.y > 0 ? 2 : 3;
                }
                if (bmOutside(c)) break;
                tCell = tExit;
                nextT = (vec2(c + up) * uBmTexel - o.xy) / d.xy;
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
    vec4 clip = uViewProj * vec4(hit.xy + uBmOrigin, hit.z, 1.0);
    gl_FragDepth = clip.z / clip.w;
    if (uOutputKind != 0) {
        fragColor = vec4(kind == kRoof ? 0.5 : 1.0, 0.0, 0.0, 1.0);
        return;
    }
    vec3 colour = uRoofColour;
    vec3 n = vec3(0.0, 0.0, 1.0);
    if (kind == kWall) {
        int column = max(int(texelFetch(uBmColumn, c, 0).r) - 1, 0);
        ivec2 slot = ivec2(column % uBmColumnsPerRow, column / uBmColumnsPerRow);
        float v = clamp((hit.z - uBmZBase) / max(top - uBmZBase, 1e-6), 0.0, 1.0);
        int j = min(int(v * float(uBmWallTexels)), uBmWallTexels - 1);
        colour = texelFetch(uBmWall, ivec2(slot.x * uBmWallTexels + j, slot.y), 0).rgb;
        n = texelFetch(uBmNormal, slot, 0).xyz * 2.0 - 1.0;
    }
    fragColor = vec4(colour * (0.55 + 0.45 * max(dot(n, uSunDir), 0.0)), 1.0);
}
