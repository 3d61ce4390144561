// The layout of a texture clipmap (clipmap/ClipmapGL.h, ClipmapGL::bind sets the uniforms): level sizes, the N×N
// toroidal levels and their blocks with validity tags. Shared by the draws (common_clipmap.glsl), the canopy layer
// (common_canopy.glsl) and the compute passes that read a clipmap. Where the program was built for one clipmap,
// ClipmapGL::layoutDefines() gives CLIP_BLOCK_SIZE, CLIP_SLOTS_PER_SIDE and CLIP_SIZE as compile-time constants:
// llvmpipe divides by a constant with a multiply and a shift, by a uniform lane by lane (common_intdiv.glsl).
#ifndef SV_COMMON_CLIP_LAYOUT
#define SV_COMMON_CLIP_LAYOUT
#include "common_intdiv.glsl"

uniform isampler2DArray uClipTags;
uniform int uClipLevels;    // toroidal levels; pyramid level uClipLevels is the coarse texture's base
uniform float uClipSize;    // N
uniform int uBlockSize;
uniform int uSlotsPerSide;
uniform vec2 uLevel0Size;   // image pixels
uniform vec2 uCoarseSize;   // texels of the coarse texture's base

// For a level texel q >= 0 (or block b >= 0): its block, its block's slot, and where the N×N level stores it.
#ifdef CLIP_BLOCK_SIZE
ivec2 clipBlockOf(ivec2 q) { return ivec2(uvec2(q) / uint(CLIP_BLOCK_SIZE)); }
ivec2 clipSlotOf(ivec2 b) { return ivec2(uvec2(b) % uint(CLIP_SLOTS_PER_SIDE)); }
ivec2 clipTexelOf(ivec2 q) { return ivec2(uvec2(q) % uint(CLIP_SIZE)); }
#else
ivec2 clipBlockOf(ivec2 q) { return svDiv(q, uBlockSize); }
ivec2 clipSlotOf(ivec2 b) { return svMod(b, uSlotsPerSide); }
ivec2 clipTexelOf(ivec2 q) { return svMod(q, int(uClipSize)); }
#endif

#endif
