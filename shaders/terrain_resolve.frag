// The deferred terrain resolve (ClipmapTerrainRendererGL, TerrainShading::Deferred): each pixel the geometry pass
// (terrain_clipmap.frag, variant GBUFFER) left terrain in is shaded once, in whole 4x4 blocks of pixels, however
// small the triangles that covered it. With forward shading llvmpipe runs the fragment shader on every 4x4 block a
// triangle touches, and the geometry clipmap's distant triangles cover a few pixels each: the clipmap sampling ran
// several times per pixel (docs/performance.md). Same position, derivatives and normal, same code (common_view.glsl):
// the same colours.
#include "common_clipmap.glsl"
#include "common_canopy.glsl"
#include "common_view.glsl"

uniform sampler2D uGPosition;  // p, dFdx(p); p.x < 0: no terrain here
uniform sampler2D uGFootprint; // dFdy(p), n.xy
out vec4 fragColor;

void main() {
    ivec2 at = ivec2(gl_FragCoord.xy);
    vec4 g0 = texelFetch(uGPosition, at, 0);
    if (g0.x < 0.0) discard;
    vec4 g1 = texelFetch(uGFootprint, at, 0);
    vec3 n = vec3(g1.zw, sqrt(max(1.0 - dot(g1.zw, g1.zw), 0.0)));
    int used;
    fragColor = vec4(viewColour(g0.xy, clipmapFootprintOf(g0.zw, g1.xy), n, 0, used), 1.0);
}
