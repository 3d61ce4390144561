// Bark: a brown Lambert-shaded cylinder (foliage/TrunksGL.h).
in vec3 vNormal;
uniform vec3 uSunDir;
out vec4 fragColor;

void main() {
    float l = 0.35 + 0.65 * max(dot(normalize(vNormal), uSunDir), 0.0);
    fragColor = vec4(vec3(0.36, 0.26, 0.17) * l, 1.0);
}
