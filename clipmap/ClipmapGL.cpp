#include "ClipmapGL.h"

#include "Raster.h"
#include "ZstdTileCheck.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace seasonview {

ClipmapGL::ClipmapGL(ClipmapLayout layout, const ClipmapOptions& options)
    : m_options(options), m_schedule(std::move(layout)) {}

ClipmapGL::~ClipmapGL() {
    m_loader.reset(); // join the worker before the source goes
}

Result<std::unique_ptr<ClipmapGL>> ClipmapGL::create(const std::vector<ImagePyramid>& layers,
                                                     const ClipmapOptions& options,
                                                     std::unique_ptr<BlockSource> source) {
    assert(!layers.empty() && "ClipmapGL::create(): no layers");
    assert(options.size >= 256 && options.size <= 4096 && options.size % options.block == 0 &&
           "ClipmapGL::create(): size must be 256..4096 and a multiple of the block");
    ClipmapLayout layout = makeClipmapLayout(layers[0].width(), layers[0].height(), options.size, options.block);
    for (const ImagePyramid& p : layers) {
        if (p.levels.size() != layout.levelSizes.size() || p.width() != layers[0].width() ||
            p.height() != layers[0].height())
            return fileError(p.folder.string(), "pyramid does not match the other layers' size or level count");
        for (size_t l = 0; l < p.levels.size(); ++l)
            if (glm::ivec2(p.levels[l].width, p.levels[l].height) != layout.levelSizes[l])
                return fileError(p.levels[l].file.string(), "pyramid level has an unexpected size");
    }
    for (const ImagePyramid& p : layers)
        if (p.format != layers[0].format)
            return fileError(p.folder.string(), "pyramid texel format differs from the other layers'");
    auto c = std::unique_ptr<ClipmapGL>(new ClipmapGL(std::move(layout), options));
    c->m_format = layers[0].format;
    const bool heights = c->m_format == TexelFormat::R32F;
    const ClipmapLayout& L = c->m_schedule.layout();
    const int clipLevels = L.clipLevels();
    const int arrayLayers = std::max({1, clipLevels, options.minClipLevels});
    const int slots = c->m_schedule.slotsPerSide();

    for (const ImagePyramid& p : layers) c->m_streaming = c->m_streaming || p.streamedLevels > 0;
    if (source) c->m_source = std::move(source);
    else c->m_source = std::make_unique<MixedBlockSource>(layers, options.cacheMegabytes, c->m_format);

    c->m_tags = gl::Texture::create(GL_TEXTURE_2D_ARRAY);
    glTextureStorage3D(c->m_tags.id(), 1, GL_R32I, slots, slots, arrayLayers);
    const GLint empty = ClipmapSchedule::kEmptyTag;
    glClearTexImage(c->m_tags.id(), 0, GL_RED_INTEGER, GL_INT, &empty);
    glTextureParameteri(c->m_tags.id(), GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTextureParameteri(c->m_tags.id(), GL_TEXTURE_MAG_FILTER, GL_NEAREST);

    c->m_coarseSize = L.levelSizes[size_t(clipLevels)];
    c->m_coarseLevels = heights ? int(L.levelSizes.size()) - clipLevels
                                : 1 + int(std::floor(std::log2(double(std::max(c->m_coarseSize.x, c->m_coarseSize.y)))));
    // Every layer in one array texture, layer-major (layer i's level l at array layer i · arrayLayers + l), so a
    // shader choosing a layer per pixel (the season) indexes one sampler instead of sampling every layer's.
    const int n = int(layers.size());
    c->m_layers = n;
    c->m_layerStride = arrayLayers;
    c->m_clip = gl::Texture::create(GL_TEXTURE_2D_ARRAY);
    glTextureStorage3D(c->m_clip.id(), 1, heights ? GL_R32F : GL_RGBA8, options.size, options.size, n * arrayLayers);
    const GLfloat zero[4] = {0, 0, 0, 0};
    glClearTexImage(c->m_clip.id(), 0, heights ? GL_RED : GL_RGBA, GL_FLOAT, zero);
    // GL_REPEAT does the toroidal modulo for texture coordinates q / N, bilinear taps included.
    glTextureParameteri(c->m_clip.id(), GL_TEXTURE_WRAP_S, GL_REPEAT);
    glTextureParameteri(c->m_clip.id(), GL_TEXTURE_WRAP_T, GL_REPEAT);
    glTextureParameteri(c->m_clip.id(), GL_TEXTURE_MIN_FILTER, heights ? GL_NEAREST : GL_LINEAR);
    glTextureParameteri(c->m_clip.id(), GL_TEXTURE_MAG_FILTER, heights ? GL_NEAREST : GL_LINEAR);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);

    c->m_coarse = gl::Texture::create(GL_TEXTURE_2D_ARRAY);
    // The resident levels are read whole through GDAL, whose libtiff does not verify the tiles' checksums.
    ZstdTileCheck residentCheck;
    constexpr int kWhole = std::numeric_limits<int>::max();
    if (heights) {
        // The resident levels, exact, one array layer each (layer i's level clipLevels + k at i · coarse levels + k).
        glTextureStorage3D(c->m_coarse.id(), 1, GL_R32F, c->m_coarseSize.x, c->m_coarseSize.y, n * c->m_coarseLevels);
        for (int i = 0; i < n; ++i)
            for (int k = 0; k < c->m_coarseLevels; ++k) {
                const auto& file = layers[size_t(i)].levels[size_t(clipLevels + k)].file;
                if (auto st = residentCheck.check(file, 0, 0, kWhole, kWhole); !st) return st.error();
                auto level = readImageF32(file, 1);
                if (!level) return level.error();
                glTextureSubImage3D(c->m_coarse.id(), 0, 0, 0, i * c->m_coarseLevels + k, level->width, level->height,
                                    1, GL_RED, GL_FLOAT, level->pixels.data());
            }
        glTextureParameteri(c->m_coarse.id(), GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        glTextureParameteri(c->m_coarse.id(), GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    } else {
        // The resident coarse pyramid: the first level that fits, mipmapped down to 1×1, one array layer per layer.
        glTextureStorage3D(c->m_coarse.id(), c->m_coarseLevels, GL_RGBA8, c->m_coarseSize.x, c->m_coarseSize.y, n);
        for (int i = 0; i < n; ++i) {
            const PyramidLevel& lv = layers[size_t(i)].levels[size_t(clipLevels)];
            if (clipLevels < layers[size_t(i)].streamedLevels) {
                // A streamed level (a clipmap narrower than the levels a streamed season has on disk): read whole,
                // through the loader's source, before the first frame.
                std::vector<std::uint8_t> texels(size_t(lv.width) * size_t(lv.height) * 4);
                if (auto st = c->m_source->read(i, clipLevels, TexelRect{0, 0, lv.width, lv.height}, texels.data()); !st)
                    return st.error();
                glTextureSubImage3D(c->m_coarse.id(), 0, 0, 0, i, lv.width, lv.height, 1, GL_RGBA, GL_UNSIGNED_BYTE,
                                    texels.data());
                continue;
            }
            if (auto st = residentCheck.check(lv.file, 0, 0, kWhole, kWhole); !st) return st.error();
            auto base = readImageU8(lv.file, 4);
            if (!base) return base.error();
            if (base->channels != 4) return fileError(lv.file.string(), "is not RGBA");
            glTextureSubImage3D(c->m_coarse.id(), 0, 0, 0, i, base->width, base->height, 1, GL_RGBA, GL_UNSIGNED_BYTE,
                                base->pixels.data());
        }
        glGenerateTextureMipmap(c->m_coarse.id());
        glTextureParameteri(c->m_coarse.id(), GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
        glTextureParameteri(c->m_coarse.id(), GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
        glTextureParameteri(c->m_coarse.id(), GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
        glTextureParameteri(c->m_coarse.id(), GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    }
    // Streamed levels wait on a service's round trips: several workers keep several regions in flight.
    c->m_loader = std::make_unique<BlockLoader>(*c->m_source, c->m_schedule, std::int64_t(64) << 20,
                                                c->m_streaming ? options.streamWorkers : 1);
    return c;
}

int ClipmapGL::uploadReady(std::int64_t budget, ClipmapFrameStats& stats) {
    const int slots = m_schedule.slotsPerSide();
    const int b = m_schedule.layout().block;
    std::vector<char> touched(size_t(std::max(1, m_schedule.layout().clipLevels())), 0);
    int uploaded = 0;
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    for (LoadedBlock& blk : m_loader->take(budget)) {
        if (!blk.error.empty()) { // stays missing, never drawn; the shader keeps using a coarser level
            if (blk.streamed) { // a service's fault: counted, shown, and the block asked again later
                ++m_streamErrors;
                m_lastStreamError = blk.error;
            } else if (!m_readError) {
                m_readError = ReadError{blk.error, blk.errorLayer};
            }
            continue;
        }
        // A block of an older window (the view moved on while it loaded) would evict a wanted one: drop it.
        if (intersect(m_schedule.window(blk.key.level), blk.texels) != blk.texels) continue;
        const int dx = wrapTexel(blk.key.bx, slots) * b, dy = wrapTexel(blk.key.by, slots) * b;
        for (int layer = 0; layer < m_layers; ++layer) {
            glTextureSubImage3D(m_clip.id(), 0, dx, dy, layer * m_layerStride + blk.key.level, blk.texels.width(),
                                blk.texels.height(), 1,
                                m_format == TexelFormat::R32F ? GL_RED : GL_RGBA,
                                m_format == TexelFormat::R32F ? GL_FLOAT : GL_UNSIGNED_BYTE, blk.layers[size_t(layer)].data());
            m_totalUploaded += std::int64_t(blk.texels.width()) * blk.texels.height(); // counted at the call
        }
        m_schedule.markStored(blk.key);
        touched[size_t(blk.key.level)] = 1;
        stats.texelsUploaded += blk.texels.area() * std::int64_t(m_layers);
        ++stats.blocksUploaded;
        ++uploaded;
    }
    for (size_t l = 0; l < touched.size(); ++l)
        if (touched[l])
            glTextureSubImage3D(m_tags.id(), 0, 0, 0, GLint(l), slots, slots, 1, GL_RED_INTEGER, GL_INT,
                                m_schedule.slotTags(int(l)).data());
    return uploaded;
}

ClipmapFrameStats ClipmapGL::update(const std::vector<glm::dvec2>& centres) {
    ClipmapFrameStats stats;
    stats.exposedTexels = m_schedule.setCenters(centres);
    m_loader->want(m_schedule.missingBlocks(4096));
    uploadReady(m_options.uploadBudgetTexels, stats);
    stats.blocksMissing = int(m_schedule.missingBlocks(size_t(1) << 30).size());
    return stats;
}

ClipmapFrameStats ClipmapGL::completeSynchronously() {
    ClipmapFrameStats stats;
    while (true) {
        const auto missing = m_schedule.missingBlocks(size_t(1) << 30);
        stats.blocksMissing = int(missing.size());
        if (missing.empty()) break;
        m_loader->want(missing);
        m_loader->waitIdle();
        if (uploadReady(std::int64_t(1) << 40, stats) == 0) break; // only unreadable blocks are left
    }
    stats.blocksMissing = int(m_schedule.missingBlocks(size_t(1) << 30).size());
    return stats;
}

void ClipmapGL::bind(const gl::ShaderProgram& program, int firstUnit, const std::string& prefix) const {
    auto name = [&](const std::string& n) { return prefix + n; };
    glBindTextureUnit(GLuint(firstUnit), m_clip.id());
    glBindTextureUnit(GLuint(firstUnit + 1), m_coarse.id());
    glBindTextureUnit(GLuint(firstUnit + 2), m_tags.id());
    program.set(name("Clip").c_str(), firstUnit);
    program.set(name("Coarse").c_str(), firstUnit + 1);
    program.set(name("ClipTags").c_str(), firstUnit + 2);
    program.set(name("ClipLayerStride").c_str(), m_layerStride);
    const ClipmapLayout& L = m_schedule.layout();
    program.set(name("ClipLevels").c_str(), L.clipLevels());
    program.set(name("ClipSize").c_str(), float(L.size));
    program.set(name("BlockSize").c_str(), L.block);
    program.set(name("SlotsPerSide").c_str(), m_schedule.slotsPerSide());
    program.set(name("Level0Size").c_str(), glm::vec2(L.levelSizes[0]));
    program.set(name("CoarseSize").c_str(), glm::vec2(m_coarseSize));
}

std::vector<std::string> ClipmapGL::layoutDefines(const std::string& prefix) const {
    const ClipmapLayout& L = m_schedule.layout();
    return {prefix + "BLOCK_SIZE " + std::to_string(L.block),
            prefix + "SLOTS_PER_SIDE " + std::to_string(m_schedule.slotsPerSide()),
            prefix + "SIZE " + std::to_string(L.size)};
}

std::int64_t ClipmapGL::residentBytes() const {
    const ClipmapLayout& L = m_schedule.layout();
    const std::int64_t arrayLayers = std::max({1, L.clipLevels(), m_options.minClipLevels});
    const std::int64_t clip = std::int64_t(L.size) * L.size * 4 * arrayLayers;
    const std::int64_t coarse = m_format == TexelFormat::R32F
                                    ? std::int64_t(m_coarseSize.x) * m_coarseSize.y * 4 * m_coarseLevels
                                    : std::int64_t(m_coarseSize.x) * m_coarseSize.y * 4 * 4 / 3;
    const std::int64_t tags = std::int64_t(m_schedule.slotsPerSide()) * m_schedule.slotsPerSide() * 4 * arrayLayers;
    return std::int64_t(m_layers) * (clip + coarse) + tags;
}

} // namespace seasonview
