// A BlockMap's bounding box (city/BlockMapGL.h; Cignoni et al. 2007 §3.2: "the fragments corresponding to rays
// entering the bounding box are activated by the rasterization of ... the bounding box"), one instance per map of
// the pool's draw (common_blockmap.glsl). Its front faces are drawn when the eye is well outside the box
// (blockmap.frag's FRONT_FACES: hidden faces skip the ray cast), its back faces otherwise (a pixel gets one fragment
// with the eye inside the box too); the fragment shader casts the pixel's ray from the eye.
#include "common_blockmap.glsl"
uniform mat4 uViewProj;
uniform int uFirstInstance; // the draw's first record
uniform int uBmPair;        // the pair of storage segments this draw binds (BmMap.z.y); -1: every map's

out vec3 vWorld;
flat out int vMap;

// The unit cube's corners (bit 0: x, 1: y, 2: z), two triangles per face, counter-clockwise seen from outside.
const int kCorner[36] = int[36](0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4, 2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1,
                                4, 5, 7, 4, 7, 6);

void main() {
    vMap = uFirstInstance + gl_InstanceID;
    BmMap m = bmMaps[vMap];
    if (uBmPair >= 0 && int(m.z.y) != uBmPair) {
        // Another draw's map (its storage is bound there): every corner at one point, nothing rasterised.
        vWorld = vec3(0.0);
        gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
        return;
    }
    int c = kCorner[gl_VertexID];
    vec3 corner = vec3(float(c & 1), float((c >> 1) & 1), float((c >> 2) & 1));
    vec3 lo = vec3(m.geo.xy, m.geo.w), hi = vec3(m.geo.xy + float(uBmSize) * m.geo.z, m.z.x);
    vWorld = mix(lo, hi, corner);
    gl_Position = uViewProj * vec4(vWorld, 1.0);
}
