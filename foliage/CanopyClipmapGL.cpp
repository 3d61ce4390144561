#include "CanopyClipmapGL.h"

#include "CanopyPyramid.h"
#include "ToroidalWindow.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

namespace seasonview {

namespace {
constexpr int kTile = 32;            // output tile of one work group (canopy_derive.comp)
constexpr int kCell = 8;             // texels per side of a cell with its own maximum (canopy_derive.comp CELL)
constexpr int kMaxDispatchBlocks = 4096;
constexpr int kMaxLayers = 32;       // uLayerK[32]
std::int32_t blockTag(int bx, int by) { return bx | (by << 16); }
// The blocks of clip level `level`'s window inside its image: [x0, x1) × [y0, y1) in block coordinates.
TexelRect windowBlocks(const ClipmapSchedule& s, int level) {
    const ClipmapLayout& L = s.layout();
    const TexelRect& w = s.window(level);
    const glm::ivec2 size = L.levelSizes[size_t(level)];
    return {std::max(0, w.x0 / L.block), std::max(0, w.y0 / L.block),
            std::min((size.x + L.block - 1) / L.block, (w.x1 + L.block - 1) / L.block),
            std::min((size.y + L.block - 1) / L.block, (w.y1 + L.block - 1) / L.block)};
}
// The texels of clip level `level` that nearest-texel fetches at level-0 pixel positions in [lo, hi] read (floor),
// clamped to the level like the shaders' fetches: first and last.
std::pair<glm::ivec2, glm::ivec2> texelsOver(const ClipmapLayout& L, int level, glm::dvec2 lo, glm::dvec2 hi) {
    const double texel = std::ldexp(1.0, level); // level-0 pixels per texel of this level
    const glm::ivec2 size = L.levelSizes[size_t(level)];
    return {glm::clamp(glm::ivec2(glm::floor(lo / texel)), glm::ivec2(0), size - 1),
            glm::clamp(glm::ivec2(glm::floor(hi / texel)), glm::ivec2(0), size - 1)};
}

// The canopy values of clip-level blocks, derived on the loader's workers (CanopyDerive.h): both seasons' texels of
// the block and its halo read through the imagery clipmap's own source (its tile cache), a byte per texel out.
class CanopyBlockSource final : public BlockSource {
public:
    CanopyBlockSource(BlockSource& imagery, ClipmapLayout layout, SegmentationMethod method, SegmentationStats stats,
                      std::vector<std::vector<CanopyGroup>> groups)
        : m_imagery(imagery), m_layout(std::move(layout)), m_method(method), m_stats(stats),
          m_groups(std::move(groups)) {}
    int layers() const override { return 1; }
    int bytesPerTexel() const override { return 1; }
    bool streamed(int, int level) const override { return m_imagery.streamed(0, level) || m_imagery.streamed(1, level); }
    Status read(int, int level, const TexelRect& t, std::uint8_t* values) override {
        const std::vector<CanopyGroup>& groups = m_groups[size_t(level)];
        const int halo = canopyDeriveHalo(m_method, groups);
        const glm::ivec2 size = m_layout.levelSizes[size_t(level)];
        const TexelRect r{std::max(0, t.x0 - halo), std::max(0, t.y0 - halo), std::min(size.x, t.x1 + halo),
                          std::min(size.y, t.y1 + halo)};
        thread_local std::vector<std::uint8_t> on, off;
        on.resize(size_t(r.area()) * 4);
        off.resize(on.size());
        if (Status st = m_imagery.read(0, level, r, on.data()); !st) return st;
        if (Status st = m_imagery.read(1, level, r, off.data()); !st) return st;
        deriveCanopyTexels(on.data(), off.data(), r, size, t, m_method, m_stats, groups, values);
        return Ok{};
    }

private:
    BlockSource& m_imagery;
    ClipmapLayout m_layout;
    SegmentationMethod m_method;
    SegmentationStats m_stats;
    std::vector<std::vector<CanopyGroup>> m_groups; // per clip level
};
} // namespace

Result<std::unique_ptr<CanopyClipmapGL>> CanopyClipmapGL::create(const ClipmapGL& source, const SegmentationStats& stats,
                                                                 const CanopyOptions& options) {
    assert(source.layers() >= 2 && source.format() == TexelFormat::Rgba8 && "CanopyClipmapGL: needs two seasons of RGB");
    if (options.layers < 1 || options.layers > kMaxLayers)
        return Error{"canopy layers must be 1.." + std::to_string(kMaxLayers) + ", got " + std::to_string(options.layers)};
    const int k = effectiveK(options.params);
    if (k < 1 || k > kSegMaxK || k % 2 == 0)
        return Error{"segmentation k must be odd and 1.." + std::to_string(kSegMaxK) + ", got " + std::to_string(k)};
    const ClipmapLayout& L = source.schedule().layout();
    assert(L.block % kTile == 0 && "CanopyClipmapGL: the block must be a multiple of the work group's tile");
    auto c = std::unique_ptr<CanopyClipmapGL>(new CanopyClipmapGL(source, options));
    c->m_stats = stats;
    const int top = canopyTopK(options.params, options.topK);
    c->m_topK = top;

    for (int coarse : {0, 1}) {
        // The method, the pass and the imagery clipmap's layout are compile-time constants (shaders/canopy_derive.comp).
        std::vector<std::string> defines = source.layoutDefines("CLIP_");
        defines.push_back("COARSE_PASS " + std::to_string(coarse));
        defines.push_back("METHOD " + std::to_string(int(options.params.method)));
        auto p = gl::ShaderProgram::buildCompute("canopy_derive.comp", defines);
        if (!p) return p.error();
        c->m_programs[coarse] = std::move(*p);
    }

    const int clipLevels = L.clipLevels();
    const int slots = source.schedule().slotsPerSide();
    c->m_arrayLayers = std::max(1, clipLevels);
    c->m_clip = gl::Texture::create(GL_TEXTURE_2D_ARRAY);
    glTextureStorage3D(c->m_clip.id(), 1, GL_R8UI, L.size, L.size, c->m_arrayLayers);
    const GLuint zero = 0;
    glClearTexImage(c->m_clip.id(), 0, GL_RED_INTEGER, GL_UNSIGNED_INT, &zero);
    const glm::ivec2 coarse = L.levelSizes[size_t(clipLevels)];
    c->m_coarse = gl::Texture::create(GL_TEXTURE_2D);
    glTextureStorage2D(c->m_coarse.id(), 1, GL_R8UI, coarse.x, coarse.y);
    glClearTexImage(c->m_coarse.id(), 0, GL_RED_INTEGER, GL_UNSIGNED_INT, &zero);
    c->m_tagTexture = gl::Texture::create(GL_TEXTURE_2D_ARRAY);
    glTextureStorage3D(c->m_tagTexture.id(), 1, GL_R32I, slots, slots, c->m_arrayLayers);
    const GLint empty = ClipmapSchedule::kEmptyTag;
    glClearTexImage(c->m_tagTexture.id(), 0, GL_RED_INTEGER, GL_INT, &empty);
    for (const gl::Texture* t : {&c->m_clip, &c->m_coarse, &c->m_tagTexture}) {
        glTextureParameteri(t->id(), GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        glTextureParameteri(t->id(), GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    }
    c->m_tags.assign(size_t(clipLevels), std::vector<std::int32_t>(size_t(slots) * size_t(slots), ClipmapSchedule::kEmptyTag));

    std::vector<std::uint32_t> luts(6 * 256);
    for (int ch = 0; ch < 3; ++ch)
        for (int v = 0; v < 256; ++v) {
            luts[size_t(ch * 256 + v)] = stats.lutOn[size_t(ch)][size_t(v)];
            luts[size_t(768 + ch * 256 + v)] = stats.lutOff[size_t(ch)][size_t(v)];
        }
    c->m_luts = gl::Buffer::create();
    glNamedBufferStorage(c->m_luts.id(), GLsizeiptr(luts.size() * 4), luts.data(), 0);
    c->m_blocks = gl::Buffer::create();
    glNamedBufferStorage(c->m_blocks.id(), kMaxDispatchBlocks * 16, nullptr, GL_DYNAMIC_STORAGE_BIT);

    // Cell maxima (a byte per kCell² texels) of every slot of every clip level, then of the coarse base's blocks.
    c->m_slotCount = slots * slots;
    c->m_coarseBlocksX = (coarse.x + L.block - 1) / L.block;
    c->m_cellsPerSide = L.block / kCell;
    const size_t cellsPerBlock = size_t(c->m_cellsPerSide) * size_t(c->m_cellsPerSide);
    const int coarseBlocks = c->m_coarseBlocksX * ((coarse.y + L.block - 1) / L.block);
    const size_t entries = size_t(clipLevels) * size_t(c->m_slotCount) + size_t(coarseBlocks);
    const size_t bytes = entries * cellsPerBlock;
    const std::vector<std::uint8_t> zeros(bytes, 0);
    c->m_cellMaxBuffer = gl::Buffer::create();
    glNamedBufferStorage(c->m_cellMaxBuffer.id(), GLsizeiptr(bytes), zeros.data(), GL_DYNAMIC_STORAGE_BIT);
    c->m_maxReadback = gl::Buffer::create();
    const GLbitfield mapFlags = GL_MAP_READ_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT;
    glNamedBufferStorage(c->m_maxReadback.id(), GLsizeiptr(bytes), nullptr, mapFlags);
    c->m_maxMapped = static_cast<const std::uint8_t*>(
        glMapNamedBufferRange(c->m_maxReadback.id(), 0, GLsizeiptr(bytes), mapFlags));
    if (!c->m_maxMapped) return Error{"canopy layer: cannot map the cell maxima's readback buffer"};
    // (At least one entry: a scene small enough for no toroidal level records nothing.)
    const std::vector<std::int32_t> noReads(std::max<size_t>(1, size_t(clipLevels) * size_t(c->m_slotCount)),
                                            ClipmapSchedule::kEmptyTag);
    c->m_reads = gl::Buffer::create();
    glNamedBufferStorage(c->m_reads.id(), GLsizeiptr(noReads.size() * 4), noReads.data(), GL_DYNAMIC_STORAGE_BIT);
    c->m_readsReadback = gl::Buffer::create();
    glNamedBufferStorage(c->m_readsReadback.id(), GLsizeiptr(noReads.size() * 4), nullptr, mapFlags);
    c->m_readsMapped = static_cast<const std::int32_t*>(
        glMapNamedBufferRange(c->m_readsReadback.id(), 0, GLsizeiptr(noReads.size() * 4), mapFlags));
    if (!c->m_readsMapped) return Error{"canopy layer: cannot map the read blocks' readback buffer"};
    c->m_readTag.assign(size_t(clipLevels), std::vector<std::int32_t>(size_t(c->m_slotCount), ClipmapSchedule::kEmptyTag));
    c->m_readFrame.assign(size_t(clipLevels), std::vector<std::int64_t>(size_t(c->m_slotCount), 0));
    c->m_maxKnown.assign(entries, -1);
    c->m_cellMax.assign(bytes, 0);
    c->m_maxGeneration.assign(entries, 0);

    // The coarse base is resident whole: derive all of it now.
    std::vector<glm::ivec2> blocks;
    for (int by = 0; by * L.block < coarse.y; ++by)
        for (int bx = 0; bx * L.block < coarse.x; ++bx) blocks.push_back({bx, by});
    c->derive(clipLevels, true, blocks);
    c->collectMaxima(true);

    const bool cpu = options.derivation == CanopyDerivation::Cpu ||
                     (options.derivation == CanopyDerivation::Auto && !source.streaming());
    if (cpu && clipLevels > 0) {
        std::vector<std::vector<CanopyGroup>> groups;
        for (int level = 0; level < clipLevels; ++level)
            groups.push_back(canopyGroups(options.params, options.layers, top, level));
        if (const std::optional<ImagePyramid>& p = options.precomputed) {
            assert(p->format == TexelFormat::R8 && int(p->levels.size()) > clipLevels &&
                   p->levels[0].width == L.levelSizes[0].x && p->levels[0].height == L.levelSizes[0].y &&
                   "CanopyClipmapGL: the precomputed canopy of the imagery clipmap's pyramids");
            c->m_cpuSource = std::make_unique<PyramidBlockSource>(pyramidLevelFiles({*p}), 64, TexelFormat::R8);
            c->m_precomputed = true;
        } else {
            c->m_cpuSource = std::make_unique<CanopyBlockSource>(source.blockSource(), L, options.params.method, stats,
                                                                 std::move(groups));
        }
        c->m_cpu = std::make_unique<BlockLoader>(*c->m_cpuSource, source.schedule(), 16 << 20,
                                                 std::max(1, options.cpuWorkers));
    }
    c->m_onDemand = options.onDemand.value_or(!c->m_cpu);
    return c;
}

int CanopyClipmapGL::layerK(int layer, int level) const {
    return canopyLayerK(m_options.params, m_options.layers, m_topK, layer, level);
}

bool CanopyClipmapGL::derivable(int level, int bx, int by) const {
    const ClipmapSchedule& s = m_source.schedule();
    const ClipmapLayout& L = s.layout();
    const glm::ivec2 size = L.levelSizes[size_t(level)];
    const int nbx = (size.x + L.block - 1) / L.block, nby = (size.y + L.block - 1) / L.block;
    const int slots = s.slotsPerSide();
    const auto& tags = s.slotTags(level);
    for (int y = by - 1; y <= by + 1; ++y)
        for (int x = bx - 1; x <= bx + 1; ++x) {
            if (x < 0 || y < 0 || x >= nbx || y >= nby) continue; // outside the image: edge texels, in the block
            if (tags[size_t(wrapTexel(y, slots)) * size_t(slots) + size_t(wrapTexel(x, slots))] != blockTag(x, y))
                return false;
        }
    return true;
}

CanopyClipmapGL::~CanopyClipmapGL() {
    if (m_maxFence) glDeleteSync(m_maxFence);
    if (m_maxMapped) glUnmapNamedBuffer(m_maxReadback.id());
    if (m_readsFence) glDeleteSync(m_readsFence);
    if (m_readsMapped) glUnmapNamedBuffer(m_readsReadback.id());
}

void CanopyClipmapGL::collectReads() {
    ++m_frame;
    if (!m_onDemand) return; // every block is derived: nothing to read back
    const size_t levels = m_readTag.size(), slots = size_t(m_slotCount);
    if (m_readsFence) {
        const GLenum r = glClientWaitSync(m_readsFence, 0, 0);
        if (r == GL_ALREADY_SIGNALED || r == GL_CONDITION_SATISFIED) {
            glDeleteSync(m_readsFence);
            m_readsFence = nullptr;
            for (size_t l = 0; l < levels; ++l)
                for (size_t i = 0; i < slots; ++i) {
                    const std::int32_t tag = m_readsMapped[l * slots + i];
                    if (tag == ClipmapSchedule::kEmptyTag) continue;
                    m_readTag[l][i] = tag;
                    m_readFrame[l][i] = m_frame;
                }
            m_readsBack = true;
        }
    }
    if (!m_readsFence && levels > 0) {
        // The buffer holds what the frames since the last copy read (update() runs before a frame's draws).
        glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_CLIENT_MAPPED_BUFFER_BARRIER_BIT);
        glCopyNamedBufferSubData(m_reads.id(), m_readsReadback.id(), 0, 0, GLsizeiptr(levels * slots * 4));
        m_readsFence = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
        const GLint empty = ClipmapSchedule::kEmptyTag;
        glClearNamedBufferData(m_reads.id(), GL_R32I, GL_RED_INTEGER, GL_INT, &empty);
    }
}

void CanopyClipmapGL::noteRead(int level, glm::dvec2 lo, glm::dvec2 hi) const {
    const ClipmapSchedule& s = m_source.schedule();
    const ClipmapLayout& L = s.layout();
    const int slots = s.slotsPerSide();
    for (int l = std::max(level, 0); l < std::min(L.clipLevels(), m_keepFrom); ++l) {
        const auto [t0, t1] = texelsOver(L, l, lo, hi);
        const glm::ivec2 b0 = t0 / L.block, b1 = t1 / L.block;
        if ((b1.x - b0.x + 1) * (b1.y - b0.y + 1) > slots * slots) continue; // wider than the level's window
        for (int by = b0.y; by <= b1.y; ++by)
            for (int bx = b0.x; bx <= b1.x; ++bx) {
                const size_t slot = size_t(wrapTexel(by, slots)) * size_t(slots) + size_t(wrapTexel(bx, slots));
                m_readTag[size_t(l)][slot] = blockTag(bx, by);
                m_readFrame[size_t(l)][slot] = m_frame;
            }
    }
}

bool CanopyClipmapGL::wanted(int level, size_t slot, std::int32_t tag) const {
    if (level >= m_keepFrom) return true;
    return m_readTag[size_t(level)][slot] == tag &&
           m_frame - m_readFrame[size_t(level)][slot] <= std::int64_t(std::max(m_options.readWindow, 1));
}

void CanopyClipmapGL::collectMaxima(bool wait) {
    for (int round = 0; round < 2; ++round) {
        if (m_maxFence) {
            const GLenum r = glClientWaitSync(m_maxFence, wait ? GL_SYNC_FLUSH_COMMANDS_BIT : 0,
                                              wait ? GLuint64(10'000'000'000) : 0);
            if (r != GL_ALREADY_SIGNALED && r != GL_CONDITION_SATISFIED) return; // not back yet: next time
            glDeleteSync(m_maxFence);
            m_maxFence = nullptr;
            // Entries derived again after the copy keep waiting for the next one.
            const size_t cells = size_t(m_cellsPerSide) * size_t(m_cellsPerSide);
            for (size_t i = 0; i < m_maxKnown.size(); ++i)
                if (m_maxGeneration[i] <= m_fenceGeneration && m_maxGeneration[i] > m_collectedGeneration) {
                    const std::uint8_t* src = m_maxMapped + i * cells;
                    std::copy(src, src + cells, m_cellMax.begin() + std::ptrdiff_t(i * cells));
                    m_maxKnown[i] = *std::max_element(src, src + cells);
                }
            m_collectedGeneration = m_fenceGeneration;
        }
        if (m_generation <= m_collectedGeneration) return;
        // Something derived since the last copy: copy again (the fence tells when it has landed).
        glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_CLIENT_MAPPED_BUFFER_BARRIER_BIT);
        glCopyNamedBufferSubData(m_cellMaxBuffer.id(), m_maxReadback.id(), 0, 0, GLsizeiptr(m_cellMax.size()));
        m_maxFence = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
        m_fenceGeneration = m_generation;
        if (!wait) return;
    }
}

int CanopyClipmapGL::maxValueOver(glm::dvec2 lo, glm::dvec2 hi) const {
    return maxValueOver(lo, hi, 0, m_source.schedule().layout().clipLevels());
}

int CanopyClipmapGL::maxValueOver(glm::dvec2 lo, glm::dvec2 hi, int minLevel, int maxLevel) const {
    const ClipmapSchedule& s = m_source.schedule();
    const ClipmapLayout& L = s.layout();
    const int slots = s.slotsPerSide(), all = m_options.layers;
    int m = 0;
    bool coarser = false; // a block of the last level scanned was not derived: fragments there read a coarser one
    for (int level = std::clamp(minLevel, 0, L.clipLevels()); level <= L.clipLevels(); ++level) {
        if (level > maxLevel && !coarser) break;
        coarser = false;
        const bool coarse = level == L.clipLevels();
        const auto [t0, t1] = texelsOver(L, level, lo, hi); // what a fragment in the box may read here
        const glm::ivec2 b0 = t0 / L.block, b1 = t1 / L.block;
        if ((b1.x - b0.x + 1) * (b1.y - b0.y + 1) > 256) return all;
        for (int by = b0.y; by <= b1.y; ++by)
            for (int bx = b0.x; bx <= b1.x; ++bx) {
                int index = 0;
                if (coarse) {
                    index = maxIndex(L.clipLevels(), 0) + by * m_coarseBlocksX + bx;
                } else {
                    const int slot = wrapTexel(by, slots) * slots + wrapTexel(bx, slots);
                    if (m_tags[size_t(level)][size_t(slot)] != blockTag(bx, by)) { // not derived here
                        coarser = true;
                        continue;
                    }
                    index = maxIndex(level, slot);
                }
                const int v = m_maxKnown[size_t(index)];
                if (v < 0) return all;
                if (v <= m) continue;
                // The cells of the block inside the box.
                const glm::ivec2 origin = glm::ivec2(bx, by) * L.block;
                const glm::ivec2 c0 = (glm::max(t0, origin) - origin) / kCell;
                const glm::ivec2 c1 = (glm::min(t1, origin + L.block - 1) - origin) / kCell;
                const std::uint8_t* cells =
                    m_cellMax.data() + size_t(index) * size_t(m_cellsPerSide) * size_t(m_cellsPerSide);
                for (int cy = c0.y; cy <= c1.y; ++cy)
                    for (int cx = c0.x; cx <= c1.x; ++cx) m = std::max(m, int(cells[cy * m_cellsPerSide + cx]));
                if (m >= all) return all;
            }
    }
    return m;
}

void CanopyClipmapGL::derive(int level, bool coarse, const std::vector<glm::ivec2>& blocks) {
    if (blocks.empty()) return;
    const ClipmapLayout& L = m_source.schedule().layout();
    const int slots = m_source.schedule().slotsPerSide();
    ++m_generation;
    if (!coarse && level == m_copyLevel) m_copyStale = true; // read back when next asked for
    const gl::ShaderProgram& program = m_programs[coarse ? 1 : 0];
    m_source.bind(program, 0);
    program.set("uLevel", level);
    program.set("uBlockSize", L.block);
    program.set("uDropThreshold", m_stats.dropThreshold);
    // The layers grouped by k (canopy_derive.comp's uGroupK): per group its k and its last layer + 1.
    const std::vector<CanopyGroup> groups = canopyGroups(m_options.params, m_options.layers, m_topK, level);
    for (size_t g = 0; g < groups.size(); ++g) {
        const std::string name = "uGroupK[" + std::to_string(g) + "]";
        glProgramUniform2i(program.id(), program.location(name.c_str()), groups[g].k, groups[g].top);
    }
    program.set("uGroups", int(groups.size()));
    glBindImageTexture(0, m_clip.id(), 0, GL_TRUE, 0, GL_WRITE_ONLY, GL_R8UI);
    glBindImageTexture(1, m_coarse.id(), 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_R8UI);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, m_blocks.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, m_luts.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, m_cellMaxBuffer.id());
    program.use();
    for (size_t first = 0; first < blocks.size(); first += kMaxDispatchBlocks) {
        const size_t n = std::min(blocks.size() - first, size_t(kMaxDispatchBlocks));
        std::vector<glm::ivec4> list(n);
        for (size_t i = 0; i < n; ++i) {
            const glm::ivec2 b = blocks[first + i];
            const int index = coarse ? maxIndex(L.clipLevels(), 0) + b.y * m_coarseBlocksX + b.x
                                     : maxIndex(level, wrapTexel(b.y, slots) * slots + wrapTexel(b.x, slots));
            list[i] = {b.x, b.y, level, index};
            m_maxKnown[size_t(index)] = -1;
            m_maxGeneration[size_t(index)] = m_generation;
        }
        glNamedBufferSubData(m_blocks.id(), 0, GLsizeiptr(n * sizeof(glm::ivec4)), list.data());
        glDispatchCompute(GLuint(L.block / kTile), GLuint(L.block / kTile), GLuint(n));
        // The next dispatch rewrites the block list; fetches and readbacks must see the stores.
        glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_SHADER_IMAGE_ACCESS_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT |
                        GL_TEXTURE_UPDATE_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT);
    }
    m_totalDerived += std::int64_t(blocks.size());
}

CanopyFrameStats CanopyClipmapGL::run(int budget, bool everything, bool onDemand) {
    CanopyFrameStats st;
    const ClipmapSchedule& s = m_source.schedule();
    const ClipmapLayout& L = s.layout();
    const int slots = s.slotsPerSide();
    for (int level = 0; level < L.clipLevels(); ++level) {
        const TexelRect blocks = windowBlocks(s, level);
        const int bx0 = blocks.x0, by0 = blocks.y0, bx1 = blocks.x1, by1 = blocks.y1;
        std::vector<glm::ivec2> todo;
        for (int by = by0; by < by1; ++by)
            for (int bx = bx0; bx < bx1; ++bx) {
                const size_t slot = size_t(wrapTexel(by, slots)) * size_t(slots) + size_t(wrapTexel(bx, slots));
                if (!everything && m_tags[size_t(level)][slot] == blockTag(bx, by)) continue;
                if (s.slotTags(level)[slot] != blockTag(bx, by)) continue; // not uploaded yet
                if (onDemand && !wanted(level, slot, blockTag(bx, by))) { // no lookup reads it: wait until one does
                    ++st.blocksUnread;
                    continue;
                }
                if (!derivable(level, bx, by) || (!everything && st.blocksDerived + int(todo.size()) >= budget)) {
                    ++st.blocksPending;
                    continue;
                }
                todo.push_back({bx, by});
            }
        if (todo.empty()) continue;
        derive(level, false, todo);
        for (const glm::ivec2& b : todo)
            m_tags[size_t(level)][size_t(wrapTexel(b.y, slots)) * size_t(slots) + size_t(wrapTexel(b.x, slots))] =
                blockTag(b.x, b.y);
        glTextureSubImage3D(m_tagTexture.id(), 0, 0, 0, level, slots, slots, 1, GL_RED_INTEGER, GL_INT,
                            m_tags[size_t(level)].data());
        st.blocksDerived += int(todo.size());
        if (onDemand && level < m_keepFrom) st.blocksOnDemand += int(todo.size());
    }
    if (everything) {
        const glm::ivec2 coarse = L.levelSizes[size_t(L.clipLevels())];
        std::vector<glm::ivec2> blocks;
        for (int by = 0; by * L.block < coarse.y; ++by)
            for (int bx = 0; bx * L.block < coarse.x; ++bx) blocks.push_back({bx, by});
        derive(L.clipLevels(), true, blocks);
        st.blocksDerived += int(blocks.size());
    }
    return st;
}

CanopyFrameStats CanopyClipmapGL::update() {
    collectReads();
    const bool onDemand = m_onDemand && m_readsBack;
    const CanopyFrameStats st =
        m_cpu ? runCpu(m_options.blocksPerFrame, onDemand, false) : run(m_options.blocksPerFrame, false, onDemand);
    collectMaxima(false);
    return st;
}

CanopyFrameStats CanopyClipmapGL::completeSynchronously() {
    const CanopyFrameStats st = m_cpu ? runCpu(1 << 30, false, true) : run(1 << 30, false);
    collectMaxima(true);
    return st;
}

std::vector<BlockKey> CanopyClipmapGL::wantedBlocks(bool onDemand, int& unread) const {
    const ClipmapSchedule& s = m_source.schedule();
    const ClipmapLayout& L = s.layout();
    const int slots = s.slotsPerSide();
    std::vector<BlockKey> out;
    unread = 0;
    for (int level = 0; level < L.clipLevels(); ++level) {
        const TexelRect blocks = windowBlocks(s, level);
        const int bx0 = blocks.x0, by0 = blocks.y0, bx1 = blocks.x1, by1 = blocks.y1;
        const size_t first = out.size();
        for (int by = by0; by < by1; ++by)
            for (int bx = bx0; bx < bx1; ++bx) {
                const size_t slot = size_t(wrapTexel(by, slots)) * size_t(slots) + size_t(wrapTexel(bx, slots));
                if (m_tags[size_t(level)][slot] == blockTag(bx, by)) continue; // derived
                if (onDemand && !wanted(level, slot, blockTag(bx, by))) { // no lookup reads it: wait until one does
                    ++unread;
                    continue;
                }
                out.push_back({level, bx, by});
            }
        // Nearest the window's centre first, as the imagery's schedule asks for its blocks.
        const TexelRect& w = s.window(level);
        const glm::dvec2 centre(0.5 * (w.x0 + w.x1) / L.block - 0.5, 0.5 * (w.y0 + w.y1) / L.block - 0.5);
        std::stable_sort(out.begin() + std::ptrdiff_t(first), out.end(), [&](const BlockKey& a, const BlockKey& b) {
            const glm::dvec2 da = glm::dvec2(a.bx, a.by) - centre, db = glm::dvec2(b.bx, b.by) - centre;
            return da.x * da.x + da.y * da.y < db.x * db.x + db.y * db.y;
        });
    }
    return out;
}

void CanopyClipmapGL::store(const LoadedBlock& b) {
    const ClipmapLayout& L = m_source.schedule().layout();
    const int slots = m_source.schedule().slotsPerSide();
    const int level = b.key.level;
    const TexelRect& t = b.texels;
    const std::vector<std::uint8_t>& v = b.layers[0];
    // The whole block: in the last block of a row or column 0 past the image (no canopy; the trunks' search reads
    // whole blocks), as canopy_derive.comp writes it.
    const bool partial = t.width() != L.block || t.height() != L.block;
    std::vector<std::uint8_t> whole;
    if (partial) {
        whole.assign(size_t(L.block) * size_t(L.block), 0);
        for (int y = 0; y < t.height(); ++y)
            std::copy_n(v.begin() + std::ptrdiff_t(size_t(y) * size_t(t.width())), t.width(),
                        whole.begin() + std::ptrdiff_t(size_t(y) * size_t(L.block)));
    }
    const std::uint8_t* block = partial ? whole.data() : v.data();
    glTextureSubImage3D(m_clip.id(), 0, wrapTexel(t.x0, L.size), wrapTexel(t.y0, L.size), level, L.block, L.block, 1,
                        GL_RED_INTEGER, GL_UNSIGNED_BYTE, block);
    if (level == m_copyLevel && !m_copyStale)
        for (int y = 0; y < L.block; ++y)
            std::copy_n(block + size_t(y) * size_t(L.block), L.block,
                        m_copy.begin() + std::ptrdiff_t(size_t(wrapTexel(t.y0 + y, L.size)) * size_t(L.size) +
                                                        size_t(wrapTexel(t.x0, L.size))));
    const size_t slot = size_t(wrapTexel(b.key.by, slots)) * size_t(slots) + size_t(wrapTexel(b.key.bx, slots));
    m_tags[size_t(level)][slot] = blockTag(b.key.bx, b.key.by);
    // The cell maxima (canopy_derive.comp step 5), here at once: maxValueOver sees them this frame.
    const int index = maxIndex(level, int(slot));
    const size_t cells = size_t(m_cellsPerSide) * size_t(m_cellsPerSide);
    std::uint8_t* cell = m_cellMax.data() + size_t(index) * cells;
    std::fill(cell, cell + cells, std::uint8_t(0));
    // The block's texels start at its origin (the image's edge cuts only its far side): cell (cx, cy) holds the
    // block's texels [8 cx, 8 cx + 8) × [8 cy, 8 cy + 8), row by row, 8 texels at a time.
    assert(t.x0 == b.key.bx * L.block && t.y0 == b.key.by * L.block);
    std::uint8_t top = 0;
    for (int y = 0; y < t.height(); ++y) {
        const std::uint8_t* row = v.data() + size_t(y) * size_t(t.width());
        std::uint8_t* cellRow = cell + size_t(y / kCell) * size_t(m_cellsPerSide);
        for (int x0 = 0; x0 < t.width(); x0 += kCell) {
            const int x1 = std::min(x0 + kCell, t.width());
            std::uint8_t m = cellRow[x0 / kCell];
            for (int x = x0; x < x1; ++x) m = std::max(m, row[x]);
            cellRow[x0 / kCell] = m;
            top = std::max(top, m);
        }
    }
    m_maxKnown[size_t(index)] = int(top);
    m_maxGeneration[size_t(index)] = 0; // no GPU copy in flight overwrites it
}

CanopyFrameStats CanopyClipmapGL::runCpu(int budget, bool onDemand, bool wait) {
    CanopyFrameStats st;
    const ClipmapSchedule& s = m_source.schedule();
    const ClipmapLayout& L = s.layout();
    const int slots = s.slotsPerSide();
    std::vector<char> touched(size_t(L.clipLevels()), 0);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1); // rows of a byte per texel
    const auto upload = [&](std::vector<LoadedBlock> blocks) {
        int stored = 0;
        for (const LoadedBlock& b : blocks) {
            if (!b.error.empty()) {
                // A service's fault is asked again later; a damaged file is reported (the block is never derived).
                if (!b.streamed && m_readError.empty()) m_readError = b.error;
                continue;
            }
            if (intersect(s.window(b.key.level), b.texels) != b.texels) continue; // the window has moved on
            store(b);
            touched[size_t(b.key.level)] = 1;
            ++stored;
            if (onDemand && b.key.level < m_keepFrom) ++st.blocksOnDemand;
        }
        st.blocksDerived += stored;
        return stored;
    };
    const std::int64_t blockTexels = std::int64_t(L.block) * L.block;
    while (true) {
        std::vector<BlockKey> want = wantedBlocks(onDemand, st.blocksUnread);
        const bool none = want.empty();
        // The loader's queue is replaced every frame: a bounded list, the most urgent first.
        if (want.size() > 1024) want.resize(1024);
        m_cpu->want(want);
        if (!wait) {
            upload(m_cpu->take(std::int64_t(budget) * blockTexels));
            break;
        }
        if (none) break;
        m_cpu->waitIdle();
        if (upload(m_cpu->take(std::numeric_limits<std::int64_t>::max())) == 0) break; // read errors only
    }
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    for (int level = 0; level < L.clipLevels(); ++level)
        if (touched[size_t(level)])
            glTextureSubImage3D(m_tagTexture.id(), 0, 0, 0, level, slots, slots, 1, GL_RED_INTEGER, GL_INT,
                                m_tags[size_t(level)].data());
    st.blocksPending = int(m_cpu->pending());
    m_totalDerived += st.blocksDerived;
    return st;
}

