// City triangles (city/CityRendererGL.h): tree triangles with their original and root-atlas texture coordinates,
// or plain triangles (roofs, untextured walls). Variant ROOF also computes the leaf-on image coordinates of the
// vertex through the terrain's local -> image lookup, as terrain_geometry.vert does, so roofs sample the imagery
// clipmap by world position (Buchholz's thesis §4.8.2, per fragment: no seams, no roof textures in the tree).
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec2 aUv;
layout(location = 2) in vec2 aRoot;

uniform mat4 uViewProj;

out vec2 vUv;
out vec2 vRoot;
out vec3 vLocal;

#ifdef ROOF
uniform sampler2D uLocalToImage; // RG32F: local -> leaf-on image coordinates in [0,1]
uniform vec2 uLookupMin, uLookupSize;
uniform float uLookupTexels;
uniform mat2 uLookupSlope;
out vec2 vImageUv;
#endif

void main() {
    vUv = aUv;
    vRoot = aRoot;
    vLocal = aPosition;
#ifdef ROOF
    vec2 t = (aPosition.xy - uLookupMin) / uLookupSize;
    vec2 tc = clamp(t, 0.0, 1.0);
    vImageUv = textureLod(uLocalToImage, (tc * (uLookupTexels - 1.0) + 0.5) / uLookupTexels, 0.0).xy +
               uLookupSlope * (t - tc);
#endif
    gl_Position = uViewProj * vec4(aPosition, 1.0);
}
