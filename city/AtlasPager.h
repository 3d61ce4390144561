#pragma once
// Paging of a texture-atlas tree's blocks under a byte capacity (Buchholz's thesis §4.6): each frame the view's block
// requests (AtlasTraversal::requests, priority order) give the ideal block set — the Needed, Culled and ParentNeeded
// blocks of highest priority whose sizes sum to at most the capacity; missing ideal blocks are queued (at most
// `queueLength` at once, in the latest frame's order: coarser blocks first, then by priority; a block that comes first
// takes the place of one queued earlier that now comes after it) for a background loader; a block that does not fit
// evicts resident blocks outside the ideal set, least recently requested first. Loaded blocks are handed out for upload
// within a per-frame byte budget. The root atlas is loaded first and never evicted, so a texture is always available.
// Resident, queued, in-flight and waiting-for-upload bytes together never exceed the capacity. Blocks are of about
// equal size (§4.6): an original texture whose bytes exceed an atlas's more than twice is split into bands of rows of
// about an atlas's bytes each, paged like any block; it is usable once all its parts are resident. Such a texture
// enters and leaves the ideal set and the resident set whole (all its parts or none: a partial one is undrawable), and
// counts its whole GPU bytes while any part is resident or reserved (the GL side allocates it whole with its first
// band).
//
// BlockMaps (BlockMapTraversal.h) are blocks of the same pager when PagerSettings::blockMaps names their file: the
// far field's maps and the near field's atlases share one capacity and one loader.
//
// Plain C++ (the GL side, CityRendererGL, uploads what update() hands out and deletes what it evicts).
#include "AtlasTraversal.h"
#include "AtlasTree.h"
#include "BlockMap.h"
#include "TextureSource.h"
#include "Result.h"

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <thread>
#include <tuple>
#include <vector>

namespace seasonview::city {

struct PagerSettings {
    std::uint64_t capacityBytes = 256ull << 20;     // GPU bytes of resident blocks
    int queueLength = 8;                            // blocks requested from the loader at a time
    std::uint64_t uploadBytesPerFrame = 8ull << 20; // handed out for upload per frame (at least one block)
    bool threaded = true;                           // false: loads run inside update() (tests, stills)
    bool decodedAtlases = false;                    // BC atlases uploaded decoded: counted as RGB(A)8 bytes
    /// BlockMaps paged with the tree's blocks (kind BlockMap, index = record): read from this file, kept by
    /// reference (null: none).
    const BlockMapFile* blockMaps = nullptr;
};

/// A loaded block: an atlas's stored blob, or an original texture's RGBA8 level 0 (rows bottom-up): all of it, or
/// for a texture split into `parts` the rows [firstRow, firstRow + rows) of it.
struct LoadedBlock {
    BlockKey key;
    std::vector<std::uint8_t> data;
    glm::ivec2 size{0}; // the whole texture's (or atlas's) size
    std::uint64_t bytes = 0; // GPU bytes once uploaded
    int parts = 1, firstRow = 0, rows = 0; // rows 0: all of them
    /// Original textures: mip levels 1.. as 2×2 box averages from the origin (halveRgbaBox, made on the loader
    /// thread), the same filter as the atlases' mips, not the driver's (Mesa's for non-power-of-two sizes is a
    /// bilinear blit that drifts by up to a texel). A band holds its share of each level's rows, from
    /// mipFirstRows[l - 1]; the bands' shares partition every level. Empty (a custom loader): the driver's mips.
    std::vector<std::vector<std::uint8_t>> mips;
    std::vector<int> mipFirstRows;
    /// A BlockMap block: the map, read and checked (its CRC) on the loader thread, and packed for upload.
    std::shared_ptr<const BlockMap> blockMap;
    std::shared_ptr<const BlockMapPacked> blockMapPacked;
};

/// Rows [first, end) of mip level `level` that the band of level-0 rows [r0, r1) of a texture `height` rows high
/// carries: floor(r0 / 2^level) up to floor(r1 / 2^level), or to the level's last row for the last band.
std::pair<int, int> bandMipRows(int r0, int r1, int height, int level);

struct PagerStats {
    std::uint64_t residentBytes = 0, reservedBytes = 0, idealBytes = 0;
    // The last update's requests (Unused aside), what they would take whole: above the capacity, the ideal set
    // stopped short of them (the view wants more than fits).
    std::uint64_t requestedBytes = 0;
    std::size_t residentBlocks = 0, queued = 0, idealBlocks = 0, idealMissing = 0;
    std::uint64_t loaded = 0, evicted = 0, uploadedBytes = 0; // totals since creation
};

class AtlasPager {
public:
    using Loader = std::function<Result<LoadedBlock>(const BlockKey&)>;

