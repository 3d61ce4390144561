// Sampling a texture clipmap (clipmap/ClipmapGL.h). Positions are level-0 texels = leaf-on image pixels (x east,
// y south). Toroidal level l holds texel q = p / 2^l at (q mod N): texture coordinate q / N with GL_REPEAT. A
// block's data is valid only when the tag stored for its slot is the block's own tag; otherwise the next coarser
// level is used, down to the resident coarse pyramid, so nothing missing or stale is ever drawn.
uniform isampler2DArray uClipTags;
uniform int uClipLevels;    // toroidal levels; pyramid level uClipLevels is the coarse texture's base
uniform float uClipSize;    // N
uniform int uBlockSize;
uniform int uSlotsPerSide;
uniform vec2 uLevel0Size;   // image pixels
uniform vec2 uCoarseSize;   // texels of the coarse texture's base

bool clipBlockValid(int level, vec2 q) {
    ivec2 b = ivec2(floor(q / float(uBlockSize)));
    if (b.x < 0 || b.y < 0) return false;
    ivec2 slot = b % uSlotsPerSide;
    return texelFetch(uClipTags, ivec3(slot, level), 0).r == (b.x | (b.y << 16));
}

vec4 clipLevelSample(sampler2DArray clip, int level, vec2 p) {
    float s = exp2(float(level));
    // Stay half a texel inside the level's image: the texel past the edge belongs to another block's slot.
    vec2 q = clamp(p / s, vec2(0.5), ceil(uLevel0Size / s) - 0.5);
    return textureLod(clip, vec3(q / uClipSize, float(level)), 0.0);
}

vec4 coarseSample(sampler2D coarse, vec2 p, float level) {
    vec2 uv = p / (exp2(float(uClipLevels)) * uCoarseSize);
    return textureLod(coarse, uv, max(level - float(uClipLevels), 0.0));
}

// The finest valid level at p, no finer than the level the pixel's footprint asks for; trilinear between it and
// the next level. `lambda`: log2 of level-0 texels per pixel. `usedLevel` receives the level actually used
// (uClipLevels or more: the coarse pyramid).
vec4 sampleClipmap(sampler2DArray clip, sampler2D coarse, vec2 p, float lambda, out int usedLevel) {
    lambda = max(lambda, 0.0);
    int l0 = int(floor(lambda));
    float f = lambda - float(l0);
    for (int l = l0; l < uClipLevels; ++l) {
        vec2 q = p / exp2(float(l));
        if (!clipBlockValid(l, q)) continue;
        usedLevel = l;
        vec4 a = clipLevelSample(clip, l, p);
        if (l != l0 || f <= 0.0) return a;
        int n = l + 1;
        vec4 b = (n < uClipLevels && clipBlockValid(n, p / exp2(float(n)))) ? clipLevelSample(clip, n, p)
                                                                           : coarseSample(coarse, p, float(n));
        return mix(a, b, f);
    }
    usedLevel = max(l0, uClipLevels);
    return coarseSample(coarse, p, max(lambda, float(uClipLevels)));
}

// log2 of level-0 texels per pixel from screen-space derivatives (isotropic, like GL's own LOD).
float clipmapLambda(vec2 p) {
    vec2 dx = dFdx(p), dy = dFdy(p);
    return log2(max(max(length(dx), length(dy)), 1e-8));
}