CanopyFrameStats CanopyClipmapGL::rederiveAll() {
    const CanopyFrameStats st = run(1 << 30, true);
    collectMaxima(false);
    return st;
}

void CanopyClipmapGL::bind(const gl::ShaderProgram& program, int firstUnit) const {
    glBindTextureUnit(GLuint(firstUnit), m_clip.id());
    glBindTextureUnit(GLuint(firstUnit + 1), m_coarse.id());
    glBindTextureUnit(GLuint(firstUnit + 2), m_tagTexture.id());
    program.set("uCanopyClip", firstUnit);
    program.set("uCanopyCoarse", firstUnit + 1);
    program.set("uCanopyTags", firstUnit + 2);
    program.set("uCanopyLayers", m_options.layers);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kCanopyReadsBinding, m_reads.id());
}

void CanopyClipmapGL::keepCopyOf(int level) const {
    assert((m_copyLevel < 0 || m_copyLevel == level) && "CanopyClipmapGL: a copy of one level only");
    if (level == m_copyLevel) return;
    m_copyLevel = level;
    m_copyStale = true; // what is derived already: read back at the first levelCopy()
}

const std::vector<std::uint8_t>& CanopyClipmapGL::levelCopy() const {
    if (m_copyStale) {
        m_copy = readClipLevel(m_copyLevel);
        m_copyStale = false;
    }
    return m_copy;
}

