// The deferred terrain resolve (ClipmapTerrainRendererGL, TerrainShading::Deferred): each pixel the geometry pass
// (terrain_clipmap.frag, variant GBUFFER) left terrain in is shaded once, in whole 4x4 blocks of pixels, however
// small the triangles that covered it. With forward shading llvmpipe runs the fragment shader on every 4x4 block a
// triangle touches, and the geometry clipmap's distant triangles cover a few pixels each: the clipmap sampling ran
// several times per pixel (docs/performance.md). Same position, derivatives and normal, same code (common_view.glsl):
// the same colours.
#include "common_clipmap.glsl"
#include "common_canopy.glsl"
#include "common_view.glsl"
#ifdef CANOPY_MARCH
#include "common_canopy_march.glsl"
uniform sampler2D uGDepth; // the terrain's depth (terrain_clipmap.frag, variant GBUFFER_DEPTH; GBUFFER_DEPTH_PACKED:
                           // in uGFootprint's z, the terrain unshaded)
#endif

uniform sampler2D uGPosition;  // p, dFdx(p); p.x < 0: no terrain here
uniform sampler2D uGFootprint; // dFdy(p), n.xy
out vec4 fragColor;

void main() {
    ivec2 at = ivec2(gl_FragCoord.xy);
    vec4 g0 = texelFetch(uGPosition, at, 0);
#ifdef CANOPY_MARCH
    // The canopy view with marched layers (common_canopy_march.glsl): a pixel shows the crown its ray meets, else the
    // ground as VIEW 8 draws it (common_view.glsl); one imagery sampling either way (the crown's leaf-on at its hit,
    // or the ground's season), and the depth of what it shows.
    CanopyHit h = canopyMarchAt(at);
    // The top layer's record has its own depth buffer: terrain nearer than the crown's hit (a crest in front of the
    // forest behind it) hides the crown, as it did when the crowns were drawn first (reversed Z; ties: the crown).
    vec4 g1 = texelFetch(uGFootprint, at, 0);
#ifdef GBUFFER_DEPTH_PACKED
    float terrainDepth = g0.x < 0.0 ? 0.0 : g1.z; // cleared: no terrain, the far depth
    vec3 n = vec3(0.0, 0.0, 1.0);
#else
    float terrainDepth = texelFetch(uGDepth, at, 0).r;
    vec3 n = vec3(g1.zw, sqrt(max(1.0 - dot(g1.zw, g1.zw), 0.0)));
#endif
    bool crown = h.layer >= 0 && (g0.x < 0.0 || canopyHitDepth(h) >= terrainDepth);
    if (g0.x < 0.0 && !crown) discard;
    // The ground's canopy level from its isotropic footprint alone; the footprint itself once, of what the pixel shows.
    int canopyLevel = int(floor(max(clipmapLambdaIso(g0.zw, g1.xy), 0.0)));
    bool under = !crown && canopyAtNoting(g0.xy, canopyLevel) > 0;
    bool base = under && uCanopyBase > 0.0;
    int season = crown || base ? 0 : uCanopyGround[under ? 1 : 0];
    vec2 sp = crown ? h.p : g0.xy;
    ClipFootprint sf = clipmapFootprintOf(crown ? h.dx : g0.zw, crown ? h.dy : g1.xy);
    int used;
    vec4 a = sampleClipmap(season, sp, sf, used);
    vec3 c = crown ? canopyLayerFactor(h.layer) * a.rgb : (base ? uCanopyBase : 1.0) * seasonColourOf(a, season, sp, sf);
    fragColor = vec4(shaded(c, crown ? h.n : n), 1.0);
    gl_FragDepth = crown ? canopyHitDepth(h) : terrainDepth;
#else
    if (g0.x < 0.0) discard;
    vec4 g1 = texelFetch(uGFootprint, at, 0);
    vec3 n = vec3(g1.zw, sqrt(max(1.0 - dot(g1.zw, g1.zw), 0.0)));
    int used;
    fragColor = vec4(viewColour(g0.xy, clipmapFootprintOf(g0.zw, g1.xy), n, 0, used), 1.0);
#endif
}