    /// Pages tree `tree` of `file` (kept by reference). `loader`: how a block is read (default: the file's atlas
    /// blobs and the original texture files).
    AtlasPager(const AtlasTreeFile& file, int tree, const PagerSettings& settings, Loader loader = {});
    ~AtlasPager();
    AtlasPager(const AtlasPager&) = delete;
    AtlasPager& operator=(const AtlasPager&) = delete;

    struct Frame {
        std::vector<LoadedBlock> upload; // now resident: upload these
        std::vector<BlockKey> evict;     // no longer resident: delete these
    };
    /// One frame's paging for `requests` (priority order).
    Frame update(const std::vector<BlockRequest>& requests);
    /// Waits until every ideal block of `requests` is resident (stills, tests); returns everything to upload.
    Frame complete(const std::vector<BlockRequest>& requests);

    bool resident(const BlockKey& key) const { return m_resident.count(key) != 0; }
    std::uint64_t capacityBytes() const { return m_settings.capacityBytes; }
    const PagerStats& stats() const { return m_stats; }
    /// GPU bytes of a block once uploaded.
    std::uint64_t blockBytes(const BlockKey& key) const;
    /// How many blocks original texture `texture` is paged as (1 unless it exceeds twice an atlas's bytes), and the
    /// rows [first, end) of its level 0 that part `part` holds.
    int textureParts(std::uint32_t texture) const;
    std::pair<int, int> partRows(std::uint32_t texture, int part) const;
    /// GPU bytes of original texture `texture` as a whole (RGBA8 with mips), however many parts it is paged as.
    std::uint64_t textureBytes(std::uint32_t texture) const;
    /// Whether every part of original texture `texture` is resident.
    bool textureResident(std::uint32_t texture) const;
    /// The first load error (a block that could not be read is not retried); empty when none.
    std::string error() const;

private:
    void worker();
    Result<LoadedBlock> load(const BlockKey& key) const;
    bool split(const BlockKey& key) const { return key.kind == BlockKey::Kind::Texture && textureParts(key.index) > 1; }
    /// Where an ideal block comes in the order blocks are loaded (update()): category, tree level, request rank.
    using LoadOrder = std::tuple<int, int, std::size_t>;
    /// Evicts the least recently requested resident block outside `ideal` (a split texture with all its parts) into
    /// `out`; false when there is none.
    bool evictOne(const std::map<BlockKey, LoadOrder>& ideal, Frame& out);
    /// Whether some part of split texture `texture` is in `blocks` (m_resident or m_reserved).
    template <class Map> static bool anyPart(const Map& blocks, std::uint32_t texture);
    /// GPU bytes held by the resident and by the reserved blocks (a split texture counted whole, once).
    std::pair<std::uint64_t, std::uint64_t> heldBytes() const;

    const AtlasTreeFile& m_file;
    int m_tree;
    std::uint64_t m_atlasRgbBytes = 0; // one atlas as RGB(A)8 with mips (textureParts' yardstick)
    PagerSettings m_settings;
    Loader m_loader;

    std::map<BlockKey, std::uint64_t> m_resident;     // key -> last frame it was requested
    std::map<BlockKey, std::uint64_t> m_reserved;     // queued, loading or waiting for upload -> bytes
    std::vector<BlockKey> m_failed;
    std::deque<LoadedBlock> m_ready;                  // loaded, waiting for upload
    std::uint64_t m_frame = 0;
    PagerStats m_stats;

    // Loader thread.
    mutable std::mutex m_mutex;
    std::condition_variable m_cv;
    std::deque<BlockKey> m_queue;
    std::vector<LoadedBlock> m_done;
    std::vector<std::pair<BlockKey, std::string>> m_errors;
    std::string m_firstError;
    bool m_stop = false;
    // The last original texture decoded for its parts (they are requested one after another).
    mutable std::mutex m_decodedMutex;
    mutable std::uint32_t m_decodedIndex = ~0u;
    mutable std::shared_ptr<const SourceTexture> m_decoded;
    std::thread m_thread;
};

} // namespace seasonview::city
