#include "PairStats.h"
#include "JsonFile.h"

#include "AtomicFile.h"
#include "StableHash.h"
#include "BandReader.h"
#include "Segmentation.h"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <numeric>
#include <thread>
#include <vector>

namespace seasonview {

namespace {

namespace fs = std::filesystem;

/// Bumped whenever what the file holds or how the histograms are sampled changes: old files then no longer match.
constexpr int kPairStatsVersion = 2; // 2: pixels where a season has no data left out, their count stored
constexpr const char* kFormatName = "seasonview pair histograms";

std::string pairKey(const ImagePyramid& on, const ImagePyramid& off) {
    return on.sourceKey + "\n" + off.sourceKey + "\nstep " + std::to_string(kSegHistogramStep) + "\nv" +
           std::to_string(kPairStatsVersion);
}

/// The source path at the front of a pyramid's sourceKey ("path|size|mtime|...").
std::string sourcePathOf(const std::string& sourceKey) { return sourceKey.substr(0, sourceKey.find('|')); }

/// Samples per histogram of a w×h pair: every kSegHistogramStep-th pixel of every kSegHistogramStep-th row.
std::uint64_t sampleCount(int w, int h) {
    const auto n = [](int v) { return std::uint64_t((v + kSegHistogramStep - 1) / kSegHistogramStep); };
    return n(w) * n(h);
}

/// The histograms in a cache file, or why there are none usable ("not prepared yet", "cache corrupt: ...").
struct CacheRead {
    std::optional<SegmentationHistograms> histograms;
    std::string reason;
};

CacheRead readCache(const fs::path& file, const std::string& key, int width, int height) {
    CacheRead r;
    const std::string name = file.filename().string();
    std::error_code ec;
    if (!fs::exists(file, ec)) {
        r.reason = "not prepared yet";
        return r;
    }
    const nlohmann::json j = readJsonFile(file, "pair statistics").ok() ? *readJsonFile(file, "pair statistics")
                                                                       : nlohmann::json(nullptr);
    // The sampled pixels where both seasons have data: all of them, or fewer (stored) where a season has none.
    const std::uint64_t all = sampleCount(width, height);
    std::uint64_t samples = all;
    if (j.is_object() && j.contains("samples") && j["samples"].is_number_unsigned())
        samples = std::min(all, j["samples"].get<std::uint64_t>());
    SegmentationHistograms h;
    // Each histogram must be complete: its bins add up to the number of samples (a cut or edited file does not).
    auto take = [&](const nlohmann::json& bins, std::uint64_t* out, size_t count) {
        if (!bins.is_array() || bins.size() != count) return false;
        std::uint64_t sum = 0;
        for (size_t i = 0; i < count; ++i) {
            if (!bins[i].is_number_unsigned()) return false;
            out[i] = bins[i].get<std::uint64_t>();
            sum += out[i];
        }
        return sum == samples;
    };
    try {
        if (j.is_discarded() || !j.is_object()) throw std::runtime_error("not an object");
        if (j.at("key").get<std::string>() != key) {
            r.reason = "sources changed";
            return r;
        }
        bool ok = jsonMember<int>(j, "width") == width && jsonMember<int>(j, "height") == height;
        for (size_t c = 0; c < 3 && ok; ++c)
            ok = take(j.at("leafon").at(c), h.on[c].data(), 256) && take(j.at("leafoff").at(c), h.off[c].data(), 256);
        if (ok) ok = take(j.at("drop"), h.drop.data(), h.drop.size());
        if (!ok) {
            r.reason = "cache corrupt: " + name + " does not hold its " + std::to_string(samples) + " samples of a " +
                       std::to_string(width) + "x" + std::to_string(height) + " pair";
            return r;
        }
    } catch (const std::exception&) {
        r.reason = "cache corrupt: " + name + " unreadable";
        return r;
    }
    r.histograms = h;
    return r;
}

std::string cacheText(const SegmentationHistograms& h, const ImagePyramid& on, const ImagePyramid& off) {
    nlohmann::json j = {{"format", kFormatName},
                        {"version", kPairStatsVersion},
                        {"key", pairKey(on, off)},
                        {"leafon_key", on.sourceKey},
                        {"leafoff_key", off.sourceKey},
                        {"step", kSegHistogramStep},
                        {"width", on.width()},
                        {"height", on.height()},
                        {"samples", std::accumulate(h.drop.begin(), h.drop.end(), std::uint64_t(0))},
                        {"leafon", h.on},
                        {"leafoff", h.off},
                        {"drop", h.drop}};
    return j.dump() + "\n";
}

/// Removes the files of older versions of the same two sources (the pyramids of a changed source are replaced, so
/// their statistics are of no use any more).
void removeStale(const fs::path& dir, const fs::path& keep, const ImagePyramid& on, const ImagePyramid& off) {
    const std::string onPath = sourcePathOf(on.sourceKey), offPath = sourcePathOf(off.sourceKey);
    std::error_code ec;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        const fs::path& p = it->path();
        if (p == keep || p.extension() != ".json" || p.filename().string().find(".partial-") != std::string::npos)
            continue;
        auto parsed = readJsonFile(p, "pair statistics");
        if (!parsed) continue;
        const nlohmann::json& j = *parsed;
        if (!j.is_object() || !j.contains("leafon_key") || !j.contains("leafoff_key") ||
            !j["leafon_key"].is_string() || !j["leafoff_key"].is_string())
            continue;
        if (sourcePathOf(j["leafon_key"].get<std::string>()) == onPath &&
            sourcePathOf(j["leafoff_key"].get<std::string>()) == offPath) {
            std::error_code ignored;
            fs::remove(p, ignored);
        }
    }
}

/// Level 0 of a pyramid opened for banded reading, checked against what the pyramid says it is.
Result<BandReader> openLevel0(const ImagePyramid& p, int preferredRows) {
    assert(!p.levels.empty() && p.format == TexelFormat::Rgba8 &&
           "preparePairHistograms(): two prepared imagery (RGBA8) pyramids");
    const PyramidLevel& level = p.levels[0];
    auto reader = BandReader::open(level.file, preferredRows);
    if (!reader) return reader.error();
    if (reader->width() != level.width || reader->height() != level.height || reader->channels() != 4 ||
        reader->type() != SampleType::U8)
        return fileError(level.file.string(),
                         "is " + std::to_string(reader->width()) + "x" + std::to_string(reader->height()) + "x" +
                             std::to_string(reader->channels()) + " " + sampleTypeName(reader->type()) +
                             ", the pyramid says " + std::to_string(level.width) + "x" +
                             std::to_string(level.height) + "x4 u8");
    return reader;
}

Result<SegmentationHistograms> computeHistograms(const ImagePyramid& on, const ImagePyramid& off,
                                                 const ProgressFn& progress) {
    if (on.width() != off.width() || on.height() != off.height())
        return fileError(off.levels[0].file.string(),
                         "is " + std::to_string(off.width()) + "x" + std::to_string(off.height()) +
                             " pixels but the leaf-on level 0 is " + std::to_string(on.width()) + "x" +
                             std::to_string(on.height()));
    // Bands of whole tile rows of both files (equal when both pyramids have the same tile size).
    const int rows = std::max(256, std::lcm(std::max(on.tileSize, 1), std::max(off.tileSize, 1)));
    auto a = openLevel0(on, rows);
    if (!a) return a.error();
    auto b = openLevel0(off, rows);
    if (!b) return b.error();
    if (a->bandRows() != b->bandRows())
        return fileError(off.levels[0].file.string(), "tiles of another height than those of " +
                                                          on.levels[0].file.string() + " (pyramids of another tile size)");
    const int w = on.width(), h = on.height(), band = a->bandRows();
    std::vector<std::uint8_t> rgbaOn(size_t(band) * size_t(w) * 4), rgbaOff(rgbaOn.size());
    std::vector<std::uint8_t> bufOn(size_t(band) * size_t(w) * 3), bufOff(bufOn.size()), valid(size_t(band) * size_t(w));
    SegmentationHistograms total;
    for (int y0 = 0; y0 < h; y0 += band) {
        const int y1 = std::min(h, y0 + band);
        Status offStatus = Ok{};
        std::thread t([&] { offStatus = b->read(y0, y1, 4, SampleType::U8, rgbaOff.data()); });
        const Status onStatus = a->read(y0, y1, 4, SampleType::U8, rgbaOn.data());
        t.join();
        if (!onStatus) return onStatus.error();
        if (!offStatus) return offStatus.error();
        const bool complete = splitPairRgba(rgbaOn.data(), rgbaOff.data(), size_t(y1 - y0) * size_t(w), bufOn.data(),
                                            bufOff.data(), valid.data());
        RgbRows pairRows{bufOn.data(), bufOff.data(), w, h, y0, y1 - y0};
        if (!complete) pairRows.valid = valid.data(); // pixels where a season has no data are left out
        total.merge(rowHistograms(pairRows, true, true));
        if (progress) progress(double(y1) / double(h), "pair statistics");
    }
    return total;
}

} // namespace

