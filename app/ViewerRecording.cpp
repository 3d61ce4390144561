#include "ViewerRecording.h"

#include "AtomicFile.h"
#include "JsonFile.h"

namespace seasonview::app {

Result<Bookmarks> loadBookmarks(const std::string& file) {
    Bookmarks b;
    b.file = file;
    std::error_code ec;
    if (file.empty() || !std::filesystem::exists(file, ec)) return b;
    auto parsed = readJsonFile(file, "bookmarks");
    if (!parsed) return parsed.error();
    const nlohmann::json& j = *parsed;
    if (!j.is_array()) return fileError(file, "bookmarks must be a JSON array of camera strings");
    for (size_t i = 0; i < j.size(); ++i) {
        if (!j[i].is_string()) return fileError(file, "bookmark " + std::to_string(i) + " is not a camera string");
        auto c = parseCamera(j[i].get<std::string>());
        if (!c) return fileError(file, "bookmark " + std::to_string(i) + ": " + c.message());
        b.cameras.push_back(c->camera);
    }
    return b;
}

Status saveBookmarks(const Bookmarks& b) {
    if (b.file.empty()) return Ok{};
    nlohmann::json j = nlohmann::json::array();
    for (const Camera& c : b.cameras) j.push_back(c.toString());
    std::string err;
    if (!writeTextAtomic(b.file, j.dump(2) + "\n", err)) return fileError(b.file.string(), err);
    return Ok{};
}

void Recorder::add(double t, const Camera& c) {
    if (!on) return;
    const bool due = frameStep > 0 ? frames++ % frameStep == 0 : t - lastT >= step - 1e-9;
    if (!due) return;
    lastT = t;
    keys.push_back({{"time", t - start},
                    {"x", c.position.x},
                    {"y", c.position.y},
                    {"z", c.position.z},
                    {"yaw", c.yawDeg},
                    {"pitch", c.pitchDeg},
                    {"fov", c.fovYDeg}});
}

Status Recorder::save() const {
    if (file.empty() || keys.size() < 2) return Ok{};
    std::string err;
    if (!writeTextAtomic(file, keys.dump(1) + "\n", err)) return fileError(file.string(), err);
    return Ok{};
}

} // namespace seasonview::app
