#pragma once
// The derived canopy layer of the imagery clipmaps (Ropinski et al. 2007 §4.1-4.2): for every texel of every clip
// level (and of the resident coarse pyramid's base), how many of the N stacked canopy layers it belongs to. The
// seasonal rule (SegmentationRule.h) runs once per block, only for the blocks newly exposed, so each canopy fragment
// costs one fetch: by default on the CPU (CanopyDerive.h), on a block loader's workers that read both seasons' texels
// around the block through the imagery clipmap's source, the render thread only uploading a byte per texel; or on the
// GPU (shaders/canopy_derive.comp, the same bytes) once a block of both seasons has been uploaded together with its
// eight neighbours (the vote and the texture test reach into them). Layer i votes over k_i × k_i texels, k growing
// from the method's k at the ground layer to `topK` at the top (§4.2), so crowns narrow towards their tops; on
// coarser levels k shrinks with the texel size (about the same metres). Validity per block through its own tag
// texture, like the imagery: a block not derived yet falls back to the next coarser level.
#include "BlockLoader.h"
#include "CanopyDerive.h"
#include "ClipmapGL.h"
#include "ClipmapTerrainRendererGL.h" // CanopySource
#include "Segmentation.h"
#include "gl/GlObjects.h"
#include "gl/ShaderProgram.h"

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace seasonview {

struct CanopyOptions {
    SegmentationParams params;   // method and the ground layer's k
    int layers = 16;             // N stacked layers (1..32)
    int topK = 0;                // k of the top layer (odd, <= kSegMaxK); 0 = min(kSegMaxK, 3 k)
    int blocksPerFrame = 256;    // derivation budget per update()
    // update() derives the blocks of levels finer than keepLevelsFrom() only where canopy lookups read them: the
    // canopy view's ground and march record, per pixel, the block each lookup starts at and each coarser one under it
    // that it falls back past, where that block is not derived (shaders/common_view.glsl, canopyAtNoting; read back
    // without waiting), the rasterised layers through noteRead(); a block none
    // read in the last readWindow frames waits
    // (a lookup falls back to the next coarser level meanwhile, as for any block not derived yet). Until the first
    // record is back every block is derived. false: every block. Unset: on demand only where the blocks are derived
    // on the GPU, whose derivation the frame pays for; derived on the CPU every block costs the frame less than the
    // lookups' records and fallbacks (docs/performance.md).
    std::optional<bool> onDemand;
    int readWindow = 30;
    CanopyDerivation derivation = CanopyDerivation::Auto;
    int cpuWorkers = 2;          // Cpu: the loader's threads deriving blocks
    // Cpu: the layer precomputed for these parameters (foliage/CanopyPyramid.h, canopyPyramidSource() of the imagery
    // clipmap's two pyramids): the loader reads its clip levels' blocks, a byte per texel, instead of deriving them.
    std::optional<ImagePyramid> precomputed;
};

struct CanopyFrameStats {
    int blocksDerived = 0;
    int blocksPending = 0;       // resident in both seasons but waiting for a neighbour or the budget
    int blocksUnread = 0;        // onDemand: resident, but no lookup read them lately: not derived
    int blocksOnDemand = 0;      // onDemand: of blocksDerived, those on levels finer than keepLevelsFrom() (read)
    // Cpu: blocksDerived are the blocks uploaded this frame; blocksPending those asked of the loader and not back.
};

class CanopyClipmapGL : public CanopySource {
public:
    /// `source`: the imagery clipmap, layer 0 leaf-on, layer 1 leaf-off (kept by reference). `stats`: the pair's
    /// statistics (tables, drop threshold) for params.method. Derives the coarse base at once.
    static Result<std::unique_ptr<CanopyClipmapGL>> create(const ClipmapGL& source, const SegmentationStats& stats,
                                                          const CanopyOptions& options = {});

    /// After the source's update(): derives the blocks that became derivable, finest level first, within the
    /// budget; blocks whose slot the source reused are invalid at once (their tag no longer matches).
    CanopyFrameStats update();
    /// Derives every derivable block (stills, tests).
    CanopyFrameStats completeSynchronously();
    /// Re-derives everything resident (the per-frame mode: what evaluating the rule every frame costs).
    CanopyFrameStats rederiveAll();

    /// Levels from `level` up are derived whether read or not (onDemand): a pass that reads a whole level (the
    /// trunks' crown search, TrunksGL::level()) and the coarser ones.
    void keepLevelsFrom(int level) { m_keepFrom = level; }

    /// Records that lookups at `level` read the level-0 pixel box [lo, hi] (onDemand): the blocks under it on this
    /// and every coarser clip level, as the shaders' record does for theirs. For passes whose depth test must stay
    /// early, where a fragment shader that writes a buffer would make it late (the rasterised canopy layers: their
    /// level and box are known per patch on the CPU).
    void noteRead(int level, glm::dvec2 lo, glm::dvec2 hi) const;

    /// Binds uCanopyClip (usampler2DArray), uCanopyCoarse (usampler2D) and uCanopyTags (isampler2DArray) to units
    /// firstUnit .. firstUnit + 2, sets uCanopyLayers (common_canopy.glsl) and binds the record of the blocks read
    /// (kCanopyReadsBinding).
    void bind(const gl::ShaderProgram& program, int firstUnit) const override;

    const CanopyOptions& options() const { return m_options; }
    /// Whether the clip levels' blocks are derived on the CPU (options().derivation resolved).
    bool derivesOnCpu() const { return m_cpu != nullptr; }
    /// Whether the loader reads the clip levels' blocks from the precomputed layer (CanopyOptions::precomputed).
    bool readsPrecomputed() const { return m_precomputed; }
    /// Keeps a copy of clip level `level` on the CPU from now on (the trunks' crown search on the CPU, TrunksGL):
    /// blocks derived on the CPU are copied as they are uploaded; after a derivation on the GPU the copy is read back
    /// when next asked for. Const: the trunks hold the layer by const reference.
    void keepCopyOf(int level) const;
    /// The copy of the level keepCopyOf() named: N × N values stored as the texture stores them (texel q at q mod N);
    /// slotTags(level) says which blocks are derived.
    const std::vector<std::uint8_t>& levelCopy() const;
    /// Whether blocks finer than keepLevelsFrom() wait until a lookup reads them (options().onDemand resolved).
    bool onDemand() const { return m_onDemand; }
    /// Cpu: the first block whose imagery could not be read (one line naming the file; "" when none). Such a block
    /// is never derived (lookups fall back to coarser levels); a still must not be written with it missing.
    const std::string& readError() const { return m_readError; }
    /// Toroidal clip levels; level clipLevels() is the coarse base.
    int clipLevels() const { return m_source.schedule().layout().clipLevels(); }
    /// k of layer `layer` on clip level `level` (odd, >= 1; `pixel`: 1).
    int layerK(int layer, int level) const;
    /// The block derived in each slot, per clip level, row-major (ClipmapSchedule's tags; kEmptyTag: none).
    const std::vector<std::int32_t>& slotTags(int level) const { return m_tags[size_t(level)]; }
    /// The toroidal canopy level `level` as stored (N×N, texel q at (q mod N)); tests.
    std::vector<std::uint8_t> readClipLevel(int level) const;
    std::vector<std::uint8_t> readCoarse() const;
    std::int64_t residentBytes() const;
    /// The largest canopy value any level could give a fragment inside the level-0 image pixel box [lo, hi]: the
    /// maxima of the derived blocks it overlaps on every clip level and the coarse base, read back from the
    /// derivation without waiting for it (collected by update()); options().layers where a block's maximum is not
    /// back yet or the box
    /// spans too many blocks to look at.
    int maxValueOver(glm::dvec2 lo, glm::dvec2 hi) const;
    /// The same for fragments that read clip level clamp(their level, minLevel, maxLevel) (the coarse base is level
    /// clipLevels()) or, where that is not derived, the first coarser one derived: the maxima of the 8×8-texel cells
    /// they may read there.
    int maxValueOver(glm::dvec2 lo, glm::dvec2 hi, int minLevel, int maxLevel) const;
    std::int64_t totalBlocksDerived() const { return m_totalDerived; }

private:
    CanopyClipmapGL(const ClipmapGL& source, const CanopyOptions& options) : m_source(source), m_options(options) {}
public:
    ~CanopyClipmapGL() override;
    CanopyClipmapGL(const CanopyClipmapGL&) = delete;
    CanopyClipmapGL& operator=(const CanopyClipmapGL&) = delete;
private:
    bool derivable(int level, int bx, int by) const;
    // Runs the compute shader over `blocks` of `level` (coarse: the coarse base).
    void derive(int level, bool coarse, const std::vector<glm::ivec2>& blocks);
    CanopyFrameStats run(int budget, bool everything, bool onDemand = false);
    // Cpu: asks the loader for the window's blocks not derived yet (finest level first, nearest the centre first;
    // onDemand: only those read lately) and uploads those it has finished, at most `budget`; `wait`: until every
    // block is in (stills).
    CanopyFrameStats runCpu(int budget, bool onDemand, bool wait);
    // Cpu: the blocks of the windows not derived yet that the loader should read.
    std::vector<BlockKey> wantedBlocks(bool onDemand, int& unread) const;
    // Cpu: uploads a derived block into its slot, its cell maxima straight into the CPU's view of them.
    void store(const LoadedBlock& block);
    std::unique_ptr<BlockSource> m_cpuSource;
    bool m_precomputed = false;
    std::unique_ptr<BlockLoader> m_cpu;
    std::string m_readError;
    bool m_onDemand = false;
    mutable int m_copyLevel = -1;
    mutable bool m_copyStale = false;
    mutable std::vector<std::uint8_t> m_copy;
    // The blocks read (onDemand): takes the record copied after an earlier frame when its fence has signalled, then
    // copies the last frame's and clears it for the next.
    void collectReads();
    // Whether a lookup read block `tag` of `level` (in `slot`) lately, or the level is kept whole.
    bool wanted(int level, size_t slot, std::int32_t tag) const;
    // The record (shaders/common_view.glsl, canopyAtNoting): per clip level, per slot, the block read there.
    gl::Buffer m_reads, m_readsReadback;
    const std::int32_t* m_readsMapped = nullptr;
    GLsync m_readsFence = nullptr;
    // Per clip level, per slot: the block last read there, and the frame its record came back (noteRead() records
    // from const draws).
    mutable std::vector<std::vector<std::int32_t>> m_readTag;
    mutable std::vector<std::vector<std::int64_t>> m_readFrame;
    std::int64_t m_frame = 0;
    bool m_readsBack = false; // a record has come back
    int m_keepFrom = 1 << 20;

    const ClipmapGL& m_source;
    CanopyOptions m_options;
    SegmentationStats m_stats;
    int m_topK = 0;
    gl::ShaderProgram m_programs[2]; // canopy_derive.comp: the clip levels, the coarse base
    gl::Texture m_clip, m_coarse, m_tagTexture;
    gl::Buffer m_blocks, m_luts;
    // Cell maxima: GPU buffer (clip levels' slots, then the coarse base's blocks), a persistently mapped copy
    // taken after each derivation with a fence, and the CPU's view of them (-1: not back yet).
    // Takes the copy in flight when its fence has signalled (or waits for it), then copies again if blocks were
    // derived since; update() and the others call it, so maxValueOver sees the maxima a frame late at most.
    void collectMaxima(bool wait);
    int maxIndex(int level, int slot) const { return level * m_slotCount + slot; }
    gl::Buffer m_cellMaxBuffer, m_maxReadback;
    const std::uint8_t* m_maxMapped = nullptr;
    GLsync m_maxFence = nullptr;
    std::vector<int> m_maxKnown;           // per block: its largest value, -1 while not back
    std::vector<std::uint8_t> m_cellMax;   // per block, per cell (row-major, m_cellsPerSide²): the cell's largest value
    int m_cellsPerSide = 8;
    std::vector<std::uint64_t> m_maxGeneration; // derivation generation of each entry
    std::uint64_t m_generation = 0, m_fenceGeneration = 0, m_collectedGeneration = 0;
    int m_slotCount = 0, m_coarseBlocksX = 0;
    std::vector<std::vector<std::int32_t>> m_tags; // per clip level, per slot: the block derived there
    int m_arrayLayers = 1;
    std::int64_t m_totalDerived = 0;
};

} // namespace seasonview
