#include "BlockMapGL.h"

#include "TerrainMeshGL.h" // kNearPlane

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>
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
    : m_size(mapSize), m_instances(gl::Buffer::create()), m_vao(gl::VertexArray::create()) {}

std::uint64_t BlockMapPoolGL::tileBytes(std::uint64_t tiles) const {
    return std::uint64_t(m_size) * std::uint64_t(m_size) * 8 * tiles;
}

std::uint64_t BlockMapPoolGL::pageBytes(std::uint64_t pages) { return pages * kBlockMapPageWords * 4; }

std::uint64_t BlockMapPoolGL::tileBytesAllocated() const {
    std::uint64_t tiles = 0;
    for (const TileSegment& g : m_tileSegments) tiles += std::uint64_t(g.tiles);
    return tileBytes(tiles);
}

std::uint64_t BlockMapPoolGL::pageBytesAllocated() const {
    std::uint64_t pages = 0;
    for (const PageSegment& g : m_pageSegments) pages += g.pages;
    return pageBytes(pages);
}

std::size_t BlockMapPoolGL::freeTiles() const {
    std::size_t n = 0;
    for (const TileSegment& g : m_tileSegments) n += g.free.size();
    return n;
}

std::size_t BlockMapPoolGL::freePages() const {
    std::size_t n = 0;
    for (const PageSegment& g : m_pageSegments) n += g.free.size();
    return n;
}

namespace {
std::size_t maxBufferTexels() {
    GLint texels = 0;
    glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &texels);
    return std::size_t(std::max(texels, 1));
}
std::size_t maxSegmentPages() { return std::max<std::size_t>(maxBufferTexels() / kBlockMapPageWords, 1); }
} // namespace

int BlockMapPoolGL::maxSegmentTiles() const {
    const std::size_t n2 = std::size_t(m_size) * std::size_t(m_size);
    return int(std::clamp<std::size_t>(maxBufferTexels() / std::max<std::size_t>(n2, 1), 1, 1u << 30));
}

Status BlockMapPoolGL::addTileSegment(int tiles) {
    TileSegment g;
    const int most = maxSegmentTiles();
    g.tiles = std::clamp(tiles, 1, most);
    // Never a power of two, as no other segment is: llvmpipe builds a shader variant for each kind of texture bound,
    // power-of-two sizes apart (a first draw with the other kind waited 340 ms for it).
    while ((g.tiles & (g.tiles - 1)) == 0 && g.tiles < most) ++g.tiles;
    g.buffer = gl::Buffer::create();
    glNamedBufferData(g.buffer.id(), GLsizeiptr(tileBytes(std::uint64_t(g.tiles))), nullptr, GL_DYNAMIC_DRAW);
    g.texels = gl::Texture::create(GL_TEXTURE_BUFFER);
    glTextureBuffer(g.texels.id(), GL_RG32UI, g.buffer.id());
    g.free.add(0, std::uint32_t(g.tiles));
    g.owner.assign(std::size_t(g.tiles), -1);
    m_tileSegments.push_back(std::move(g));
    return Ok{};
}

Status BlockMapPoolGL::addPageSegment(std::size_t pages) {
    const std::size_t most = maxSegmentPages();
    if (pages > most)
        return Error{"BlockMaps: " + std::to_string(pages * kBlockMapPageWords) +
                     " words of walls in one segment do not fit this GL's " +
                     std::to_string(most * kBlockMapPageWords) + "-texel texture buffers"};
    PageSegment g;
    g.pages = std::max<std::size_t>(pages, 1);
    while ((g.pages & (g.pages - 1)) == 0 && g.pages < most) ++g.pages; // as addTileSegment
    g.buffer = gl::Buffer::create();
    glNamedBufferData(g.buffer.id(), GLsizeiptr(pageBytes(g.pages)), nullptr, GL_DYNAMIC_DRAW);
    g.words = gl::Texture::create(GL_TEXTURE_BUFFER);
    glTextureBuffer(g.words.id(), GL_R32UI, g.buffer.id());
    g.free.add(0, std::uint32_t(g.pages));
    g.owner.assign(g.pages, -1);
    m_pageSegments.push_back(std::move(g));
    return Ok{};
}

namespace {
// The two of `used` (per segment) with the fewest in use, the lower index first.
std::pair<int, int> twoLeastUsed(const std::vector<std::size_t>& used) {
    std::vector<int> order(used.size());
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](int x, int y) { return used[std::size_t(x)] < used[std::size_t(y)]; });
    return {std::min(order[0], order[1]), std::max(order[0], order[1])};
}
// A segment index after segments a < b are erased.
int afterErasing(int i, int a, int b) { return i - (i > a ? 1 : 0) - (i > b ? 1 : 0); }
} // namespace

