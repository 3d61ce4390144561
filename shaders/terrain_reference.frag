// Reference renderer: imagery draped by per-vertex image coordinates; nothing outside the image.
#include "common_tiled_image.glsl"

uniform sampler2DArray uImagery;

in vec2 vImageUv;
out vec4 fragColor;

void main() {
    if (any(lessThan(vImageUv, vec2(0.0))) || any(greaterThan(vImageUv, vec2(1.0)))) discard;
    fragColor = vec4(sampleTiledImage(uImagery, vImageUv).rgb, 1.0);
}
