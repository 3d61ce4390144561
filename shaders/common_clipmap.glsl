// Sampling a texture clipmap (clipmap/ClipmapGL.h). Positions are level-0 texels = leaf-on image pixels (x east,
// y south). Toroidal level l holds texel q = p / 2^l at (q mod N): texture coordinate q / N with GL_REPEAT. A
// block's data is valid only when the tag stored for its slot is the block's own tag; otherwise the next coarser
// level is used, down to the resident coarse pyramid, so nothing missing or stale is ever drawn.
#include "common_clip_layout.glsl"

// Every layer's toroidal levels in one array (layer i's level l at array layer i · uClipLayerStride + l) and the
// layers' coarse pyramids (array layer i, mipmapped): a pixel choosing its layer (the season) indexes one sampler.
uniform sampler2DArray uClip;
uniform sampler2DArray uCoarse;
uniform int uClipLayerStride;

bool clipBlockValid(int level, vec2 q) {
    ivec2 b = ivec2(floor(q / float(uBlockSize)));
    if (b.x < 0 || b.y < 0) return false;
    ivec2 slot = clipSlotOf(b);
    return texelFetch(uClipTags, ivec3(slot, level), 0).r == (b.x | (b.y << 16));
}

vec4 clipLevelSample(int layer, int level, vec2 p) {
    float s = exp2(float(level));
    // Stay half a texel inside the level's image: the texel past the edge belongs to another block's slot.
    vec2 q = clamp(p / s, vec2(0.5), ceil(uLevel0Size / s) - 0.5);
    return textureLod(uClip, vec3(q / uClipSize, float(layer * uClipLayerStride + level)), 0.0);
}

vec4 coarseSample(int layer, vec2 p, float level) {
    vec2 uv = p / (exp2(float(uClipLevels)) * uCoarseSize);
    return textureLod(uCoarse, vec3(uv, float(layer)), max(level - float(uClipLevels), 0.0));
}

// A pixel's footprint in level-0 texels: the ellipse spanned by the screen-space derivatives (Heckbert 1989).
// Anisotropic filtering by footprint assembly: `probes` bilinear probes spread along the major axis, each at the
// level the footprint's length / probes asks for, so a grazing pixel is sharp across and smooth along the view.
// Done in the shader rather than by the sampler so that every probe checks its own block's tag: hardware
// anisotropic taps would reach into neighbouring slots whose data may be stale.
struct ClipFootprint {
    vec2 axis;          // major axis, full length, level-0 texels
    int probes;         // 1 = isotropic
    float lambda;       // log2 of level-0 texels per probe across the view: the level to sample
    float lambdaIso;    // log2 of level-0 texels per pixel, isotropic (GL's own LOD; what the statistics use)
};

uniform float uClipAniso;   // maximum anisotropy (probes per pixel); 1 = off

// log2 of level-0 texels per pixel, isotropic (ClipFootprint::lambdaIso), from the derivatives alone.
float clipmapLambdaIso(vec2 dx, vec2 dy) {
    float iso = max(length(dx), length(dy));
    return iso > 1e-8 ? log2(min(iso, 1e30)) : log2(1e-8);
}

// The footprint from the screen-space derivatives dx = dFdx(p), dy = dFdy(p) (the deferred resolve stores them).
ClipFootprint clipmapFootprintOf(vec2 dx, vec2 dy) {
    // Eigen-decomposition of J Jᵀ, J = [dx dy]: the footprint ellipse's squared semi-axes and the major direction.
    float a = dx.x * dx.x + dy.x * dy.x, b = dx.x * dx.y + dy.x * dy.y, c = dx.y * dx.y + dy.y * dy.y;
    float h = 0.5 * (a + c), d = sqrt(max(h * h - (a * c - b * b), 0.0));
    float major = sqrt(h + d), minor = sqrt(max(h - d, 0.0));
    vec2 e1 = vec2(b, h + d - a), e2 = vec2(h + d - c, b);
    vec2 dir = dot(e1, e1) > dot(e2, e2) ? e1 : e2;
    dir = dot(dir, dir) > 1e-20 ? normalize(dir) : vec2(1.0, 0.0);
    ClipFootprint f;
    // Written so that non-finite derivatives (a surface seen exactly edge-on) give one probe at a finite level:
    // comparisons with NaN are false. A NaN level would start sampleClipmap's level loop at int(NaN) = INT_MIN
    // (2^31 iterations for one fragment).
    float ratio = major / max(minor, 1e-8);
    ratio = ratio >= 1.0 ? min(ratio, max(uClipAniso, 1.0)) : 1.0;
    f.probes = clamp(int(ceil(ratio - 1e-3)), 1, 16);
    f.axis = f.probes > 1 && major < 1e30 ? dir * major : vec2(0.0);
    // The level of the minor axis (of major / max anisotropy when clamped); not major / probes as GL allows,
    // which would undersample when the ratio is just above an integer.
    float m = major / ratio;
    f.lambda = m > 1e-8 ? log2(min(m, 1e30)) : log2(1e-8);
    f.lambdaIso = clipmapLambdaIso(dx, dy);
    return f;
}

ClipFootprint clipmapFootprint(vec2 p) { return clipmapFootprintOf(dFdx(p), dFdy(p)); }

// The mean of the footprint's probes at one level; false if any probe's block is not valid.
bool clipLevelProbes(int layer, int level, vec2 p, ClipFootprint f, out vec4 colour) {
    float s = exp2(float(level));
    colour = vec4(0.0);
    for (int i = 0; i < f.probes; ++i) {
        vec2 pi = clamp(p + f.axis * ((float(i) + 0.5) / float(f.probes) - 0.5), vec2(0.0), uLevel0Size);
        if (!clipBlockValid(level, pi / s)) return false;
        colour += clipLevelSample(layer, level, pi);
    }
    colour /= float(f.probes);
    return true;
}

vec4 coarseProbes(int layer, vec2 p, float level, ClipFootprint f) {
    vec4 colour = vec4(0.0);
    for (int i = 0; i < f.probes; ++i)
        colour += coarseSample(layer, p + f.axis * ((float(i) + 0.5) / float(f.probes) - 0.5), level);
    return colour / float(f.probes);
}

// The finest valid level at p, no finer than the level the footprint asks for; trilinear between it and the next
// level, of layer `layer` (0 leaf-on, 1 leaf-off). `usedLevel` receives the level actually used (uClipLevels or more:
// the coarse pyramid).
vec4 sampleClipmap(int layer, vec2 p, ClipFootprint f, out int usedLevel) {
    float lambda = f.lambda > 0.0 ? min(f.lambda, 64.0) : 0.0; // bounded: l0 below starts a loop
    int l0 = int(floor(lambda));
    float t = lambda - float(l0);
    vec4 a, b;
    for (int l = l0; l < uClipLevels; ++l) {
        if (!clipLevelProbes(layer, l, p, f, a)) continue;
        usedLevel = l;
        if (l != l0 || t <= 0.0) return a;
        int n = l + 1;
        if (n >= uClipLevels || !clipLevelProbes(layer, n, p, f, b)) b = coarseProbes(layer, p, float(n), f);
        return mix(a, b, t);
    }
    usedLevel = max(l0, uClipLevels);
    return coarseProbes(layer, p, max(lambda, float(uClipLevels)), f);
}