std::size_t BlockMapPoolGL::pagesPerMap() const {
    return m_live > 0 ? std::max<std::size_t>((m_usedPages + m_live - 1) / m_live, 1) : 1;
}

Status BlockMapPoolGL::growTiles(std::size_t tiles) {
    // What is needed, and up to half the tiles held more (at least kMinTiles in all) within the limit: nothing
    // resident moves, so a generous segment costs only the memory the limit allows.
    std::size_t held = 0;
    for (const TileSegment& g : m_tileSegments) held += std::size_t(g.tiles);
    const std::uint64_t needed = allocatedBytes() + tileBytes(tiles);
    // Room for whole maps: each extra tile with the pages a map takes on average (free tiles without pages for
    // their maps would be room lost under the limit).
    const std::uint64_t perMap = tileBytes(1) + pageBytes(pagesPerMap());
    const std::size_t room = m_byteLimit > needed ? std::size_t((m_byteLimit - needed) / perMap) : 0;
    const std::size_t wanted = std::max(held / 2, tiles < std::size_t(kMinTiles) ? kMinTiles - tiles : 0);
    std::size_t n = tiles + std::min(wanted, room);
    // At kMaxSegments, the two segments with the fewest live tiles and the new room made one (their tiles copied).
    if (m_tileSegments.size() >= std::size_t(kMaxSegments)) {
        std::vector<std::size_t> used;
        for (const TileSegment& g : m_tileSegments) used.push_back(std::size_t(g.used));
        const auto [a, b] = twoLeastUsed(used);
        if (used[std::size_t(a)] + used[std::size_t(b)] + n <= std::size_t(maxSegmentTiles())) return mergeTiles(a, b, n);
    }
    while (n > 0) {
        const int part = int(std::min<std::size_t>(n, std::size_t(maxSegmentTiles())));
        if (auto st = addTileSegment(part); !st) return st;
        n -= std::size_t(part);
    }
    return Ok{};
}

Status BlockMapPoolGL::growPages(std::size_t pages) {
    // As growTiles: what is needed in one segment (a map's pages lie in one), and up to half the pages held more.
    std::size_t held = 0;
    for (const PageSegment& g : m_pageSegments) held += g.pages;
    const std::uint64_t needed = allocatedBytes() + pageBytes(pages);
    // Room for whole maps, as growTiles: the extra pages with a tile for each map's worth of them.
    const std::size_t perMap = pagesPerMap();
    const std::size_t room =
        m_byteLimit > needed ? std::size_t((m_byteLimit - needed) / (tileBytes(1) + pageBytes(perMap))) * perMap : 0;
    const std::size_t wanted = std::max(held / 2, pages < kMinPages ? kMinPages - pages : 0);
    const std::size_t n = std::min(pages + std::min(wanted, room), std::max(pages, maxSegmentPages()));
    if (m_pageSegments.size() >= std::size_t(kMaxSegments)) {
        std::vector<std::size_t> used;
        for (const PageSegment& g : m_pageSegments) used.push_back(g.used);
        const auto [a, b] = twoLeastUsed(used);
        if (used[std::size_t(a)] + used[std::size_t(b)] + n <= maxSegmentPages()) return mergePages(a, b, n);
    }
    return addPageSegment(n);
}

void BlockMapPoolGL::moveTile(int handle, int to) {
    Slot& s = m_slots[std::size_t(handle)];
    TileSegment &from = m_tileSegments[std::size_t(s.tileSegment)], &dst = m_tileSegments[std::size_t(to)];
    const int t = int(dst.free.take());
    const GLsizeiptr bytes = GLsizeiptr(tileBytes(1));
    glCopyNamedBufferSubData(from.buffer.id(), dst.buffer.id(), GLintptr(s.tile) * bytes, GLintptr(t) * bytes, bytes);
    from.owner[std::size_t(s.tile)] = -1;
    from.free.release(std::uint32_t(s.tile));
    --from.used;
    dst.owner[std::size_t(t)] = handle;
    ++dst.used;
    s.tileSegment = to;
    s.tile = t;
    m_movedBytes += tileBytes(1);
}

