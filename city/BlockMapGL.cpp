#include "BlockMapGL.h"

#include "TerrainMeshGL.h" // kNearPlane

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <string>

namespace seasonview::city {

namespace {

// Tiles per side of a layer: a layer of up to 256² texels (4² maps of the usual 64², 512 KiB): the room a partly
// used last layer leaves is small next to a city's capacity; the GL's 2048 layers at least hold 32,768 such maps.
int tilesPerSide(int n) { return std::clamp(256 / std::max(n, 1), 1, 16); }

gl::Texture arrayTexture(GLenum internalFormat, int side, int layers) {
    gl::Texture t = gl::Texture::create(GL_TEXTURE_2D_ARRAY);
    glTextureStorage3D(t.id(), 1, internalFormat, side, side, layers);
    glTextureParameteri(t.id(), GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTextureParameteri(t.id(), GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    return t;
}

// One instance record (common_blockmap.glsl's BmMap, std430).
struct Record {
    float geo[4];
    float z[4];
    std::int32_t tile[4];
    std::int32_t wall[4];
    float source[4];
};
static_assert(sizeof(Record) == 80);

} // namespace

Result<gl::ShaderProgram> BlockMapPoolGL::buildProgram(bool roofImagery, bool frontFaces) {
    std::vector<std::string> defines;
    if (roofImagery) defines.push_back("ROOF_IMAGERY");
    if (frontFaces) defines.push_back("FRONT_FACES");
    static_assert((kBlockMapPageWords & (kBlockMapPageWords - 1)) == 0, "pages of a power of two words");
    int bits = 0;
    while ((std::size_t(1) << bits) < kBlockMapPageWords) ++bits;
    defines.push_back("BM_PAGE_BITS " + std::to_string(bits));
    return gl::ShaderProgram::build("blockmap.vert", "blockmap.frag", defines);
}

BlockMapPoolGL::BlockMapPoolGL(int mapSize)
    : m_size(mapSize), m_tilesPerSide(tilesPerSide(mapSize)), m_instances(gl::Buffer::create()),
      m_vao(gl::VertexArray::create()) {}

Status BlockMapPoolGL::growLayers(int layers) {
    GLint maxLayers = 0;
    glGetIntegerv(GL_MAX_ARRAY_TEXTURE_LAYERS, &maxLayers);
    if (layers > maxLayers)
        return Error{"BlockMaps: " + std::to_string(std::int64_t(layers) * m_tilesPerSide * m_tilesPerSide) +
                     " maps resident at once do not fit this GL's " + std::to_string(maxLayers) + " texture layers"};
    const int side = m_tilesPerSide * m_size;
    gl::Texture texels = arrayTexture(GL_RGBA8UI, side, layers), columns = arrayTexture(GL_R32UI, side, layers);
    if (m_layers > 0) {
        glCopyImageSubData(m_texels.id(), GL_TEXTURE_2D_ARRAY, 0, 0, 0, 0, texels.id(), GL_TEXTURE_2D_ARRAY, 0, 0, 0, 0,
                           side, side, m_layers);
        glCopyImageSubData(m_columns.id(), GL_TEXTURE_2D_ARRAY, 0, 0, 0, 0, columns.id(), GL_TEXTURE_2D_ARRAY, 0, 0, 0,
                           0, side, side, m_layers);
    }
    const int perLayer = m_tilesPerSide * m_tilesPerSide;
    m_freeTiles.add(std::uint32_t(m_layers * perLayer), std::uint32_t(layers * perLayer));
    m_texels = std::move(texels);
    m_columns = std::move(columns);
    m_layers = layers;
    return Ok{};
}

Status BlockMapPoolGL::shrinkLayers(int layers) {
    const int perLayer = m_tilesPerSide * m_tilesPerSide, end = layers * perLayer;
    // The live tiles at or past the new end moved to the lowest free ones below it (there are enough: the live maps
    // fit `layers`), within the same arrays.
    for (Slot& s : m_slots) {
        if (!s.live || s.tile < end) continue;
        const int to = int(m_freeTiles.take());
        const glm::ivec3 a = tileAt(s.tile), b = tileAt(to);
        for (const gl::Texture* t : {&m_texels, &m_columns})
            glCopyImageSubData(t->id(), GL_TEXTURE_2D_ARRAY, 0, a.x, a.y, a.z, t->id(), GL_TEXTURE_2D_ARRAY, 0, b.x, b.y,
                               b.z, m_size, m_size, 1);
        s.tile = to;
    }
    const int side = m_tilesPerSide * m_size;
    gl::Texture texels = arrayTexture(GL_RGBA8UI, side, layers), columns = arrayTexture(GL_R32UI, side, layers);
    glCopyImageSubData(m_texels.id(), GL_TEXTURE_2D_ARRAY, 0, 0, 0, 0, texels.id(), GL_TEXTURE_2D_ARRAY, 0, 0, 0, 0,
                       side, side, layers);
    glCopyImageSubData(m_columns.id(), GL_TEXTURE_2D_ARRAY, 0, 0, 0, 0, columns.id(), GL_TEXTURE_2D_ARRAY, 0, 0, 0, 0,
                       side, side, layers);
    m_texels = std::move(texels);
    m_columns = std::move(columns);
    m_layers = layers;
    m_freeTiles.keepBelow(std::uint32_t(end));
    return Ok{};
}

Status BlockMapPoolGL::resizePages(std::size_t pages) {
    GLint maxTexels = 0;
    glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &maxTexels);
    if (pages * kBlockMapPageWords > std::size_t(maxTexels))
        return Error{"BlockMaps: " + std::to_string(pages * kBlockMapPageWords) +
                     " words of walls resident at once do not fit this GL's " + std::to_string(maxTexels) +
                     "-texel texture buffers"};
    gl::Buffer buffer = gl::Buffer::create();
    const std::size_t pageBytes = kBlockMapPageWords * 4;
    glNamedBufferData(buffer.id(), GLsizeiptr(std::max<std::size_t>(pages, 1) * pageBytes), nullptr, GL_DYNAMIC_DRAW);
    const std::size_t kept = std::min(pages, m_pageCapacity);
    if (kept > 0) glCopyNamedBufferSubData(m_wordBuffer.id(), buffer.id(), 0, 0, GLsizeiptr(kept * pageBytes));
    if (pages > m_pageCapacity) m_freePages.add(std::uint32_t(m_pageCapacity), std::uint32_t(pages));
    else m_freePages.keepBelow(std::uint32_t(pages));
    gl::Texture words = gl::Texture::create(GL_TEXTURE_BUFFER);
    glTextureBuffer(words.id(), GL_R32UI, buffer.id());
    m_wordBuffer = std::move(buffer);
    m_words = std::move(words);
    m_pageCapacity = pages;
    m_pageOwner.resize(pages);
    return Ok{};
}

std::uint32_t BlockMapPoolGL::takePage(int handle, std::uint32_t index) {
    const std::uint32_t p = m_freePages.take();
    m_pageOwner[p] = {handle, index};
    ++m_usedPages;
    return p;
}

void BlockMapPoolGL::movePagesBelow(std::size_t target) {
    const std::size_t pageBytes = kBlockMapPageWords * 4;
    for (std::size_t p = target; p < m_pageCapacity; ++p) {
        const PageOwner o = m_pageOwner[p];
        if (o.handle < 0) continue;
        const std::uint32_t to = takePage(o.handle, o.index); // the lowest free page: below target
        --m_usedPages;                                       // moved, not added
        glCopyNamedBufferSubData(m_wordBuffer.id(), m_wordBuffer.id(), GLintptr(p * pageBytes),
                                 GLintptr(std::size_t(to) * pageBytes), GLsizeiptr(pageBytes));
        m_pageOwner[p] = PageOwner{};
        Slot& s = m_slots[std::size_t(o.handle)];
        s.pages[o.index] = to;
        // The table's entry for this page (in the map's first page, which may be this one, now moved).
        glNamedBufferSubData(m_wordBuffer.id(), GLintptr((std::size_t(s.pages[0]) * kBlockMapPageWords + o.index) * 4),
                             4, &to);
    }
}

std::uint64_t BlockMapPoolGL::tileBytes(int layers) const {
    const auto side = std::uint64_t(m_tilesPerSide) * std::uint64_t(m_size);
    return side * side * 8 * std::uint64_t(layers);
}

Status BlockMapPoolGL::prepare(std::uint64_t bytes, std::size_t pagesComing, std::size_t mapsComing) {
    m_byteLimit = bytes;
    // Layers beyond what the maps need (live and coming) given back once under three quarters of them have been in
    // use for kShrinkAfterFrames frames in a row, or at once when the pool is over the limit; the pages grown once for
    // the frame's maps when its free ones cannot hold them.
    const int perLayer = m_tilesPerSide * m_tilesPerSide;
    const int layersNeeded = int((m_live + mapsComing + std::size_t(perLayer) - 1) / std::size_t(perLayer));
    // At once where the pool holds more than the limit (the city's other blocks need the room).
    const bool over = allocatedBytes() > bytes;
    m_underUsedFrames = 4 * layersNeeded < 3 * m_layers ? m_underUsedFrames + 1 : 0;
    if (m_underUsedFrames > 0 && (over || m_underUsedFrames >= kShrinkAfterFrames)) {
        m_underUsedFrames = 0;
        if (auto st = shrinkLayers(std::max(layersNeeded + layersNeeded / 4, 1)); !st) return st;
    }
    const std::size_t need = m_usedPages + pagesComing;
    if (need > m_pageCapacity) {
        m_pagesUnderUsedFrames = 0;
        return growPages(need);
    }
    // The pages likewise: those in use moved below an eighth more than the maps need, the buffer remade that size.
    const std::size_t fit = std::max(need + need / 8, kMinPages);
    m_pagesUnderUsedFrames = 4 * need < 3 * m_pageCapacity && fit < m_pageCapacity ? m_pagesUnderUsedFrames + 1 : 0;
    if (m_pagesUnderUsedFrames > 0 && (over || m_pagesUnderUsedFrames >= kShrinkAfterFrames)) {
        m_pagesUnderUsedFrames = 0;
        movePagesBelow(fit);
        return resizePages(fit); // smaller: cannot fail
    }
    return Ok{};
}

Status BlockMapPoolGL::growPages(std::size_t need) {
    // To what the maps need, and up to a quarter more (at least kMinPages in all) within the limit: each growth copies
    // every page kept, so it grows by a share of what it holds (with an eighth, the 10,000-building path grew ten
    // times in a row, up to 150 ms each on llvmpipe).
    const std::size_t pageBytes = kBlockMapPageWords * 4;
    const std::uint64_t needed = tileBytes(m_layers) + std::uint64_t(need) * pageBytes;
    const std::size_t room = m_byteLimit > needed ? std::size_t((m_byteLimit - needed) / pageBytes) : 0;
    const std::size_t extra = std::min(std::max(need / 4, kMinPages > need ? kMinPages - need : 0), room);
    return resizePages(need + extra);
}

Result<int> BlockMapPoolGL::add(const BlockMap& map, const BlockMapPacked* packed) {
    if (map.size != m_size)
        return Error{"BlockMaps: a map of " + std::to_string(map.size) + "² texels in a pool of " +
                     std::to_string(m_size) + "² maps"};
    BlockMapPacked own;
    if (!packed) {
        own = packBlockMap(map);
        packed = &own;
    }
    const std::size_t pageBytes = kBlockMapPageWords * 4;
    // Room within the limit beyond what is needed (saturating).
    auto spare = [&](std::uint64_t needed) { return m_byteLimit > needed ? m_byteLimit - needed : 0; };
    // Its pages first: a map that does not fit changes nothing.
    const std::size_t words = packed->words.size(), pages = blockMapPages(words);
    if (pages > kBlockMapPageWords) // its page table must fit its first page
        return Error{"BlockMaps: a map of " + std::to_string(words) + " wall words exceeds the pool's " +
                     std::to_string(kBlockMapPageWords * (kBlockMapPageWords - 1)) + " a map"};
    if (m_freePages.size() < pages)
        if (auto st = growPages(m_usedPages + pages); !st) return st.error();
    if (m_freeTiles.empty()) {
        // A layer more, and up to a quarter more within the limit.
        const std::uint64_t layerBytes = tileBytes(1);
        const std::uint64_t need = tileBytes(m_layers + 1) + std::uint64_t(m_pageCapacity) * pageBytes;
        const int extra = int(std::min<std::uint64_t>(std::uint64_t(m_layers / 4), spare(need) / layerBytes));
        if (auto st = growLayers(m_layers + 1 + extra); !st) return st.error();
    }
    int handle;
    if (!m_freeSlots.empty()) {
        handle = m_freeSlots.back();
        m_freeSlots.pop_back();
    } else {
        handle = int(m_slots.size());
        m_slots.emplace_back();
    }
    Slot& s = m_slots[std::size_t(handle)];
    s.live = true;
    s.origin = map.origin;
    s.texel = map.texel;
    s.zBase = map.zBase;
    s.zTop = map.zTop;
    s.wallTexels = map.wallTexels;
    s.span = packed->span;
    s.columns = map.columns();
    s.pages.clear();
    for (std::size_t j = 0; j < pages; ++j) s.pages.push_back(takePage(handle, std::uint32_t(j)));
    s.tile = int(m_freeTiles.take());
    ++m_live;
    const glm::ivec3 tile = tileOf(handle);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTextureSubImage3D(m_texels.id(), 0, tile.x, tile.y, tile.z, m_size, m_size, 1, GL_RGBA_INTEGER, GL_UNSIGNED_BYTE,
                        packed->texels.data());
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTextureSubImage3D(m_columns.id(), 0, tile.x, tile.y, tile.z, m_size, m_size, 1, GL_RED_INTEGER, GL_UNSIGNED_INT,
                        map.column.data());
    if (pages > 0) {
        // The map's words as the shader reads them: its page table (a word per page), then its words; page by page.
        std::vector<std::uint32_t> all(pages * kBlockMapPageWords, 0u);
        std::copy(s.pages.begin(), s.pages.end(), all.begin());
        std::copy(packed->words.begin(), packed->words.end(), all.begin() + std::ptrdiff_t(pages));
        for (std::size_t j = 0; j < pages; ++j)
            glNamedBufferSubData(m_wordBuffer.id(), GLintptr(std::size_t(s.pages[j]) * pageBytes), GLsizeiptr(pageBytes),
                                 all.data() + j * kBlockMapPageWords);
    }
    return handle;
}

void BlockMapPoolGL::remove(int handle) {
    if (handle < 0 || std::size_t(handle) >= m_slots.size() || !m_slots[std::size_t(handle)].live) return;
    Slot& s = m_slots[std::size_t(handle)];
    for (const std::uint32_t p : s.pages) {
        m_pageOwner[p] = PageOwner{};
        m_freePages.release(p);
        --m_usedPages;
    }
    m_freeTiles.release(std::uint32_t(s.tile));
    s = Slot{};
    m_freeSlots.push_back(handle);
    --m_live; // its tile and pages are given back by prepare(), once the maps have needed fewer for a while
}

glm::dvec3 BlockMapPoolGL::boxMin(int handle) const {
    const Slot& s = m_slots[std::size_t(handle)];
    return {s.origin, s.zBase};
}

glm::dvec3 BlockMapPoolGL::boxMax(int handle) const {
    const Slot& s = m_slots[std::size_t(handle)];
    return {s.origin + double(m_size) * s.texel, s.zTop};
}

bool BlockMapPoolGL::needsBackFaces(int handle, const glm::dvec3& eye, double margin) const {
    const glm::dvec3 lo = boxMin(handle) - margin, hi = boxMax(handle) + margin;
    return eye.x >= lo.x && eye.x <= hi.x && eye.y >= lo.y && eye.y <= hi.y && eye.z >= lo.z && eye.z <= hi.z;
}

glm::ivec3 BlockMapPoolGL::tileAt(int tile) const {
    const int perLayer = m_tilesPerSide * m_tilesPerSide, t = tile % perLayer;
    return {(t % m_tilesPerSide) * m_size, (t / m_tilesPerSide) * m_size, tile / perLayer};
}

glm::ivec3 BlockMapPoolGL::tileOf(int handle) const { return tileAt(m_slots[std::size_t(handle)].tile); }

std::uint64_t BlockMapPoolGL::allocatedBytes() const {
    return tileBytes(m_layers) + std::uint64_t(m_pageCapacity) * kBlockMapPageWords * 4;
}

std::uint64_t BlockMapPoolGL::usedBytes() const {
    const auto n = std::uint64_t(m_size);
    return n * n * 8 * std::uint64_t(m_live) + std::uint64_t(m_usedPages) * kBlockMapPageWords * 4;
}

void BlockMapPoolGL::setInstances(const std::vector<Instance>& instances) {
    std::vector<Record> records(std::max<std::size_t>(instances.size(), 1), Record{});
    for (std::size_t i = 0; i < instances.size(); ++i) {
        const int h = instances[i].handle;
        const Slot& s = m_slots[std::size_t(h)];
        const glm::ivec3 tile = tileOf(h);
        Record& r = records[i];
        r = Record{{float(s.origin.x), float(s.origin.y), float(s.texel), float(s.zBase)},
                   {float(s.zTop), 0.0f, 0.0f, 0.0f},
                   {tile.x, tile.y, tile.z, std::int32_t(s.pages.size())},
                   {s.wallTexels, s.span, s.columns, s.pages.empty() ? 0 : std::int32_t(s.pages[0])},
                   {instances[i].sourceColour.r, instances[i].sourceColour.g, instances[i].sourceColour.b,
                    instances[i].sourceColour.a}};
    }
    // A new store each frame: the GL need not wait for the last frame's draws to read the old one.
    glNamedBufferData(m_instances.id(), GLsizeiptr(records.size() * sizeof(Record)), records.data(), GL_STREAM_DRAW);
}

void BlockMapPoolGL::begin(const gl::ShaderProgram& p, const glm::dmat4& viewProj, const glm::dvec3& eye,
                           double pixelAngle, const DrawSettings& s, bool frontFaces) const {
    p.set("uPixelAngle", float(pixelAngle));
    p.set("uViewProj", glm::mat4(viewProj));
    p.set("uEye", glm::vec3(eye));
    p.set("uRoofColour", s.roofColour);
    p.set("uSunDir", glm::vec3(glm::normalize(glm::dvec3(-0.5, 0.6, 0.75))));
    p.set("uOutputKind", s.outputKind ? 1 : 0);
    p.set("uBmSize", m_size);
    p.set("uBmTexels", kUnit);
    p.set("uBmColumn", kUnit + 1);
    p.set("uBmWords", kUnit + 2);
    p.use();
    glBindTextureUnit(GLuint(kUnit), m_texels.id());
    glBindTextureUnit(GLuint(kUnit + 1), m_columns.id());
    glBindTextureUnit(GLuint(kUnit + 2), m_words.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, m_instances.id());
    glBindVertexArray(m_vao.id());
    glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE); // reversed Z in [0, 1]: gl_FragDepth is the hit's clip z / w
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_GREATER);
    glEnable(GL_CULL_FACE);
    // One fragment per pixel either way: the front faces (the eye outside), or the back faces (inside it or not).
    glCullFace(frontFaces ? GL_BACK : GL_FRONT);
}

