// Instanced trunks (foliage/TrunksGL.h): one cylinder per crown centre found by trunk_find.comp, from the terrain
// (common_elevation.glsl) up to the crowns' base, its radius a fraction of the crown's, drawn as a quad facing the eye.
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

uniform vec3 uEye;             // local metres

out float vU;          // across the quad, -1 .. 1 along vAcross, in radii from the axis
flat out vec3 vAcross; // the horizontal unit vector across the quad, from u = 0 towards u = 1
flat out vec3 vToward; // the horizontal unit vector from the axis to the eye

void main() {
    if (gl_InstanceID >= uCapacity) {
        gl_Position = vec4(0.0, 0.0, 0.0, 0.0); // past the buffer: no triangle
        vU = 0.0;
        vAcross = vToward = vec3(1.0, 0.0, 0.0);
        return;
    }
    vec4 t = trunks[gl_InstanceID];
    vec2 local = (uImageToLocal * vec3(t.xy, 1.0)).xy;
    vec2 s = vec2(local.x - uGridOrigin.x, uGridOrigin.y - local.y) / uGridSpacing;
    float ground = elevationAt(0, s);
    float radius = clamp(t.z * uMetresPerPixel * uRadiusFraction, uMinRadius, uMaxRadius);
    // The cylinder as the quad through its axis facing the eye (a cylindrical billboard), its normal rebuilt per
    // fragment from the position across it: the cylinder's outline (to r² / d of its width at distance d) and
    // shading with 4 vertices a trunk, where an 8-sided prism took 18 (llvmpipe shades vertices on the render
    // thread). Strip: u = -1 bottom, top, then u = 1 bottom, top.
    vec2 toward = uEye.xy - local;
    toward = dot(toward, toward) > 1e-6 ? normalize(toward) : vec2(0.0, -1.0);
    vec2 across = vec2(toward.y, -toward.x);
    float u = (gl_VertexID & 2) != 0 ? 1.0 : -1.0;
    bool top = (gl_VertexID & 1) == 1;
    // Sunk 1 m into the ground so slopes show no gap under it.
    vec3 p = vec3(local + radius * u * across, top ? ground + uTrunkHeight : ground - 1.0);
    vU = u;
    vAcross = vec3(across, 0.0);
    vToward = vec3(toward, 0.0);
    gl_Position = uViewProj * vec4(p, 1.0);
}