void BlockMapPoolGL::movePages(int handle, int to) {
    Slot& s = m_slots[std::size_t(handle)];
    PageSegment &from = m_pageSegments[std::size_t(s.pageSegment)], &dst = m_pageSegments[std::size_t(to)];
    const GLsizeiptr bytes = GLsizeiptr(pageBytes(1));
    for (std::uint32_t& p : s.pages) {
        const std::uint32_t q = dst.free.take();
        glCopyNamedBufferSubData(from.buffer.id(), dst.buffer.id(), GLintptr(p) * bytes, GLintptr(q) * bytes, bytes);
        from.owner[p] = -1;
        from.free.release(p);
        --from.used;
        dst.owner[q] = handle;
        ++dst.used;
        p = q;
    }
    s.pageSegment = to;
    writePageTable(handle);
    m_movedBytes += pageBytes(s.pages.size());
}

void BlockMapPoolGL::writePageTable(int handle) {
    const Slot& s = m_slots[std::size_t(handle)];
    if (s.pages.empty()) return;
    glNamedBufferSubData(m_pageSegments[std::size_t(s.pageSegment)].buffer.id(), GLintptr(pageBytes(s.pages[0])),
                         GLsizeiptr(s.pages.size() * 4), s.pages.data());
}

void BlockMapPoolGL::shrinkTiles(std::size_t need, bool over) {
    for (bool gave = true; gave && !m_tileSegments.empty();) {
        gave = false;
        std::size_t held = 0;
        for (const TileSegment& g : m_tileSegments) held += std::size_t(g.tiles);
        // The segment with the most free tiles whose live ones the others' free tiles can take, leaving what is needed
        // (over the limit) or a quarter more.
        int pick = -1;
        for (int i = 0; i < int(m_tileSegments.size()); ++i) {
            const TileSegment& g = m_tileSegments[std::size_t(i)];
            const std::size_t left = held - std::size_t(g.tiles);
            if (left < (over ? need : need + need / 4) || freeTiles() - g.free.size() < std::size_t(g.used)) continue;
            if (pick < 0 || g.free.size() > m_tileSegments[std::size_t(pick)].free.size()) pick = i;
        }
        if (pick < 0) return;
        for (std::size_t t = 0; t < m_tileSegments[std::size_t(pick)].owner.size(); ++t) {
            const int h = m_tileSegments[std::size_t(pick)].owner[t];
            if (h < 0) continue;
            int to = 0;
            while (to == pick || m_tileSegments[std::size_t(to)].free.empty()) ++to;
            moveTile(h, to);
        }
        m_tileSegments.erase(m_tileSegments.begin() + pick);
        for (Slot& s : m_slots)
            if (s.live && s.tileSegment > pick) --s.tileSegment;
        gave = !over || allocatedBytes() > m_byteLimit;
    }
}

void BlockMapPoolGL::shrinkPages(std::size_t need, bool over) {
    for (bool gave = true; gave && !m_pageSegments.empty();) {
        gave = false;
        std::size_t held = 0;
        for (const PageSegment& g : m_pageSegments) held += g.pages;
        // As shrinkTiles; each map of the segment must find one other segment with room for all its pages.
        int pick = -1;
        std::vector<int> maps, target;
        for (int i = 0; i < int(m_pageSegments.size()); ++i) {
            const PageSegment& g = m_pageSegments[std::size_t(i)];
            if (held - g.pages < (over ? need : need + need / 4)) continue;
            if (pick >= 0 && g.free.size() <= m_pageSegments[std::size_t(pick)].free.size()) continue;
            std::vector<int> its;
            for (const int h : g.owner)
                if (h >= 0 && (its.empty() || its.back() != h)) its.push_back(h);
            std::sort(its.begin(), its.end());
            its.erase(std::unique(its.begin(), its.end()), its.end());
            std::vector<std::size_t> room(m_pageSegments.size());
            for (std::size_t j = 0; j < room.size(); ++j) room[j] = int(j) == i ? 0 : m_pageSegments[j].free.size();
            std::vector<int> to(its.size(), -1);
            bool fits = true;
            for (std::size_t k = 0; k < its.size() && fits; ++k) {
                const std::size_t n = m_slots[std::size_t(its[k])].pages.size();
                for (std::size_t j = 0; j < room.size() && to[k] < 0; ++j)
                    if (room[j] >= n) {
                        room[j] -= n;
                        to[k] = int(j);
                    }
                fits = to[k] >= 0;
            }
            if (!fits) continue;
            pick = i;
            maps = std::move(its);
            target = std::move(to);
        }
        if (pick < 0) return;
        for (std::size_t k = 0; k < maps.size(); ++k) movePages(maps[k], target[k]);
        m_pageSegments.erase(m_pageSegments.begin() + pick);
        for (Slot& s : m_slots)
            if (s.live && s.pageSegment > pick) --s.pageSegment;
        gave = !over || allocatedBytes() > m_byteLimit;
    }
}


