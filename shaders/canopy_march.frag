// The canopy march (common_canopy_march.glsl) with forward terrain shading: a pass over the whole frame before the
// terrain, writing each hit's colour and depth; where a ray meets no layer, the far depth under a colour of alpha 0
// (blended away), so the terrain drawn next shows there. With deferred shading the terrain resolve marches instead
// (terrain_resolve.frag, variant CANOPY_MARCH): one full-screen pass less.
#include "common_clipmap.glsl"
#include "common_canopy.glsl"
#include "common_view.glsl"
#include "common_canopy_march.glsl"

out vec4 fragColor;

void main() {
    ivec2 pixel = ivec2(gl_FragCoord.xy);
    if (!canopyEntryRecorded(pixel)) discard;
    CanopyHit h = canopyMarchAt(pixel);
    if (h.layer < 0) {
        gl_FragDepth = 0.0; // reversed Z: far, as cleared
        fragColor = vec4(0.0);
        return;
    }
    int used;
    vec4 a = sampleClipmap(0, h.p, clipmapFootprintOf(h.dx, h.dy), used);
    fragColor = vec4(shaded(canopyLayerFactor(h.layer) * a.rgb, h.n), 1.0);
    gl_FragDepth = canopyHitDepth(h);
}
