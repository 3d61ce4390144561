// Reference renderer: full-resolution mesh, positions in the local frame (metres).
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec2 aImageUv;

uniform mat4 uViewProj;

out vec2 vImageUv;

void main() {
    vImageUv = aImageUv;
    gl_Position = uViewProj * vec4(aPosition, 1.0);
}
