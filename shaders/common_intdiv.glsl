// Integer division and remainder of x >= 0 by a divisor known only when drawing (a uniform), exact for x < 2^24.
// llvmpipe has no vector integer division: `/` and `%` by a non-constant run lane by lane as scalar divisions (they
// were a quarter of the terrain's frame, docs/performance.md). Here the quotient comes from a float division, within
// one of the exact quotient (x and d are exact in float and the division errs by at most 2.5 ulp), and one integer
// step corrects it. Programs built for one clipmap get its layout as compile-time constants instead
// (common_clip_layout.glsl), where a division is a multiply and a shift. ShaderIntMathGLTest checks both against C++.
#ifndef SV_COMMON_INTDIV
#define SV_COMMON_INTDIV

ivec2 svDiv(ivec2 x, int d) {
    ivec2 q = ivec2(floor(vec2(x) / float(d)));
    ivec2 r = x - q * d;
    return q + ivec2(greaterThanEqual(r, ivec2(d))) - ivec2(lessThan(r, ivec2(0)));
}

ivec2 svMod(ivec2 x, int d) { return x - svDiv(x, d) * d; }

#endif
