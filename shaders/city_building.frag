// City fragments. Variants: ATLAS (a node's atlas through the root-atlas coordinates, Buchholz & Döllner 2005's
// texture-matrix trick: fract(root · 2^level), sampled with the derivatives of root · 2^level so the wrap of
// fract() does not fool the mip selection), ORIGINAL (the original texture), FLAT (one dummy texture for every
// triangle: the paper's upper bound), ROOF (the imagery clipmap of the current season at the fragment's world
// position), PLAIN (untextured: one colour). Walls are shaded from their face normal.
#ifdef ROOF
#include "common_clipmap.glsl"
#include "common_roof.glsl" // its variants ROOF_BLEND, SEASONS_COMPLETE
uniform int uHasImagery;
in vec2 vImageUv;
#else
uniform sampler2D uTexture;
uniform float uLevelScale; // ATLAS: 2^level
uniform float uMaxAniso;   // ORIGINAL, FLAT: the sampler's maximum anisotropy
#endif
uniform vec3 uSunDir;
uniform vec3 uPlainColour;
uniform float uAlphaCut; // RGBA tree: fragments below this alpha are dropped
uniform vec4 uSourceColour; // a > 0: the levels view, the colour of what draws these triangles, shaded by the face

in vec2 vUv;
in vec2 vRoot;
in vec3 vLocal;
out vec4 fragColor;

void main() {
    vec3 n = normalize(cross(dFdx(vLocal), dFdy(vLocal)));
    float light = 0.62 + 0.38 * abs(dot(n, uSunDir));
    vec4 c;
#if defined(ATLAS)
    vec2 s = vRoot * uLevelScale;
    c = textureGrad(uTexture, fract(s), dFdx(s), dFdy(s));
#elif defined(ORIGINAL) || defined(FLAT)
    // llvmpipe's anisotropic filter (an EWA scan of the footprint's texels at the level it picks, from the
    // coordinates' own quad differences) is unbounded once the level clamps at the last mip: a facade whose
    // repeating texture spans hundreds of repetitions per pixel (seen edge-on from 885 m, frame 25 of
    // data/paths/blockcity_pedestrian_overview.json) took 20-60 s for one 640x360 frame. Beyond the footprint
    // the last mip can absorb, the filter returns that mip's mean whatever the coordinates, so the coordinates
    // are scaled down by a power of two until it fits. k is per 2x2 quad (coarse derivatives), as the filter's
    // own differences are; k = 1 (the coordinates untouched) everywhere else.
    vec2 size = vec2(textureSize(uTexture, 0));
    float major = max(length(dFdxCoarse(vUv) * size), length(dFdyCoarse(vUv) * size));
    float room = uMaxAniso * max(size.x, size.y);
    float k = major <= room ? 1.0 : (major < 1e30 ? exp2(ceil(log2(major / room))) : 1e30);
    c = texture(uTexture, vUv / k);
#elif defined(ROOF)
    light = 1.0; // the orthophoto carries its own light
    if (uHasImagery != 0 && all(greaterThanEqual(vImageUv, vec2(0.0))) && all(lessThanEqual(vImageUv, vec2(1.0)))) {
        vec2 p = vImageUv * uLevel0Size;
        c = vec4(roofImagery(p, clipmapFootprint(p), uPlainColour), 1.0);
    } else {
        c = vec4(uPlainColour, 1.0);
        light = 0.62 + 0.38 * abs(dot(n, uSunDir));
    }
#else
    c = vec4(uPlainColour, 1.0);
#endif
    if (c.a < uAlphaCut) discard;
    if (uSourceColour.a > 0.0) {
        c.rgb = uSourceColour.rgb;
        light = 0.62 + 0.38 * abs(dot(n, uSunDir));
    }
    fragColor = vec4(c.rgb * light, 1.0);
}