fs::path pairHistogramsFile(const ImagePyramid& leafon, const ImagePyramid& leafoff, const fs::path& cacheDir) {
    char name[40];
    std::snprintf(name, sizeof name, "%016llx.json",
                  static_cast<unsigned long long>(stableHash64(pairKey(leafon, leafoff))));
    return cacheDir / "pairstats" / name;
}

std::optional<SegmentationHistograms> cachedPairHistograms(const ImagePyramid& leafon, const ImagePyramid& leafoff,
                                                           const fs::path& cacheDir) {
    if (leafon.levels.empty() || leafoff.levels.empty()) return std::nullopt;
    return readCache(pairHistogramsFile(leafon, leafoff, cacheDir), pairKey(leafon, leafoff), leafon.width(),
                     leafon.height())
        .histograms;
}

Result<SegmentationHistograms> preparePairHistograms(const ImagePyramid& leafon, const ImagePyramid& leafoff,
                                                     const fs::path& cacheDir, const ProgressFn& progress,
                                                     PairHistogramsReport* report) {
    const auto t0 = std::chrono::steady_clock::now();
    PairHistogramsReport local;
    PairHistogramsReport& r = report ? *report : local;
    r = PairHistogramsReport{};
    r.file = pairHistogramsFile(leafon, leafoff, cacheDir);
    auto seconds = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };

    CacheRead cached = readCache(r.file, pairKey(leafon, leafoff), leafon.width(), leafon.height());
    if (cached.histograms) {
        r.seconds = seconds();
        return std::move(*cached.histograms);
    }
    r.reason = cached.reason;
    auto histograms = computeHistograms(leafon, leafoff, progress);
    if (!histograms) return histograms.error();

    const fs::path dir = r.file.parent_path();
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) return fileError(dir.string(), "cannot create the cache folder (" + ec.message() + ")");
    std::string err;
    if (!writeTextAtomic(r.file, cacheText(*histograms, leafon, leafoff), err)) return fileError(r.file.string(), err);
    removeStale(dir, r.file, leafon, leafoff);
    r.built = true;
    r.seconds = seconds();
    return histograms;
}

} // namespace seasonview
