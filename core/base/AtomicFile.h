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

/// Removes what writers killed before they could commit or discard left in `dir`: files and folders named
/// "*.partial-PID*" whose process no longer runs (a live PID, this process's own, or a name without a PID is kept).
/// Called by commitTemporary for the target's folder, so leftovers go with the next successful write there.
void removeStaleTemporaries(const std::filesystem::path& dir);

/// Removes `tmp` if it exists, ignoring errors.
void discardTemporary(const std::filesystem::path& tmp);

/// Writes `text` to `target` atomically. Returns false and sets `error` on failure.
bool writeTextAtomic(const std::filesystem::path& target, const std::string& text, std::string& error);

} // namespace seasonview
