#pragma once
// JSON files seasonview reads (scene manifests, camera paths, presets, viewer scripts, bookmarks and the caches'
// indexes), parsed within limits: a file over kMaxJsonBytes or nested deeper than kMaxJsonDepth is refused before
// it is held in memory whole or walked, with the limit named.
#include "Result.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <type_traits>

namespace seasonview {

/// Deepest nesting of arrays and objects any seasonview JSON file needs is 4; 64 leaves room for hand edits.
inline constexpr int kMaxJsonDepth = 64;
/// The largest JSON file read (camera paths of 10^5 keyframes are ~20 MB).
inline constexpr std::uintmax_t kMaxJsonBytes = std::uintmax_t(256) << 20;

/// Parses `text` read from `name`. Errors: "NAME: malformed JSON WHAT (line L, column C)", "NAME: JSON nested
/// deeper than 64 levels". `what` names the kind of file ("camera path", "manifest").
Result<nlohmann::json> parseJson(const std::string& text, const std::string& name, const std::string& what);

/// Reads and parses a file. Errors also: "file not found", "is a directory", "cannot read file", over the size
/// limit. No exception escapes.
Result<nlohmann::json> readJsonFile(const std::filesystem::path& file, const std::string& what);

/// A JSON value as T when it is one: integers only from integral numbers within T's range (nlohmann's get<int>() of
/// 1e300 is undefined behaviour), floating point from any number, anything else as nlohmann converts it. Never
/// throws.
template <typename T> std::optional<T> jsonAs(const nlohmann::json& v) {
    if constexpr (std::is_integral_v<T> && !std::is_same_v<T, bool>) {
        if (v.is_number_unsigned()) {
            const std::uint64_t u = v.get<std::uint64_t>();
            if (u > std::uint64_t(std::numeric_limits<T>::max())) return std::nullopt;
            return T(u);
        }
        if (v.is_number_integer()) {
            const std::int64_t i = v.get<std::int64_t>();
            if (std::is_unsigned_v<T> ? i < 0 || std::uint64_t(i) > std::uint64_t(std::numeric_limits<T>::max())
                                      : i < std::int64_t(std::numeric_limits<T>::min()) ||
                                            i > std::int64_t(std::numeric_limits<T>::max()))
                return std::nullopt;
            return T(i);
        }
        if (v.is_number_float()) {
            const double d = v.get<double>();
            // The range test in double: 2^63 and 2^64 are exact there, so no value that overflows T passes.
            if (!(d == std::floor(d)) || !(d >= double(std::numeric_limits<T>::min())) ||
                !(d < 2.0 * (double(std::numeric_limits<T>::max() / 2 + 1))))
                return std::nullopt;
            return T(d);
        }
        return std::nullopt;
    } else if constexpr (std::is_floating_point_v<T>) {
        if (!v.is_number()) return std::nullopt;
        return T(v.get<double>());
    } else {
        try {
            return v.template get<T>();
        } catch (const nlohmann::json::exception&) {
            return std::nullopt;
        }
    }
}

/// A JSON object's member `key` as T (jsonAs), or nothing when it is missing or of another type.
template <typename T> std::optional<T> jsonMember(const nlohmann::json& j, const char* key) {
    if (!j.is_object()) return std::nullopt;
    const auto it = j.find(key);
    if (it == j.end()) return std::nullopt;
    return jsonAs<T>(*it);
}

/// The same with a fallback for a missing member or one of another type (unlike nlohmann's value(), which throws
/// on another type).
template <typename T> T jsonValue(const nlohmann::json& j, const char* key, T fallback) {
    return jsonMember<T>(j, key).value_or(std::move(fallback));
}

} // namespace seasonview