void BlockMapPoolGL::draw(const gl::ShaderProgram& p, int first, int count) const {
    if (count <= 0) return;
    p.set("uFirstInstance", first);
    glDrawArraysInstanced(GL_TRIANGLES, 0, 36, count);
}

void BlockMapPoolGL::end() {
    glBindVertexArray(0);
    glDisable(GL_CULL_FACE);
    glCullFace(GL_BACK);
    for (int i = 0; i < kTextures; ++i) glBindTextureUnit(GLuint(kUnit + i), 0);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, 0);
}

Result<std::unique_ptr<BlockMapGL>> BlockMapGL::create(const BlockMap& map) {
    auto program = BlockMapPoolGL::buildProgram(false);
    if (!program) return program.error();
    std::unique_ptr<BlockMapGL> b(new BlockMapGL());
    b->m_program = std::move(*program);
    b->m_pool = std::make_unique<BlockMapPoolGL>(map.size);
    auto h = b->m_pool->add(map);
    if (!h) return h.error();
    b->m_pool->setInstances({BlockMapPoolGL::Instance{*h, glm::vec4(0.0f)}});
    return b;
}

int BlockMapGL::draw(const Camera& camera, const gl::RenderTarget& target, const DrawSettings& s) const {
    target.bind();
    const double aspect = double(target.width()) / double(target.height());
    const double pixelAngle = 2.0 * std::tan(camera.fovYDeg * M_PI / 360.0) / double(target.height());
    m_pool->begin(m_program, camera.projectionMatrix(aspect, kNearPlane) * camera.viewMatrix(), camera.position,
                  pixelAngle, s);
    m_pool->draw(m_program, 0, 1);
    BlockMapPoolGL::end();
    return 1;
}

} // namespace seasonview::city