Status BlockMapPoolGL::mergeTiles(int a, int b, std::size_t extra) {
    const std::size_t tiles = std::size_t(m_tileSegments[std::size_t(a)].used + m_tileSegments[std::size_t(b)].used);
    if (auto st = addTileSegment(int(tiles + extra)); !st) return st;
    const int into = int(m_tileSegments.size()) - 1;
    for (int h = 0; h < int(m_slots.size()); ++h) {
        const Slot& s = m_slots[std::size_t(h)];
        if (s.live && (s.tileSegment == a || s.tileSegment == b)) moveTile(h, into);
    }
    m_tileSegments.erase(m_tileSegments.begin() + b);
    m_tileSegments.erase(m_tileSegments.begin() + a);
    for (Slot& s : m_slots)
        if (s.live) s.tileSegment = afterErasing(s.tileSegment, a, b);
    return Ok{};
}

Status BlockMapPoolGL::mergePages(int a, int b, std::size_t extra) {
    if (auto st = addPageSegment(m_pageSegments[std::size_t(a)].used + m_pageSegments[std::size_t(b)].used + extra); !st)
        return st;
    const int into = int(m_pageSegments.size()) - 1;
    for (int h = 0; h < int(m_slots.size()); ++h) {
        const Slot& s = m_slots[std::size_t(h)];
        if (s.live && !s.pages.empty() && (s.pageSegment == a || s.pageSegment == b)) movePages(h, into);
    }
    m_pageSegments.erase(m_pageSegments.begin() + b);
    m_pageSegments.erase(m_pageSegments.begin() + a);
    for (Slot& s : m_slots)
        if (s.live) s.pageSegment = afterErasing(s.pageSegment, a, b);
    return Ok{};
}

