#include "Stretch.h"

#include "AtomicFile.h"

#include <nlohmann/json.hpp>

#include <cstdlib>
#include <fstream>
#include <functional>
#include <vector>

namespace seasonview {

Stretch computeStretch(const Image<std::uint16_t>& image, double lowPercent, double highPercent) {
    Stretch s;
    s.identity = false;
    s.channels = std::min(image.channels, 4);
    for (int c = 0; c < s.channels; ++c) {
        std::vector<std::uint64_t> hist(65536, 0);
        std::uint64_t n = 0;
        const size_t count = size_t(image.width) * size_t(image.height);
        for (size_t i = 0; i < count; ++i) {
            std::uint16_t v = image.pixels[i * size_t(image.channels) + size_t(c)];
            if (v == 0) continue;
            ++hist[v];
            ++n;
        }
        if (n == 0) {
            s.low[size_t(c)] = 0;
            s.high[size_t(c)] = 65535;
            continue;
        }
        auto percentile = [&](double p) {
            const std::uint64_t target = std::uint64_t(p / 100.0 * double(n - 1));
            std::uint64_t acc = 0;
            for (int v = 0; v < 65536; ++v) {
                acc += hist[size_t(v)];
                if (acc > target) return float(v);
            }
            return 65535.0f;
        };
        s.low[size_t(c)] = percentile(lowPercent);
        s.high[size_t(c)] = std::max(percentile(highPercent), s.low[size_t(c)] + 1.0f);
    }
    return s;
}

std::filesystem::path defaultCacheDir() {
    if (const char* c = std::getenv("SEASONVIEW_CACHE"); c && *c) return c;
    if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) return std::filesystem::path(x) / "seasonview";
    if (const char* h = std::getenv("HOME"); h && *h) return std::filesystem::path(h) / ".cache" / "seasonview";
    return std::filesystem::temp_directory_path() / "seasonview-cache";
}

Result<Stretch> stretchFor(const RasterInfo& info, const std::filesystem::path& cacheDir) {
    if (info.type == SampleType::U8) {
        Stretch s;
        s.channels = info.channels;
        return s;
    }
    std::error_code ec;
    const std::filesystem::path abs = std::filesystem::weakly_canonical(std::filesystem::absolute(info.path, ec), ec);
    const auto size = std::filesystem::file_size(info.path, ec);
    const auto mtime = std::filesystem::last_write_time(info.path, ec).time_since_epoch().count();
    const std::string key = abs.string() + "|" + std::to_string(size) + "|" + std::to_string(mtime) + "|" +
                            std::to_string(kStretchLowPercent) + "-" + std::to_string(kStretchHighPercent);
    char name[64];
    std::snprintf(name, sizeof name, "stretch-%016zx.json", std::hash<std::string>{}(key));
    const std::filesystem::path cached = cacheDir / name;
    if (std::ifstream f(cached); f) {
        auto j = nlohmann::json::parse(f, nullptr, false);
        if (!j.is_discarded() && j.value("key", "") == key) {
            Stretch s;
            s.identity = false;
            s.channels = j.at("channels").get<int>();
            for (int c = 0; c < s.channels && c < 4; ++c) {
                s.low[size_t(c)] = j.at("low").at(size_t(c)).get<float>();
                s.high[size_t(c)] = j.at("high").at(size_t(c)).get<float>();
            }
            return s;
        }
    }
    auto img = readImageU16(info.path, 4);
    if (!img) return img.error();
    Stretch s = computeStretch(*img);
    nlohmann::json j = {{"key", key},
                        {"file", abs.string()},
                        {"percentiles", {kStretchLowPercent, kStretchHighPercent}},
                        {"channels", s.channels},
                        {"low", std::vector<float>(s.low.begin(), s.low.begin() + s.channels)},
                        {"high", std::vector<float>(s.high.begin(), s.high.begin() + s.channels)}};
    std::filesystem::create_directories(cacheDir, ec);
    std::string err;
    (void)writeTextAtomic(cached, j.dump(2) + "\n", err); // best effort
    return s;
}

Result<Image<std::uint8_t>> readDisplayRgba(const RasterInfo& info, const Stretch& stretch) {
    Image<std::uint8_t> out;
    out.width = info.width;
    out.height = info.height;
    out.channels = 4;
    out.pixels.assign(size_t(info.width) * size_t(info.height) * 4, 255);
    auto fill = [&](const auto& img) {
        const size_t n = size_t(img.width) * size_t(img.height);
        for (size_t i = 0; i < n; ++i) {
            for (int c = 0; c < 4; ++c) {
                int src = img.channels >= 3 ? c : 0; // grey -> RGB
                if (c == 3) {
                    if (img.channels != 4 && img.channels != 2) break;
                    src = img.channels - 1;
                }
                out.pixels[i * 4 + size_t(c)] =
                    stretch.apply(src, float(img.pixels[i * size_t(img.channels) + size_t(src)]));
            }
        }
    };
    if (info.type == SampleType::U8) {
        auto img = readImageU8(info.path, 4);
        if (!img) return img.error();
        fill(*img);
    } else {
        auto img = readImageU16(info.path, 4);
        if (!img) return img.error();
        fill(*img);
    }
    return out;
}

} // namespace seasonview