std::vector<std::uint8_t> CanopyClipmapGL::readClipLevel(int level) const {
    const int n = m_source.schedule().layout().size;
    std::vector<std::uint8_t> out(size_t(n) * size_t(n));
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glGetTextureSubImage(m_clip.id(), 0, 0, 0, level, n, n, 1, GL_RED_INTEGER, GL_UNSIGNED_BYTE, GLsizei(out.size()),
                         out.data());
    return out;
}

std::vector<std::uint8_t> CanopyClipmapGL::readCoarse() const {
    const ClipmapLayout& L = m_source.schedule().layout();
    const glm::ivec2 size = L.levelSizes[size_t(L.clipLevels())];
    std::vector<std::uint8_t> out(size_t(size.x) * size_t(size.y));
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glGetTextureImage(m_coarse.id(), 0, GL_RED_INTEGER, GL_UNSIGNED_BYTE, GLsizei(out.size()), out.data());
    return out;
}

std::int64_t CanopyClipmapGL::residentBytes() const {
    const ClipmapLayout& L = m_source.schedule().layout();
    const glm::ivec2 coarse = L.levelSizes[size_t(L.clipLevels())];
    const std::int64_t slots = m_source.schedule().slotsPerSide();
    return std::int64_t(L.size) * L.size * m_arrayLayers + std::int64_t(coarse.x) * coarse.y +
           slots * slots * 4 * m_arrayLayers;
}

} // namespace seasonview
