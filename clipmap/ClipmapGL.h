#pragma once
// The GL side of the texture clipmaps: per imagery layer (leaf-on, leaf-off, ...) one RGBA8 2D array texture of
// N×N toroidal levels plus one mipmapped texture of the resident coarse pyramid, and one R32I array texture of
// block tags shared by all layers (they share level geometry, centres and update schedule, so switching season
// is instant). Uploads only; the schedule (ClipmapSchedule) and loading (BlockLoader) are plain C++.
#include "BlockLoader.h"
#include "ClipmapSchedule.h"
#include "ImagePyramid.h"
#include "gl/GlObjects.h"
#include "gl/ShaderProgram.h"

#include <glm/vec2.hpp>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace seasonview {

struct ClipmapOptions {
    // N: texels per side of a toroidal level (256..4096). 2048 = the smallest power of two at least as wide as a
    // 1920-pixel view: straight down, a level spans at most N pixels, so narrower levels leave pixels too coarse.
    int size = 2048;
    int block = 64;                           // upload/validity block, texels
    std::int64_t uploadBudgetTexels = 1 << 20; // per frame (per layer): 4 MiB of RGBA8 per layer
    int cacheMegabytes = 128;                 // loader's OpenImageIO tile cache bound
    // Toroidal levels allocated at least (0 = as many as the image needs: one per pyramid level wider than N). A
    // fixed stack makes GPU memory identical for every image up to N · 2^levels; smaller images leave the extra
    // layers unused.
    int minClipLevels = 0;
    int streamWorkers = kStreamWorkers; // loader threads when a layer streams its finest levels (ImagePyramid.h)
};

struct ClipmapFrameStats {
    std::int64_t texelsUploaded = 0;  // this frame, all layers
    std::int64_t exposedTexels = 0;   // geometric minimum of this frame's move, per layer
    int blocksUploaded = 0;
    int blocksMissing = 0;            // wanted but not resident after this frame's uploads
};

class ClipmapGL {
public:
    /// All layers must have pyramids of the same size. Loads the resident coarse pyramid synchronously (at most
    /// N² texels per layer); toroidal levels start empty. Needs a current GL 4.5 context.
    /// `source` replaces the pyramid files as the loader's source (tests: a slow source); it must serve the
    /// same layers and levels.
    static Result<std::unique_ptr<ClipmapGL>> create(const std::vector<ImagePyramid>& layers,
                                                     const ClipmapOptions& options = {},
                                                     std::unique_ptr<BlockSource> source = nullptr);
    ~ClipmapGL();

    /// Once a frame: moves the windows to `centres` (level-0 texels = leaf-on image pixels, one per toroidal level;
    /// extra entries ignored), asks the loader for missing blocks, uploads what is ready within the budget.
    ClipmapFrameStats update(const std::vector<glm::dvec2>& centres);
    /// Blocks until every wanted block is loaded and uploaded (stills and tests; never in an interactive loop).
    ClipmapFrameStats completeSynchronously();

    /// The first block that could not be read (a damaged pyramid tile: its Zstandard checksum, a truncated file):
    /// the message (naming the file) and its layer. Such a block is never drawn (coarser levels stand in); a still
    /// must not be written with it missing.
    struct ReadError {
        std::string message;
        int layer = -1;
    };
    const std::optional<ReadError>& readError() const { return m_readError; }
    /// Blocks of streamed levels whose read failed so far (a service's fault, not the cache's: not a readError();
    /// each failure counted, the block asked again later), and the last failure's line (a tile's URL and HTTP
    /// status). The viewer's HUD and the bench show them; a still is not written with one.
    std::int64_t streamErrors() const { return m_streamErrors; }
    const std::string& lastStreamError() const { return m_lastStreamError; }
    /// Whether any layer streams its finest levels (ImagePyramid::streamedLevels).
    bool streaming() const { return m_streaming; }

    /// Binds the toroidal levels of every layer (uClip, a sampler2DArray: layer i's level l at array layer
    /// i · uClipLayerStride + l) to unit firstUnit, the coarse pyramids (uCoarse, a sampler2DArray: Rgba8, layer i
    /// mipmapped at array layer i; R32F below) to firstUnit + 1, the tag texture (uClipTags) to firstUnit + 2, and
    /// sets the clipmap uniforms of common_clip_layout.glsl. With a `prefix` ("uElev") every name's leading "u" is
    /// replaced by it (uElevClip, uElevClipTags, uElevLevel0Size, ...), so two clipmaps can feed one program.
    /// Units used: 3.
    void bind(const gl::ShaderProgram& program, int firstUnit = 0, const std::string& prefix = "u") const;
    /// The layout bind() sets as uniforms that shaders divide by, as preprocessor definitions for a program built for
    /// this clipmap: PREFIX + BLOCK_SIZE, SLOTS_PER_SIDE and SIZE (shaders/common_clip_layout.glsl; llvmpipe divides
    /// by a constant with a multiply and a shift, by a uniform lane by lane).
    std::vector<std::string> layoutDefines(const std::string& prefix = "CLIP_") const;
    /// Rgba8 pyramids: RGBA8 levels, each layer's coarse pyramid mipmapped at its array layer. R32F (elevation):
    /// R32F levels read with texelFetch, and the coarse pyramid's exact levels as array layers (layer i's level
    /// clip levels + k at i · (levels - clip levels) + k, stored from texel 0,0), since mipmaps would round sizes
    /// down where the pyramid rounds up.
    TexelFormat format() const { return m_format; }

    const ClipmapSchedule& schedule() const { return m_schedule; }
    int layers() const { return m_layers; }
    /// GPU bytes of all clipmap textures (toroidal levels, coarse pyramids with mips, tags).
    std::int64_t residentBytes() const;
    std::int64_t loaderCacheBytes() const { return m_source->cacheBytes(); }
    /// Where the loader reads blocks (thread-safe): layers derived from the imagery read it too, through the same
    /// tile cache (foliage/CanopyClipmapGL.h).
    BlockSource& blockSource() const { return *m_source; }
    /// Texels handed to glTextureSubImage3D for the toroidal levels since creation, counted at each call (apart from
    /// the per-frame ClipmapFrameStats, so the bench can check the two agree).
    std::int64_t totalTexelsUploaded() const { return m_totalUploaded; }
    glm::ivec2 imageSize() const { return m_schedule.layout().levelSizes[0]; }

private:
    ClipmapGL(ClipmapLayout layout, const ClipmapOptions& options);
    int uploadReady(std::int64_t budget, ClipmapFrameStats& stats);

    ClipmapOptions m_options;
    ClipmapSchedule m_schedule;
    std::unique_ptr<BlockSource> m_source;
    std::unique_ptr<BlockLoader> m_loader;
    gl::Texture m_clip, m_coarse; // every layer's levels in one array texture each (bind())
    int m_layers = 0, m_layerStride = 1; // layers; array layers per layer in m_clip
    gl::Texture m_tags;
    std::optional<ReadError> m_readError;
    TexelFormat m_format = TexelFormat::Rgba8;
    int m_coarseLevels = 0; // mip levels (Rgba8) or array layers (R32F) of each coarse texture
    glm::ivec2 m_coarseSize{0};
    std::int64_t m_totalUploaded = 0;
    std::int64_t m_streamErrors = 0;
    std::string m_lastStreamError;
    bool m_streaming = false;
};

} // namespace seasonview
