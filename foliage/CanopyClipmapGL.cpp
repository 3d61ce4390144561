#include "CanopyClipmapGL.h"

#include "ToroidalWindow.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <string>
#include <utility>

namespace seasonview {

namespace {
constexpr int kTile = 32;            // output tile of one work group (canopy_derive.comp)
constexpr int kCell = 8;             // texels per side of a cell with its own maximum (canopy_derive.comp CELL)
constexpr int kMaxDispatchBlocks = 4096;
constexpr int kMaxLayers = 32;       // uLayerK[32]
std::int32_t blockTag(int bx, int by) { return bx | (by << 16); }
// The texels of clip level `level` that nearest-texel fetches at level-0 pixel positions in [lo, hi] read (floor),
// clamped to the level like the shaders' fetches: first and last.
std::pair<glm::ivec2, glm::ivec2> texelsOver(const ClipmapLayout& L, int level, glm::dvec2 lo, glm::dvec2 hi) {
    const double texel = std::ldexp(1.0, level); // level-0 pixels per texel of this level
    const glm::ivec2 size = L.levelSizes[size_t(level)];
    return {glm::clamp(glm::ivec2(glm::floor(lo / texel)), glm::ivec2(0), size - 1),
            glm::clamp(glm::ivec2(glm::floor(hi / texel)), glm::ivec2(0), size - 1)};
}
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
    int top = options.topK > 0 ? options.topK : std::min(kSegMaxK, 3 * k);
    if (options.params.method == SegmentationMethod::Pixel) top = 1;
    top = std::clamp(top | 1, k, kSegMaxK);
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
    return c;
}

int CanopyClipmapGL::layerK(int layer, int level) const {
    const int k = effectiveK(m_options.params), n = m_options.layers;
    // Ground layer k, top layer m_topK, odd in between (Ropinski et al. 2007 §4.2: k grows with height).
    const int ki = n > 1 ? k + 2 * int(std::lround(double(m_topK - k) / 2.0 * double(layer) / double(n - 1))) : k;
    // About the same metres on coarser levels: k / 2^level, rounded down to odd.
    return 2 * int(std::floor(double(ki) / std::exp2(double(level + 1)))) + 1;
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
    if (!m_options.onDemand) return; // every block is derived: nothing to read back
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
    const gl::ShaderProgram& program = m_programs[coarse ? 1 : 0];
    m_source.bind(program, 0);
    program.set("uLevel", level);
    program.set("uBlockSize", L.block);
    program.set("uDropThreshold", m_stats.dropThreshold);
    // The layers grouped by k (canopy_derive.comp's uGroupK): per group its k and its last layer + 1.
    const auto kOf = [&](int layer) {
        return m_options.params.method == SegmentationMethod::Pixel ? 1 : layerK(layer, level);
    };
    int groups = 0;
    for (int i = 0; i < m_options.layers; ++i) {
        if (i + 1 < m_options.layers && kOf(i + 1) == kOf(i)) continue;
        const std::string name = "uGroupK[" + std::to_string(groups++) + "]";
        glProgramUniform2i(program.id(), program.location(name.c_str()), kOf(i), i + 1);
    }
    program.set("uGroups", groups);
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
        const TexelRect& w = s.window(level);
        const glm::ivec2 size = L.levelSizes[size_t(level)];
        const int bx0 = std::max(0, w.x0 / L.block), by0 = std::max(0, w.y0 / L.block);
        const int bx1 = std::min((size.x + L.block - 1) / L.block, (w.x1 + L.block - 1) / L.block);
        const int by1 = std::min((size.y + L.block - 1) / L.block, (w.y1 + L.block - 1) / L.block);
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
    const CanopyFrameStats st = run(m_options.blocksPerFrame, false, m_options.onDemand && m_readsBack);
    collectMaxima(false);
    return st;
}

CanopyFrameStats CanopyClipmapGL::completeSynchronously() {
    const CanopyFrameStats st = run(1 << 30, false);
    collectMaxima(true);
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
