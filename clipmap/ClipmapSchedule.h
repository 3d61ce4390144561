#pragma once
// What each clip level must hold and what it holds (plain C++, no GL). Levels are toroidal N×N windows on the
// pyramid levels that are larger than N; smaller pyramid levels are resident whole (the "coarse pyramid").
// Content is tracked per B×B block: each texture slot carries the tag of the block it holds, so a slot with stale
// data after the window moved is simply a tag mismatch (the shader then falls back to a coarser level).
#include "ToroidalWindow.h"

#include <glm/vec2.hpp>

#include <cstdint>
#include <vector>

namespace seasonview {

struct ClipmapLayout {
    int size = 1024;                    // texels per side of every toroidal level
    int block = 64;                     // upload and validity granularity, texels (divides size)
    std::vector<glm::ivec2> levelSizes; // pyramid level sizes, level 0 = the full image
    /// Toroidal levels: the pyramid levels that do not fit in size×size. The rest are resident whole.
    int clipLevels() const;
};

/// The layout of an image of w×h pixels: its pyramid halves (ceil) down to 1×1.
ClipmapLayout makeClipmapLayout(int width, int height, int size, int block);

struct BlockKey {
    int level = 0, bx = 0, by = 0; // block coordinates in level texels / block
    bool operator==(const BlockKey&) const = default;
};

class ClipmapSchedule {
public:
    explicit ClipmapSchedule(ClipmapLayout layout);

    const ClipmapLayout& layout() const { return m_layout; }
    int slotsPerSide() const { return m_layout.size / m_layout.block; }

    /// Moves the windows. `centres` has one centre per clip level, in level-0 texels (image pixels, x east, y
    /// south); level l's window is centred on centre / 2^l, snapped to whole blocks. Returns the number of texels
    /// newly exposed inside the images (the geometric minimum any toroidal update must upload).
    long long setCenters(const std::vector<glm::dvec2>& centres);

    const TexelRect& window(int level) const { return m_windows[size_t(level)]; }

    /// Blocks inside the windows (and inside the level's image) whose slot does not hold them yet: finest level
    /// first, within a level nearest to the window centre first; at most `limit`.
    std::vector<BlockKey> missingBlocks(size_t limit) const;

    /// The block's texels are now in its slot (call after uploading them).
    void markStored(const BlockKey& key);
    bool holds(const BlockKey& key) const;

    /// The level texels of a block, clipped to the level's image.
    TexelRect blockTexels(const BlockKey& key) const;

    /// Slot tags of a level, row-major, slotsPerSide² entries (for the validity texture); kEmptyTag where empty.
    const std::vector<std::int32_t>& slotTags(int level) const { return m_tags[size_t(level)]; }
    static constexpr std::int32_t kEmptyTag = -1;
    /// The tag of a block: bx | by << 16 (bx, by < 32768, so never kEmptyTag). The shader computes the same.
    static std::int32_t tagOf(int bx, int by);

private:
    ClipmapLayout m_layout;
    std::vector<TexelRect> m_windows;
    std::vector<std::vector<std::int32_t>> m_tags;
};

} // namespace seasonview
