// Instanced trunks (foliage/TrunksGL.h): one 8-sided cylinder per crown centre found by trunk_find.comp, from the
// terrain (common_elevation.glsl) up to the crowns' base, its radius a fraction of the crown's.
#include "common_elevation.glsl"

layout(std430, binding = 0) readonly buffer Trunks {
    uint vertexCount;
    uint instanceCount;
    uint first;
    uint baseInstance;
    vec4 trunks[];
};

uniform mat4 uViewProj;
uniform mat3 uImageToLocal;   // level-0 image pixel (x east, y south) -> local metres
uniform vec2 uGridOrigin;     // elevation grid: local position of sample (0, 0)
uniform float uGridSpacing;
uniform float uMetresPerPixel;
uniform float uTrunkHeight;   // metres: the crowns' base above the ground
uniform float uRadiusFraction;
uniform float uMinRadius, uMaxRadius; // metres
uniform int uCapacity;

out vec3 vNormal;

const int SIDES = 8;

void main() {
    if (gl_InstanceID >= uCapacity) {
        gl_Position = vec4(0.0, 0.0, 0.0, 0.0); // past the buffer: no triangle
        vNormal = vec3(0.0, 0.0, 1.0);
        return;
    }
    vec4 t = trunks[gl_InstanceID];
    vec2 local = (uImageToLocal * vec3(t.xy, 1.0)).xy;
    vec2 s = vec2(local.x - uGridOrigin.x, uGridOrigin.y - local.y) / uGridSpacing;
    float ground = elevationAt(0, s);
    float radius = clamp(t.z * uMetresPerPixel * uRadiusFraction, uMinRadius, uMaxRadius);
    // A triangle strip round the sides: a0, b0, a1, b1, ..., a8 = a0, b8 = b0 (a = bottom, b = top), two triangles
    // per side, (a_k, b_k, a_k+1) and (a_k+1, b_k, b_k+1): each corner shaded once for its two sides, 18 vertices a
    // trunk instead of 48 as separate triangles.
    int k = gl_VertexID / 2;
    bool top = (gl_VertexID & 1) == 1;
    float a = 6.2831853 * float(k) / float(SIDES);
    vec2 dir = vec2(cos(a), sin(a));
    // Sunk 1 m into the ground so slopes show no gap under it.
    vec3 p = vec3(local + radius * dir, top ? ground + uTrunkHeight : ground - 1.0);
    vNormal = vec3(dir, 0.0);
    gl_Position = uViewProj * vec4(p, 1.0);
}
