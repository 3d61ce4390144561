// Reference renderer: imagery draped by per-vertex image coordinates; nothing outside the image. Premultiplied RGBA:
// where the season has no data the other one shows, then uNoDataColour, as in the clipmap renderer.
#include "common_tiled_image.glsl"

uniform sampler2DArray uImagery;
uniform sampler2DArray uOther;
uniform vec3 uNoDataColour;

in vec2 vImageUv;
out vec4 fragColor;

void main() {
    if (any(lessThan(vImageUv, vec2(0.0))) || any(greaterThan(vImageUv, vec2(1.0)))) discard;
    vec4 a = sampleTiledImage(uImagery, vImageUv);
    if (a.a < 0.999) {
        vec4 b = sampleTiledImage(uOther, vImageUv);
        a.rgb += (1.0 - a.a) * (b.rgb + (1.0 - b.a) * uNoDataColour);
    }
    fragColor = vec4(a.rgb, 1.0);
}
