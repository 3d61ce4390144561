#pragma once
// Internal to city/: the tree file's byte layout. A 32-byte header ("SVATLAS\0", version, reserved, index offset,
// index bytes), the atlas blobs, then the index (AtlasTreeFile without the pixels) at the end, so the build can
// stream atlases out as it makes them and write the index last.
#include "AtlasTree.h"

#include <cstdint>
#include <vector>

namespace seasonview::city::detail {

constexpr std::size_t kHeaderBytes = 32;
std::vector<std::uint8_t> serializeIndex(const AtlasTreeFile& f);
std::vector<std::uint8_t> fileHeader(std::uint64_t indexOffset, std::uint64_t indexBytes, std::uint32_t indexCrc);

} // namespace seasonview::city::detail
