// Bark: a brown Lambert-shaded cylinder (foliage/TrunksGL.h), its normal at the point of the cylinder seen through
// this fragment of the quad facing the eye (shaders/trunk.vert).
in float vU;
flat in vec3 vAcross;
flat in vec3 vToward;
uniform vec3 uSunDir;
out vec4 fragColor;

void main() {
    float u = clamp(vU, -1.0, 1.0);
    vec3 n = u * vAcross + sqrt(1.0 - u * u) * vToward;
    float l = 0.35 + 0.65 * max(dot(n, uSunDir), 0.0);
    fragColor = vec4(vec3(0.36, 0.26, 0.17) * l, 1.0);
}
