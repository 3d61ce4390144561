#pragma once
// Original textures for the atlas build, read on demand through a byte-capped LRU cache (the build never holds all
// textures, thesis §4.7.1's 7.3 GB of facades), each with a box-filtered mip chain, sampled trilinearly so a
// texture shrunk into an atlas does not alias.
#include "CityModel.h"
#include "Result.h"

#include <glm/vec2.hpp>
#include <glm/vec4.hpp>

#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <unordered_map>
#include <vector>

namespace seasonview::city {

/// One decoded texture: RGBA8 mips, rows bottom-up (texture coordinate v = 0 is the image's bottom row).
struct SourceTexture {
    std::vector<std::vector<std::uint8_t>> mips;
    std::vector<glm::ivec2> sizes;
    int channels = 3; // of the file
    bool repeat = true;
    int firstLevel = 0; // mips finer than this were dropped (empty): sample() never reads them
    std::uint64_t bytes() const;
    /// Colour at texture coordinates `uv` (texture units; repeated or clamped) with `texelsPerSample` source texels
    /// of level 0 per output sample (chooses and blends two mip levels). RGBA, 0..255.
    glm::vec4 sample(glm::dvec2 uv, double texelsPerSample) const;
};

/// The next mip level of an RGBA8 image of `size` texels: 2×2 box averages from the origin, odd sizes' last
/// row/column folded into its neighbour (the atlases' mips average the same blocks: their areas start on
/// multiples of the border). The result is max(size / 2, 1).
std::vector<std::uint8_t> halveRgbaBox(const std::vector<std::uint8_t>& src, glm::ivec2 size);
/// Appends to a texture holding its level 0 its box-filtered mips (halveRgbaBox) down to 1×1.
void addBoxMips(SourceTexture& t);

/// Reads a texture file (any format OpenImageIO reads; 8/16-bit, grey, RGB or RGBA) into a SourceTexture.
Result<SourceTexture> readSourceTexture(const CityTexture& texture);

class TextureCache {
public:
    explicit TextureCache(const std::vector<CityTexture>& textures, std::uint64_t capacityBytes);
    /// The same over textures `read` makes (numbered as it knows them; called on prefetch's threads too).
    TextureCache(std::function<Result<SourceTexture>(int)> read, std::uint64_t capacityBytes);
    /// The texture (read on first use, kept until the cache's bytes exceed the capacity, least recently used
    /// first). A failed read is an error naming the file.
    Result<std::shared_ptr<const SourceTexture>> get(int texture);
    /// Reads the missing ones of `textures` on up to `threads` threads and keeps them (the first error is returned,
    /// naming its file). Then get() finds them, as long as the capacity holds them all.
    Status prefetch(const std::vector<int>& textures, int threads);
    /// Per texture the finest mip level any sample will read (a BlockMap build reads facades at metres per
    /// texel): finer levels are dropped as a texture is read, so the cache holds many more. Empty: keep every level.
    void setFinestLevels(std::vector<int> levels) { m_finest = std::move(levels); }
    std::uint64_t bytes() const { return m_bytes; }
    std::uint64_t peakBytes() const { return m_peak; }
    std::uint64_t reads() const { return m_reads; }

private:
    void insert(int texture, std::shared_ptr<const SourceTexture> tex);
    void dropFinerMips(int texture, SourceTexture& t) const;
    std::function<Result<SourceTexture>(int)> m_read;
    std::uint64_t m_capacity, m_bytes = 0, m_peak = 0, m_reads = 0;
    std::list<int> m_lru; // front = most recent
    struct Entry {
        std::shared_ptr<const SourceTexture> tex;
        std::list<int>::iterator pos;
    };
    std::unordered_map<int, Entry> m_entries;
    std::vector<int> m_finest;
};

} // namespace seasonview::city
