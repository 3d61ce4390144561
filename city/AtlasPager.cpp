#include "AtlasPager.h"

#include "AtlasCodec.h"
#include "TextureSource.h"

#include <algorithm>
#include <set>
#include <tuple>

namespace seasonview::city {

AtlasPager::AtlasPager(const AtlasTreeFile& file, int tree, const PagerSettings& settings, Loader loader)
    : m_file(file), m_tree(tree), m_settings(settings), m_loader(std::move(loader)) {
    // An atlas's bytes as RGB(A)8 with mips, however it is uploaded: the yardstick of textureParts (BC1 atlases are
    // a sixth of it, and 512² facade photos would otherwise be cut into nine blocks each for no gain).
    const int size = m_file.info.atlasSize;
    for (int l = 0; l < atlasLevels(size); ++l)
        m_atlasRgbBytes += atlasLevelBytes(AtlasFormat::Deflate, m_file.trees[std::size_t(m_tree)].alpha, size, l);
    m_atlasRgbBytes = std::max<std::uint64_t>(m_atlasRgbBytes, 1);
    if (m_settings.threaded) m_thread = std::thread([this] { worker(); });
}

AtlasPager::~AtlasPager() {
    {
        std::lock_guard lock(m_mutex);
        m_stop = true;
    }
    m_cv.notify_all();
    if (m_thread.joinable()) m_thread.join();
}

std::uint64_t AtlasPager::textureBytes(std::uint32_t texture) const {
    const glm::ivec2 s = m_file.textureSizes[texture];
    return std::uint64_t(std::max(s.x, 1)) * std::uint64_t(std::max(s.y, 1)) * 4u * 4u / 3u; // RGBA8 + mips
}

template <class Map> bool AtlasPager::anyPart(const Map& blocks, std::uint32_t texture) {
    const auto it = blocks.lower_bound(BlockKey{BlockKey::Kind::Texture, texture, 0});
    return it != blocks.end() && it->first.kind == BlockKey::Kind::Texture && it->first.index == texture;
}

std::pair<std::uint64_t, std::uint64_t> AtlasPager::heldBytes() const {
    // Both maps are ordered by (kind, index, part): a texture's parts are neighbours, counted at the first.
    std::uint64_t resident = 0, reserved = 0;
    const BlockKey* last = nullptr;
    auto first = [&](const BlockKey& k) {
        const bool is = !last || last->kind != k.kind || last->index != k.index;
        last = &k;
        return is;
    };
    for (const auto& [k, f] : m_resident)
        if (!split(k)) resident += blockBytes(k);
        else if (first(k)) resident += textureBytes(k.index);
    last = nullptr;
    for (const auto& [k, b] : m_reserved)
        if (!split(k)) reserved += b;
        else if (first(k) && !anyPart(m_resident, k.index)) reserved += textureBytes(k.index);
    return {resident, reserved};
}

std::uint64_t AtlasPager::blockBytes(const BlockKey& key) const {
    if (key.kind == BlockKey::Kind::BlockMap)
        return m_settings.blockMaps && key.index < m_settings.blockMaps->records().size()
                   ? m_settings.blockMaps->records()[key.index].gpuBytes()
                   : 0;
    if (key.kind == BlockKey::Kind::Atlas) {
        const AtlasTreeData& t = m_file.trees[std::size_t(m_tree)];
        const int size = m_file.info.atlasSize;
        std::uint64_t n = 0;
        // Deflate atlases are uploaded decoded (RGB(A)8 with the stored mips), BC ones as they are unless the
        // renderer decodes them (CityRendererGL: software rasterisers, no S3TC).
        const AtlasFormat uploaded = m_settings.decodedAtlases ? AtlasFormat::Deflate : m_file.info.format;
        for (int l = 0; l < atlasLevels(size); ++l) n += atlasLevelBytes(uploaded, t.alpha, size, l);
        return n;
    }
    const glm::ivec2 s = m_file.textureSizes[key.index];
    const std::uint64_t whole = textureBytes(key.index);
    const int parts = textureParts(key.index);
    if (parts == 1) return whole;
    const auto [r0, r1] = partRows(key.index, key.part);
    return whole * std::uint64_t(r1 - r0) / std::uint64_t(std::max(s.y, 1)); // its share of the rows (and mips)
}

int AtlasPager::textureParts(std::uint32_t texture) const {
    const glm::ivec2 s = m_file.textureSizes[texture];
    const std::uint64_t whole = textureBytes(texture);
    const std::uint64_t atlas = m_atlasRgbBytes;
    if (whole <= 2 * atlas) return 1;
    // Bands of about an atlas's bytes (§4.6: blocks of about equal size), at most one per row; the count is that of
    // the bands of ceil(h / parts) rows, so none is empty (4096 rows in 65 parts would leave the 65th without one).
    const std::uint64_t h = std::uint64_t(std::max(s.y, 1));
    const std::uint64_t parts = std::min<std::uint64_t>({(whole + atlas - 1) / atlas, h, 65535});
    const std::uint64_t per = (h + parts - 1) / parts;
    return int((h + per - 1) / per);
}

std::pair<int, int> AtlasPager::partRows(std::uint32_t texture, int part) const {
    const int h = std::max(m_file.textureSizes[texture].y, 1), parts = textureParts(texture);
    const int per = (h + parts - 1) / parts;
    return {std::min(h, part * per), std::min(h, (part + 1) * per)};
}

bool AtlasPager::textureResident(std::uint32_t texture) const {
    const int parts = textureParts(texture);
    for (int p = 0; p < parts; ++p)
        if (!m_resident.count({BlockKey::Kind::Texture, texture, std::uint16_t(p)})) return false;
    return true;
}

std::string AtlasPager::error() const {
    std::lock_guard lock(m_mutex);
    return m_firstError;
}

Result<LoadedBlock> AtlasPager::load(const BlockKey& key) const {
    if (m_loader) return m_loader(key);
    LoadedBlock b;
    b.key = key;
    b.bytes = blockBytes(key);
    if (key.kind == BlockKey::Kind::BlockMap) {
        if (!m_settings.blockMaps) return Error{"BlockMap " + std::to_string(key.index) + " asked of a pager without BlockMaps"};
        auto m = m_settings.blockMaps->read(key.index);
        if (!m) return m.error();
        b.size = glm::ivec2(m->size);
        b.blockMapPacked = std::make_shared<const BlockMapPacked>(packBlockMap(*m));
        b.blockMap = std::make_shared<const BlockMap>(std::move(*m));
        return b;
    }
    if (key.kind == BlockKey::Kind::Atlas) {
        auto blob = m_file.readAtlasBlob(m_tree, int(key.index));
        if (!blob) return blob.error();
        b.data = std::move(*blob);
        b.size = glm::ivec2(m_file.info.atlasSize);
        return b;
    }
    const int parts = textureParts(key.index);
    if (parts == 1) {
        auto tex = readSourceTexture(m_file.textures[key.index]);
        if (!tex) return tex.error();
        b.size = tex->sizes[0];
        b.data = std::move(tex->mips[0]);
        for (std::size_t l = 1; l < tex->mips.size(); ++l) {
            b.mips.push_back(std::move(tex->mips[l]));
            b.mipFirstRows.push_back(0);
        }
        return b;
    }
    // One band of rows: the texture is decoded once for its parts (kept until another one is).
    std::shared_ptr<const SourceTexture> tex;
    {
        std::lock_guard lock(m_decodedMutex);
        if (m_decodedIndex == key.index) tex = m_decoded;
    }
    if (!tex) {
        auto read = readSourceTexture(m_file.textures[key.index]);
        if (!read) return read.error();
        tex = std::make_shared<const SourceTexture>(std::move(*read));
        std::lock_guard lock(m_decodedMutex);
        m_decodedIndex = key.index;
        m_decoded = tex;
    }
    const glm::ivec2 size = tex->sizes[0];
    if (size != m_file.textureSizes[key.index])
        return Error{m_file.textures[key.index].path + ": the texture's size changed since the tree was built"};
    const auto [r0, r1] = partRows(key.index, key.part);
    auto rows = [&](std::size_t l, int first, int end) {
        const std::size_t row = std::size_t(tex->sizes[l].x) * 4;
        const auto& px = tex->mips[l];
        return std::vector<std::uint8_t>(px.begin() + std::ptrdiff_t(row * std::size_t(first)),
                                         px.begin() + std::ptrdiff_t(row * std::size_t(end)));
    };
    b.size = size;
    b.parts = parts;
    b.firstRow = r0;
    b.rows = r1 - r0;
    b.data = rows(0, r0, r1);
    for (std::size_t l = 1; l < tex->mips.size(); ++l) {
        const auto [m0, m1] = bandMipRows(r0, r1, size.y, int(l));
        b.mips.push_back(rows(l, m0, m1));
        b.mipFirstRows.push_back(m0);
    }
    return b;
}

std::pair<int, int> bandMipRows(int r0, int r1, int height, int level) {
    const int levelHeight = std::max(height >> level, 1);
    const int first = std::min(r0 >> level, levelHeight);
    return {first, r1 >= height ? levelHeight : std::min(r1 >> level, levelHeight)};
}

void AtlasPager::worker() {
    for (;;) {
        BlockKey key;
        {
            std::unique_lock lock(m_mutex);
            m_cv.wait(lock, [&] { return m_stop || !m_queue.empty(); });
            if (m_stop) return;
            key = m_queue.front();
            m_queue.pop_front();
        }
        auto r = load(key);
        std::lock_guard lock(m_mutex);
        if (r) m_done.push_back(std::move(*r));
        else {
            m_errors.emplace_back(key, r.error().message);
            if (m_firstError.empty()) m_firstError = r.error().message;
        }
    }
}

bool AtlasPager::evictOne(const std::map<BlockKey, LoadOrder>& ideal, Frame& out) {
    // The least recently requested resident block outside the ideal set, never the root's atlas.
    auto victim = m_resident.end();
    for (auto it = m_resident.begin(); it != m_resident.end(); ++it) {
        if (ideal.count(it->first) || (it->first.kind == BlockKey::Kind::Atlas && it->first.index == 0)) continue;
        if (victim == m_resident.end() || it->second < victim->second) victim = it;
    }
    if (victim == m_resident.end()) return false;
    const BlockKey v = victim->first;
    if (!split(v)) {
        out.evict.push_back(v);
        m_resident.erase(victim);
        ++m_stats.evicted;
        return true;
    }
    // Every resident part of it (none is in the ideal set: the set takes a texture whole).
    for (auto it = m_resident.lower_bound(BlockKey{v.kind, v.index, 0});
         it != m_resident.end() && it->first.kind == v.kind && it->first.index == v.index;) {
        out.evict.push_back(it->first);
        it = m_resident.erase(it);
        ++m_stats.evicted;
    }
    return true;
}

AtlasPager::Frame AtlasPager::update(const std::vector<BlockRequest>& asked) {
    ++m_frame;
    Frame out;

    // Original textures split into parts: every part, in the request's place.
    std::vector<BlockRequest> expanded;
    const std::vector<BlockRequest>* reqs = &asked;
    if (std::any_of(asked.begin(), asked.end(), [&](const BlockRequest& r) {
            return r.key.kind == BlockKey::Kind::Texture && textureParts(r.key.index) > 1;
        })) {
        expanded.reserve(asked.size() * 2);
        for (const auto& r : asked) {
            const int parts = r.key.kind == BlockKey::Kind::Texture ? textureParts(r.key.index) : 1;
            for (int p = 0; p < parts; ++p) {
                expanded.push_back(r);
                expanded.back().key.part = std::uint16_t(parts > 1 ? p : r.key.part);
            }
        }
        reqs = &expanded;
    }
    const std::vector<BlockRequest>& requests = *reqs;

    // The ideal block set: requests in priority order while they fit the capacity (the root first: it is always
    // Needed and nearest to the front). A split texture is in it with all its parts or not at all: the set never
    // stops between its bands (a partial texture cannot be drawn), and one part that failed to load fails it whole.
    // Each ideal block's place in the order blocks are loaded: the coarser first within a category (its tree level:
    // §4.6's "parents of needed nodes first", for every block: a coarse atlas or map stands in for all below it, and
    // stays useful while the eye moves on, where a fine block near the eye may be behind it by the time it is in),
    // then the request's place in priority order (a split texture's parts share it).
    std::map<BlockKey, LoadOrder> ideal;
    std::uint64_t idealBytes = 0, requestedBytes = 0;
    bool full = false;
    for (std::size_t rank = 0; rank < asked.size(); ++rank) {
        const BlockRequest& r = asked[rank];
        if (r.category == BlockCategory::Unused) break;
        const int parts = r.key.kind == BlockKey::Kind::Texture ? textureParts(r.key.index) : 1;
        const bool failed = std::any_of(m_failed.begin(), m_failed.end(), [&](const BlockKey& k) {
            return parts > 1 ? k.kind == BlockKey::Kind::Texture && k.index == r.key.index : k == r.key;
        });
        if (failed) continue;
        const std::uint64_t b = parts > 1 ? textureBytes(r.key.index) : blockBytes(r.key);
        requestedBytes += b;
        if (full || idealBytes + b > m_settings.capacityBytes) {
            full = true; // the rest is counted in requestedBytes only
            continue;
        }
        idealBytes += b;
        const LoadOrder order{int(r.category), r.level, rank};
        if (parts == 1) ideal.emplace(r.key, order);
        else
            for (int p = 0; p < parts; ++p) ideal.emplace(BlockKey{r.key.kind, r.key.index, std::uint16_t(p)}, order);
    }
    for (const auto& r : requests)
        if (auto it = m_resident.find(r.key); it != m_resident.end()) it->second = m_frame;

    // Finished loads become ready; queued loads that left the ideal set are dropped, the others wait in this frame's
    // load order (the view has changed since they were queued), and so do loaded blocks waiting for the upload budget.
    const auto inLoadOrder = [&](const BlockKey& a, const BlockKey& b) { return ideal.at(a) < ideal.at(b); };
    {
        std::lock_guard lock(m_mutex);
        for (auto& d : m_done) m_ready.push_back(std::move(d));
        m_done.clear();
        for (auto& [key, message] : m_errors) {
            m_reserved.erase(key);
            m_failed.push_back(key);
        }
        m_errors.clear();
        for (auto it = m_queue.begin(); it != m_queue.end();) {
            if (!ideal.count(*it)) {
                m_reserved.erase(*it);
                it = m_queue.erase(it);
            } else {
                ++it;
            }
        }
        std::stable_sort(m_queue.begin(), m_queue.end(), inLoadOrder);
    }
    std::stable_sort(m_ready.begin(), m_ready.end(), [&](const LoadedBlock& a, const LoadedBlock& b) {
        const auto ia = ideal.find(a.key), ib = ideal.find(b.key); // one that left the ideal set: last (dropped)
        if (ia == ideal.end() || ib == ideal.end()) return ib == ideal.end() && ia != ideal.end();
        return ia->second < ib->second;
    });

    // Requests of this frame: missing ideal blocks in load order, room made by evicting resident blocks outside
    // the ideal set (least recently requested first), never the root. A split texture costs its whole bytes with its
    // first part held (the GL side allocates it whole then) and nothing more with the others; it is evicted with all
    // its resident parts at once (only then is its allocation freed).
    auto usedBytes = [&] {
        const auto [resident, reserved] = heldBytes();
        return resident + reserved;
    };
    std::uint64_t used = usedBytes();
    std::size_t inFlight = m_reserved.size() - m_ready.size();
    // Each missing block with its place, looked up once (a frame may miss a thousand).
    std::vector<std::pair<LoadOrder, const BlockRequest*>> missingBlocks;
    for (const auto& r : requests)
        if (auto it = ideal.find(r.key); it != ideal.end() && !m_resident.count(r.key) && !m_reserved.count(r.key))
            missingBlocks.emplace_back(it->second, &r);
    std::stable_sort(missingBlocks.begin(), missingBlocks.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    const std::size_t missing = missingBlocks.size();
    for (const auto& [place, next] : missingBlocks) {
        const BlockRequest& r = *next;
        if (int(inFlight) >= m_settings.queueLength && m_settings.threaded) {
            // The loader's queue is full: the last queued block (load order, not yet loading), if it comes after
            // this one, gives it its place.
            std::lock_guard lock(m_mutex);
            if (m_queue.empty() || ideal.at(m_queue.back()) <= place) continue;
            m_reserved.erase(m_queue.back());
            m_queue.pop_back();
            --inFlight;
            used = usedBytes();
        }
        if (int(inFlight) >= m_settings.queueLength) continue;
        const std::uint64_t b = !split(r.key) ? blockBytes(r.key)
                                : anyPart(m_resident, r.key.index) || anyPart(m_reserved, r.key.index) ? 0
                                                                                                       : textureBytes(r.key.index);
        while (used + b > m_settings.capacityBytes && evictOne(ideal, out)) used = usedBytes();
        if (used + b > m_settings.capacityBytes) break; // in-flight leftovers still hold the room: next frame
        used += b;
        m_reserved[r.key] = blockBytes(r.key);
        ++inFlight;
        if (m_settings.threaded) {
            std::lock_guard lock(m_mutex); // in load order, after the blocks that share its place
            m_queue.insert(std::upper_bound(m_queue.begin(), m_queue.end(), r.key, inLoadOrder), r.key);
        } else {
            auto loaded = load(r.key);
            if (loaded) m_ready.push_back(std::move(*loaded));
            else {
                m_reserved.erase(r.key);
                m_failed.push_back(r.key);
                used = usedBytes();
                if (m_firstError.empty()) m_firstError = loaded.error().message;
            }
        }
    }
    if (m_settings.threaded) m_cv.notify_all();

    // Hand out ready blocks within the upload budget (at least one per frame); a ready block that left the ideal
    // set while loading is dropped.
    std::uint64_t budget = 0;
    while (!m_ready.empty() && (budget == 0 || budget + m_ready.front().bytes <= m_settings.uploadBytesPerFrame)) {
        LoadedBlock b = std::move(m_ready.front());
        m_ready.pop_front();
        m_reserved.erase(b.key);
        if (!ideal.count(b.key)) continue;
        budget += b.bytes;
        m_resident[b.key] = m_frame;
        m_stats.uploadedBytes += b.bytes;
        ++m_stats.loaded;
        out.upload.push_back(std::move(b));
    }

    std::tie(m_stats.residentBytes, m_stats.reservedBytes) = heldBytes();
    m_stats.residentBlocks = m_resident.size();
    m_stats.queued = m_reserved.size();
    m_stats.idealBytes = idealBytes;
    m_stats.requestedBytes = requestedBytes;
    m_stats.idealBlocks = ideal.size();
    m_stats.idealMissing = missing;
    return out;
}

AtlasPager::Frame AtlasPager::complete(const std::vector<BlockRequest>& requests) {
    Frame all;
    for (int guard = 0; guard < 100000; ++guard) {
        Frame f = update(requests);
        for (auto& b : f.upload) all.upload.push_back(std::move(b));
        for (auto& k : f.evict) {
            // Uploaded earlier in this call and evicted again: never handed out.
            auto it = std::find_if(all.upload.begin(), all.upload.end(), [&](const LoadedBlock& b) { return b.key == k; });
            if (it != all.upload.end()) all.upload.erase(it);
            else all.evict.push_back(k);
        }
        if (m_stats.idealMissing == 0 && m_stats.queued == 0) break;
        if (m_settings.threaded && f.upload.empty()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return all;
}

} // namespace seasonview::city
