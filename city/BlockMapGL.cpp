#include "BlockMapGL.h"

#include "TerrainMeshGL.h" // kNearPlane

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <string>

namespace seasonview::city {

namespace {

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

Result<gl::ShaderProgram> BlockMapPoolGL::buildProgram(bool roofImagery, bool frontFaces,
                                                      std::vector<std::string> defines) {
    if (roofImagery) defines.push_back("ROOF_IMAGERY");
    if (frontFaces) defines.push_back("FRONT_FACES");
    static_assert((kBlockMapPageWords & (kBlockMapPageWords - 1)) == 0, "pages of a power of two words");
    int bits = 0;
    while ((std::size_t(1) << bits) < kBlockMapPageWords) ++bits;
    defines.push_back("BM_PAGE_BITS " + std::to_string(bits));
    return gl::ShaderProgram::build("blockmap.vert", "blockmap.frag", defines);
}

namespace {
std::size_t maxBufferTexels() {
    GLint texels = 0;
    glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &texels);
    return std::size_t(std::max(texels, 1));
}
} // namespace

BlockMapPoolGL::BlockMapPoolGL(int mapSize)
    : m_size(mapSize),
      m_tiles(m_tileStore, maxBufferTexels() / std::max<std::size_t>(std::size_t(mapSize) * std::size_t(mapSize), 1),
              kMinTiles),
      m_pages(m_pageStore, maxBufferTexels() / kBlockMapPageWords, kMinPages), m_instances(gl::Buffer::create()),
      m_vao(gl::VertexArray::create()) {
    m_tileStore.format = GL_RGBA32UI; // n² texels a map (BlockMapGL.h's top)
    m_tileStore.unitBytes = tileBytes(1);
    m_pageStore.format = GL_R32UI;
    m_pageStore.unitBytes = pageBytes(1);
    m_pageStore.pageTables = true;
    m_tileStore.movedBytes = m_pageStore.movedBytes = &m_movedBytes;
}

std::uint64_t BlockMapPoolGL::tileBytes(std::uint64_t tiles) const {
    return std::uint64_t(m_size) * std::uint64_t(m_size) * 16 * tiles;
}

std::uint64_t BlockMapPoolGL::pageBytes(std::uint64_t pages) { return pages * kBlockMapPageWords * 4; }

Status BlockMapPoolGL::Segments::addSegment(std::size_t units) {
    Segment g;
    g.buffer = gl::Buffer::create();
    glNamedBufferData(g.buffer.id(), GLsizeiptr(unitBytes * units), nullptr, GL_DYNAMIC_DRAW);
    g.texture = gl::Texture::create(GL_TEXTURE_BUFFER);
    glTextureBuffer(g.texture.id(), format, g.buffer.id());
    segments.push_back(std::move(g));
    return Ok{};
}

void BlockMapPoolGL::Segments::moveOwner(int, int fromSegment, const std::vector<std::uint32_t>& from, int toSegment,
                                         const std::vector<std::uint32_t>& to) {
    const GLuint src = segments[std::size_t(fromSegment)].buffer.id(), dst = segments[std::size_t(toSegment)].buffer.id();
    const auto bytes = GLsizeiptr(unitBytes);
    for (std::size_t k = 0; k < from.size(); ++k)
        glCopyNamedBufferSubData(src, dst, GLintptr(from[k]) * bytes, GLintptr(to[k]) * bytes, bytes);
    if (pageTables) writePageTable(toSegment, to);
    *movedBytes += unitBytes * from.size();
}

void BlockMapPoolGL::Segments::eraseSegment(int segment) { segments.erase(segments.begin() + segment); }

void BlockMapPoolGL::Segments::writePageTable(int segment, const std::vector<std::uint32_t>& pages) const {
    if (pages.empty()) return;
    glNamedBufferSubData(segments[std::size_t(segment)].buffer.id(), GLintptr(unitBytes * pages[0]),
                         GLsizeiptr(pages.size() * 4), pages.data());
}

std::size_t BlockMapPoolGL::pagesPerMap() const {
    return m_live > 0 ? std::max<std::size_t>((m_pages.inUse() + m_live - 1) / m_live, 1) : 1;
}

Status BlockMapPoolGL::growTiles(std::size_t tiles) {
    const std::uint64_t needed = allocatedBytes() + tileBytes(tiles);
    const std::uint64_t perMap = tileBytes(1) + pageBytes(pagesPerMap());
    return m_tiles.grow(tiles, m_byteLimit > needed ? std::size_t((m_byteLimit - needed) / perMap) : 0);
}

Status BlockMapPoolGL::growPages(std::size_t pages) {
    if (pages > m_pages.maxUnits())
        return Error{"BlockMaps: " + std::to_string(pages * kBlockMapPageWords) +
                     " words of walls in one segment do not fit this GL's " +
                     std::to_string(m_pages.maxUnits() * kBlockMapPageWords) + "-texel texture buffers"};
    const std::uint64_t needed = allocatedBytes() + pageBytes(pages);
    const std::size_t perMap = pagesPerMap();
    return m_pages.grow(pages, m_byteLimit > needed
                                   ? std::size_t((m_byteLimit - needed) / (tileBytes(1) + pageBytes(perMap))) * perMap
                                   : 0);
}

Status BlockMapPoolGL::prepare(std::uint64_t bytes, std::size_t pagesComing, std::size_t mapsComing) {
    m_byteLimit = bytes;
    // Segments given back once the live and coming maps have needed under three quarters of the tiles (pages) for
    // kShrinkAfterFrames frames in a row, or at once when the pool holds more than the limit (the city's other
    // blocks need the room); one added when the free room cannot hold what comes.
    const std::size_t tilesNeed = m_live + mapsComing, pagesNeed = m_pages.inUse() + pagesComing;
    auto over = [&] { return allocatedBytes() > m_byteLimit; };
    m_underUsedFrames = 4 * tilesNeed < 3 * m_tiles.held() ? m_underUsedFrames + 1 : 0;
    if (m_underUsedFrames > 0 && (over() || m_underUsedFrames >= kShrinkAfterFrames)) {
        m_underUsedFrames = 0;
        m_tiles.shrink(tilesNeed, over(), over);
    }
    m_pagesUnderUsedFrames = 4 * pagesNeed < 3 * m_pages.held() ? m_pagesUnderUsedFrames + 1 : 0;
    if (m_pagesUnderUsedFrames > 0 && (over() || m_pagesUnderUsedFrames >= kShrinkAfterFrames)) {
        m_pagesUnderUsedFrames = 0;
        m_pages.shrink(pagesNeed, over(), over);
    }
    if (m_tiles.freeUnits() < mapsComing)
        if (auto st = growTiles(mapsComing - m_tiles.freeUnits()); !st) return st;
    if (m_pages.freeUnits() < pagesComing) return growPages(pagesComing);
    return Ok{};
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
    const std::size_t words = packed->words.size(), pages = blockMapPages(words);
    if (pages > kBlockMapPageWords) // its page table must fit its first page
        return Error{"BlockMaps: a map of " + std::to_string(words) + " wall words exceeds the pool's " +
                     std::to_string(kBlockMapPageWords * (kBlockMapPageWords - 1)) + " a map"};
    int handle;
    if (!m_freeSlots.empty()) {
        handle = m_freeSlots.back();
        m_freeSlots.pop_back();
    } else {
        handle = int(m_slots.size());
        m_slots.emplace_back();
    }
    // Its pages first, then its tile; a map that does not fit changes nothing.
    auto fail = [&](const Status& st) {
        m_pages.release(handle);
        m_freeSlots.push_back(handle);
        return st.error();
    };
    // (A growth leaves a segment with room for what it was asked: SegmentPool::grow.)
    if (!m_pages.place(handle, pages)) {
        if (auto st = growPages(pages); !st) return fail(st);
        if (!m_pages.place(handle, pages)) return fail(Error{"BlockMaps: no room for a map's pages after growing"});
    }
    if (!m_tiles.place(handle, 1)) {
        if (auto st = growTiles(1); !st) return fail(st);
        if (!m_tiles.place(handle, 1)) return fail(Error{"BlockMaps: no room for a map's tile after growing"});
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
    ++m_live;
    glNamedBufferSubData(m_tileStore.segments[std::size_t(m_tiles.segmentOf(handle))].buffer.id(),
                         GLintptr(tileBytes(m_tiles.unitsOf(handle)[0])), GLsizeiptr(tileBytes(1)), packed->tile.data());
    if (pages > 0) {
        // The map's words as the shader reads them: its page table (a word per page), then its words; page by page.
        const std::vector<std::uint32_t>& at = m_pages.unitsOf(handle);
        std::vector<std::uint32_t> all(pages * kBlockMapPageWords, 0u);
        std::copy(at.begin(), at.end(), all.begin());
        std::copy(packed->words.begin(), packed->words.end(), all.begin() + std::ptrdiff_t(pages));
        const GLuint buffer = m_pageStore.segments[std::size_t(m_pages.segmentOf(handle))].buffer.id();
        for (std::size_t j = 0; j < pages; ++j)
            glNamedBufferSubData(buffer, GLintptr(pageBytes(at[j])), GLsizeiptr(pageBytes(1)),
                                 all.data() + j * kBlockMapPageWords);
    }
    return handle;
}

void BlockMapPoolGL::remove(int handle) {
    if (handle < 0 || std::size_t(handle) >= m_slots.size() || !m_slots[std::size_t(handle)].live) return;
    m_pages.release(handle);
    m_tiles.release(handle);
    m_slots[std::size_t(handle)] = Slot{};
    m_freeSlots.push_back(handle);
    --m_live; // its segments are given back by prepare(), once the maps have needed fewer for a while
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

std::uint64_t BlockMapPoolGL::allocatedBytes() const { return tileBytes(m_tiles.held()) + pageBytes(m_pages.held()); }

std::uint64_t BlockMapPoolGL::usedBytes() const { return tileBytes(m_live) + pageBytes(m_pages.inUse()); }

void BlockMapPoolGL::setInstances(const std::vector<Instance>& instances) {
    std::vector<Record> records(std::max<std::size_t>(instances.size(), 1), Record{});
    m_instancePair.resize(instances.size());
    for (std::size_t i = 0; i < instances.size(); ++i) {
        const int h = instances[i].handle;
        const Slot& s = m_slots[std::size_t(h)];
        const std::vector<std::uint32_t>& pages = m_pages.unitsOf(h);
        const int pair = m_tiles.segmentOf(h) * kPairStride + std::max(m_pages.segmentOf(h), 0);
        m_instancePair[i] = pair;
        Record& r = records[i];
        r = Record{{float(s.origin.x), float(s.origin.y), float(s.texel), float(s.zBase)},
                   {float(s.zTop), float(pair), 0.0f, 0.0f},
                   {0, 0, std::int32_t(m_tiles.unitsOf(h)[0]) * m_size * m_size, std::int32_t(pages.size())},
                   {s.wallTexels, s.span, s.columns, pages.empty() ? 0 : std::int32_t(pages[0])},
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
    p.set("uBmWords", kUnit + 1);
    p.use();
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, m_instances.id());
    glBindVertexArray(m_vao.id());
    glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE); // reversed Z in [0, 1]: gl_FragDepth is the hit's clip z / w
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_GREATER);
    glEnable(GL_CULL_FACE);
    // One fragment per pixel either way: the front faces (the eye outside), or the back faces (inside it or not).
    glCullFace(frontFaces ? GL_BACK : GL_FRONT);
}

int BlockMapPoolGL::draw(const gl::ShaderProgram& p, int first, int count) const {
    if (count <= 0) return 0;
    // The pairs of segments the instances use, in order of first use: a draw call each, with that pair's storage
    // bound; the vertex shader drops the boxes of the other pairs (uBmPair; -1: every instance is of the one pair).
    std::vector<int> pairs;
    for (int i = first; i < first + count; ++i)
        if (std::find(pairs.begin(), pairs.end(), m_instancePair[std::size_t(i)]) == pairs.end())
            pairs.push_back(m_instancePair[std::size_t(i)]);
    p.set("uFirstInstance", first);
    for (const int pair : pairs) {
        const std::size_t ps = std::size_t(pair % kPairStride);
        glBindTextureUnit(GLuint(kUnit), m_tileStore.segments[std::size_t(pair / kPairStride)].texture.id());
        glBindTextureUnit(GLuint(kUnit + 1), ps < m_pageStore.segments.size() ? m_pageStore.segments[ps].texture.id() : 0);
        p.set("uBmPair", pairs.size() == 1 ? -1 : pair);
        glDrawArraysInstanced(GL_TRIANGLES, 0, 36, count);
    }
    return int(pairs.size());
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
