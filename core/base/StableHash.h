#pragma once
// A hash that names cache files: 64-bit FNV-1a, stable across compilers, runs and machines (std::hash is not).
#include <cstdint>
#include <string_view>

namespace seasonview {

inline std::uint64_t stableHash64(std::string_view s) {
    std::uint64_t h = 0xcbf29ce484222325ull;
    for (unsigned char c : s) h = (h ^ c) * 0x100000001b3ull;
    return h;
}

} // namespace seasonview
