// The seasonal treetop rule per texel, the GPU copy of foliage/SegmentationRule.h: the same constants (checked by
// SegmentationRuleTest, which parses the `const int SV_SEG_*` lines below) and the same integer arithmetic, on 8-bit
// colour (ivec3 0..255, after the stretch and, for `equalized`, the equalisation table). FoliageRuleGLTest runs
// these functions on the GPU against the C++ ones. Texels outside the image come from clamp-to-edge fetches.

const int SV_SEG_DEFAULT_K = 5;
const int SV_SEG_MAX_K = 15;
const int SV_SEG_DROP_SCALE = 256;
const int SV_SEG_DROP_BINS = 512;
const int SV_SEG_MIN_DROP = 13;
const int SV_SEG_TEXTURE_PREFILTER = 3;
const int SV_SEG_TEXTURE_WINDOW = 5;
const int SV_SEG_TEXTURE_NUM = 9;
const int SV_SEG_TEXTURE_DEN = 10000;
const int SV_SEG_TEXTURE_HALO = 3; // SV_SEG_TEXTURE_PREFILTER / 2 + SV_SEG_TEXTURE_WINDOW / 2
const int SV_SEG_MIN_ALPHA = 128;

// A premultiplied 8-bit component back to its colour where coverage a is partial, as unpremultiply() on the CPU.
int svUnpremultiply(int c, int a) { return a > 0 && a < 255 ? min(255, (c * 255 + a / 2) / a) : c; }
// The same for the three components at once, in float: (n + 0.5) / a lies at least 0.5 / a from an integer, far more
// than the division's error (2.5 ulp, below 0.01 / a for n < 2^16), so its floor is the integer quotient exactly
// (ShaderIntMathGLTest checks every c and a). llvmpipe has no vector integer division: it divides lane by lane, and a
// select computes the quotient for every texel, so this is what canopy_derive.comp uses.
ivec3 svUnpremultiply3(ivec3 c, int a) {
    vec3 q = floor((vec3(c * 255 + a / 2) + 0.5) / float(max(a, 1)));
    return a > 0 && a < 255 ? min(ivec3(255), ivec3(q)) : c;
}

// maxchannel(c) = g (Ropinski et al. 2007 §4.1): green strictly brighter than red and blue.
bool svGreenIsMax(ivec3 c) { return c.g > c.r && c.g > c.b; }

// More than half of the k×k votes (§4.1: |{...}| > k²/2).
bool svIsMajority(int count, int k) { return 2 * count > k * k; }

int svExgNumerator(ivec3 c) { return 2 * c.g - c.r - c.b; }
int svExgDenominator(ivec3 c) { return c.r + c.g + c.b + 1; }

// ExG(on) - ExG(off) >= t / SV_SEG_DROP_SCALE, exact in 32-bit integers.
bool svDropAtLeast(ivec3 on, ivec3 off, int t) {
    int dOn = svExgDenominator(on), dOff = svExgDenominator(off);
    int num = svExgNumerator(on) * dOff - svExgNumerator(off) * dOn;
    return SV_SEG_DROP_SCALE * num >= t * dOn * dOff;
}

// Standard deviation of n smoothed brightness values > 0.03 × their mean: DEN (n sumSq - sum²) > NUM sum², rearranged
// as on the CPU; exact in double (every product an integer below 2^53).
bool svTextured(double n, double sum, double sumSq) {
    return double(SV_SEG_TEXTURE_DEN) * n * sumSq > double(SV_SEG_TEXTURE_DEN + SV_SEG_TEXTURE_NUM) * sum * sum;
}

bool svDefaultTexel(bool dropAboveThreshold, bool isTextured) { return dropAboveThreshold && isTextured; }
