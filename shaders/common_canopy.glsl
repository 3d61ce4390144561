// The derived canopy layer (foliage/CanopyClipmapGL.h): per texel, how many stacked canopy layers it belongs to.
// Same level layout, toroidal addressing and block tags as the imagery clipmap (common_clipmap.glsl's uniforms),
// its own tags (a block is derived once it and its neighbours are resident). Nearest texel: one fetch.
#include "common_clip_layout.glsl"

uniform usampler2DArray uCanopyClip;
uniform usampler2D uCanopyCoarse;
uniform isampler2DArray uCanopyTags;
uniform int uCanopyLayers;

bool canopyBlockValid(int level, ivec2 q) {
    ivec2 b = clipBlockOf(q); // q >= 0
    ivec2 slot = clipSlotOf(b);
    return texelFetch(uCanopyTags, ivec3(slot, level), 0).r == (b.x | (b.y << 16));
}

// Layers the texel at level-0 position p belongs to, from `level` or the first coarser level derived there.
int canopyAt(vec2 p, int level) {
    for (int l = max(level, 0); l < uClipLevels; ++l) {
        float s = exp2(float(l));
        ivec2 q = clamp(ivec2(floor(p / s)), ivec2(0), ivec2(ceil(uLevel0Size / s)) - 1);
        if (canopyBlockValid(l, q)) return int(texelFetch(uCanopyClip, ivec3(clipTexelOf(q), l), 0).r);
    }
    float s = exp2(float(uClipLevels));
    ivec2 q = clamp(ivec2(floor(p / s)), ivec2(0), ivec2(uCoarseSize) - 1);
    return int(texelFetch(uCanopyCoarse, q, 0).r);
}