Status BlockMapPoolGL::prepare(std::uint64_t bytes, std::size_t pagesComing, std::size_t mapsComing) {
    m_byteLimit = bytes;
    // Segments given back once the live and coming maps have needed under three quarters of the tiles (pages) for
    // kShrinkAfterFrames frames in a row, or at once when the pool holds more than the limit (the city's other
    // blocks need the room); one added when the free room cannot hold what comes.
    std::size_t tilesHeld = 0, pagesHeld = 0;
    for (const TileSegment& g : m_tileSegments) tilesHeld += std::size_t(g.tiles);
    for (const PageSegment& g : m_pageSegments) pagesHeld += g.pages;
    const std::size_t tilesNeed = m_live + mapsComing, pagesNeed = m_usedPages + pagesComing;
    m_underUsedFrames = 4 * tilesNeed < 3 * tilesHeld ? m_underUsedFrames + 1 : 0;
    if (m_underUsedFrames > 0 && (allocatedBytes() > bytes || m_underUsedFrames >= kShrinkAfterFrames)) {
        m_underUsedFrames = 0;
        shrinkTiles(tilesNeed, allocatedBytes() > bytes);
    }
    m_pagesUnderUsedFrames = 4 * pagesNeed < 3 * pagesHeld ? m_pagesUnderUsedFrames + 1 : 0;
    if (m_pagesUnderUsedFrames > 0 && (allocatedBytes() > bytes || m_pagesUnderUsedFrames >= kShrinkAfterFrames)) {
        m_pagesUnderUsedFrames = 0;
        shrinkPages(pagesNeed, allocatedBytes() > bytes);
    }
    if (freeTiles() < mapsComing)
        if (auto st = growTiles(mapsComing - freeTiles()); !st) return st;
    if (freePages() < pagesComing) return growPages(pagesComing);
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
    // Its pages first: a map that does not fit changes nothing.
    const std::size_t words = packed->words.size(), pages = blockMapPages(words);
    if (pages > kBlockMapPageWords) // its page table must fit its first page
        return Error{"BlockMaps: a map of " + std::to_string(words) + " wall words exceeds the pool's " +
                     std::to_string(kBlockMapPageWords * (kBlockMapPageWords - 1)) + " a map"};
    // The lowest segments with room: what is in use gathers there, and the others empty as maps leave.
    auto pageSegment = [&] {
        for (int i = 0; i < int(m_pageSegments.size()); ++i)
            if (m_pageSegments[std::size_t(i)].free.size() >= pages) return i;
        return -1;
    };
    auto tileSegment = [&] {
        for (int i = 0; i < int(m_tileSegments.size()); ++i)
            if (!m_tileSegments[std::size_t(i)].free.empty()) return i;
        return -1;
    };
    int ps = pages > 0 ? pageSegment() : 0;
    if (ps < 0) {
        if (auto st = growPages(pages); !st) return st.error();
        ps = pageSegment();
    }
    int ts = tileSegment();
    if (ts < 0) {
        if (auto st = growTiles(1); !st) return st.error();
        ts = tileSegment();
        if (pages > 0) ps = pageSegment(); // (a merge of tiles leaves the pages as they are; looked up again anyway)
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
    s.pageSegment = pages > 0 ? ps : 0;
    if (pages > 0) {
        PageSegment& g = m_pageSegments[std::size_t(ps)];
        for (std::size_t j = 0; j < pages; ++j) {
            const std::uint32_t p = g.free.take();
            g.owner[p] = handle;
            s.pages.push_back(p);
        }
        g.used += pages;
        m_usedPages += pages;
    }
    TileSegment& tg = m_tileSegments[std::size_t(ts)];
    s.tileSegment = ts;
    s.tile = int(tg.free.take());
    tg.owner[std::size_t(s.tile)] = handle;
    ++tg.used;
    ++m_live;
    glNamedBufferSubData(tg.buffer.id(), GLintptr(tileBytes(std::uint64_t(s.tile))), GLsizeiptr(tileBytes(1)),
                         packed->tile.data());
    if (pages > 0) {
        // The map's words as the shader reads them: its page table (a word per page), then its words; page by page.
        std::vector<std::uint32_t> all(pages * kBlockMapPageWords, 0u);
        std::copy(s.pages.begin(), s.pages.end(), all.begin());
        std::copy(packed->words.begin(), packed->words.end(), all.begin() + std::ptrdiff_t(pages));
        const GLuint buffer = m_pageSegments[std::size_t(ps)].buffer.id();
        for (std::size_t j = 0; j < pages; ++j)
            glNamedBufferSubData(buffer, GLintptr(pageBytes(s.pages[j])), GLsizeiptr(pageBytes(1)),
                                 all.data() + j * kBlockMapPageWords);
    }
    return handle;
}

void BlockMapPoolGL::remove(int handle) {
    if (handle < 0 || std::size_t(handle) >= m_slots.size() || !m_slots[std::size_t(handle)].live) return;
    Slot& s = m_slots[std::size_t(handle)];
    if (!s.pages.empty()) {
        PageSegment& g = m_pageSegments[std::size_t(s.pageSegment)];
        for (const std::uint32_t p : s.pages) {
            g.owner[p] = -1;
            g.free.release(p);
        }
        g.used -= s.pages.size();
        m_usedPages -= s.pages.size();
    }
    TileSegment& tg = m_tileSegments[std::size_t(s.tileSegment)];
    tg.owner[std::size_t(s.tile)] = -1;
    tg.free.release(std::uint32_t(s.tile));
    --tg.used;
    s = Slot{};
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

std::uint64_t BlockMapPoolGL::allocatedBytes() const { return tileBytesAllocated() + pageBytesAllocated(); }

std::uint64_t BlockMapPoolGL::usedBytes() const { return tileBytes(m_live) + pageBytes(m_usedPages); }

void BlockMapPoolGL::setInstances(const std::vector<Instance>& instances) {
    std::vector<Record> records(std::max<std::size_t>(instances.size(), 1), Record{});
    m_instancePair.resize(instances.size());
    for (std::size_t i = 0; i < instances.size(); ++i) {
        const int h = instances[i].handle;
        const Slot& s = m_slots[std::size_t(h)];
        const int pair = s.tileSegment * kPairStride + s.pageSegment;
        m_instancePair[i] = pair;
        Record& r = records[i];
        r = Record{{float(s.origin.x), float(s.origin.y), float(s.texel), float(s.zBase)},
                   {float(s.zTop), float(pair), 0.0f, 0.0f},
                   {0, 0, s.tile * m_size * m_size, std::int32_t(s.pages.size())},
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
        const TileSegment& t = m_tileSegments[std::size_t(pair / kPairStride)];
        const std::size_t ps = std::size_t(pair % kPairStride);
        glBindTextureUnit(GLuint(kUnit), t.texels.id());
        glBindTextureUnit(GLuint(kUnit + 1), ps < m_pageSegments.size() ? m_pageSegments[ps].words.id() : 0);
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
