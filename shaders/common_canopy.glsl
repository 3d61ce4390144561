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

// Whether every block of clip level `level` under the level-0 box [lo, hi] is derived, for a box that spans at most
// 2 × 2 blocks there (false for a wider one, or a level past the clip levels): canopyAt(p, level) for p in the box is
// then the level's texel at p, one fetch instead of a tag check and a fetch per level tried (the march's stepped loop,
// common_canopy_march.glsl).
bool canopyBoxDerived(vec2 lo, vec2 hi, int level) {
    if (level < 0 || level >= uClipLevels) return false;
    float s = exp2(float(level));
    ivec2 last = ivec2(ceil(uLevel0Size / s)) - 1;
    ivec2 t0 = clamp(ivec2(floor(lo / s)), ivec2(0), last), t1 = clamp(ivec2(floor(hi / s)), ivec2(0), last);
    if (any(greaterThan(clipBlockOf(t1) - clipBlockOf(t0), ivec2(1)))) return false;
    return canopyBlockValid(level, t0) && canopyBlockValid(level, ivec2(t1.x, t0.y)) &&
           canopyBlockValid(level, ivec2(t0.x, t1.y)) && canopyBlockValid(level, t1);
}
