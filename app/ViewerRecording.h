#pragma once
// The viewer's camera bookmarks (K adds, J jumps; kept in a JSON array of camera strings) and the flight recorder
// (R: the flown camera as bench keyframes, a `bench --path` file).
#include "Camera.h"
#include "Result.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace seasonview::app {

struct Bookmarks {
    std::filesystem::path file; // empty: kept in memory only
    std::vector<Camera> cameras;
    size_t next = 0;
};

/// The bookmarks in `file` (none when it is empty or does not exist yet); errors name the file and the bookmark.
Result<Bookmarks> loadBookmarks(const std::string& file);
/// Writes the bookmarks to their file atomically (nothing without a file).
Status saveBookmarks(const Bookmarks& b);

/// The flown camera as bench keyframes, one every `step` seconds of the viewer's clock.
struct Recorder {
    std::filesystem::path file;
    bool on = false;
    double step = 0.25, start = 0.0, lastT = -1e9;
    nlohmann::json keys = nlohmann::json::array();
    int frameStep = 0; // fixed clock: a keyframe every this many frames (uniform keyframe times)
    int frames = 0;
    /// Adds a keyframe at the viewer's time `t` when recording and one is due.
    void add(double t, const Camera& c);
    /// Writes the keyframes to `file` (atomically) when there are at least two.
    Status save() const;
};

} // namespace seasonview::app
