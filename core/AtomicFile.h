#pragma once
// Write-then-rename helpers: no half-written output file is ever left under the final name.
#include <filesystem>
#include <string>

namespace seasonview {

/// A temporary path next to `target` that keeps its extension (so format-by-extension writers still work):
/// "dir/.name.partial-PID.ext". Distinct per process.
std::filesystem::path temporaryPathFor(const std::filesystem::path& target);

/// Renames `tmp` to `target` (replacing it). On failure removes `tmp` and returns false with `error` set.
bool commitTemporary(const std::filesystem::path& tmp, const std::filesystem::path& target, std::string& error);

/// Removes `tmp` if it exists, ignoring errors.
void discardTemporary(const std::filesystem::path& tmp);

/// Writes `text` to `target` atomically. Returns false and sets `error` on failure.
bool writeTextAtomic(const std::filesystem::path& target, const std::string& text, std::string& error);

} // namespace seasonview
