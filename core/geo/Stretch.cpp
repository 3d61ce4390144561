#include "Stretch.h"
#include "JsonFile.h"

#include "AtomicFile.h"
#include "StableHash.h"

#include "BandReader.h"
#include "GdalSupport.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <optional>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <vector>

namespace seasonview {

namespace {

using Histograms = std::vector<std::vector<std::uint64_t>>; // per band, 65536 bins

Stretch stretchFromHistograms(const Histograms& hist, double lowPercent, double highPercent) {
    Stretch s;
    s.identity = false;
    s.channels = int(hist.size());
    for (size_t c = 0; c < hist.size(); ++c) {
        std::uint64_t n = 0;
        for (int v = 1; v < 65536; ++v) n += hist[c][size_t(v)]; // zero: the usual nodata fill, ignored
        if (n == 0) {
            s.low[c] = 0;
            s.high[c] = 65535;
            continue;
        }
        auto percentile = [&](double p) {
            const std::uint64_t target = std::uint64_t(p / 100.0 * double(n - 1));
            std::uint64_t acc = 0;
            for (int v = 1; v < 65536; ++v) {
                acc += hist[c][size_t(v)];
                if (acc > target) return float(v);
            }
            return 65535.0f;
        };
        s.low[c] = percentile(lowPercent);
        s.high[c] = std::max(percentile(highPercent), s.low[c] + 1.0f);
    }
    return s;
}

void accumulate(Histograms& hist, const std::uint16_t* px, size_t pixels, int stride) {
    for (size_t c = 0; c < hist.size(); ++c)
        for (size_t i = 0; i < pixels; ++i) ++hist[c][px[i * size_t(stride) + c]];
}

// Streams the file in bands of rows: memory stays a few MB whatever the image size.
Result<Stretch> streamedStretch(const std::filesystem::path& path, double lowPercent, double highPercent) {
    auto reader = BandReader::open(path, 64);
    if (!reader) return reader.error();
    const int channels = std::min(reader->channels(), 4);
    Histograms hist(size_t(channels), std::vector<std::uint64_t>(65536, 0));
    std::vector<std::uint16_t> rows(size_t(reader->width()) * size_t(reader->bandRows()) * size_t(channels));
    for (int y = 0; y < reader->height(); y += reader->bandRows()) {
        const int y1 = std::min(reader->height(), y + reader->bandRows());
        if (auto st = reader->read(y, y1, channels, SampleType::U16, rows.data()); !st) return st.error();
        accumulate(hist, rows.data(), size_t(reader->width()) * size_t(y1 - y), channels);
    }
    return stretchFromHistograms(hist, lowPercent, highPercent);
}

} // namespace

Stretch computeStretch(const Image<std::uint16_t>& image, double lowPercent, double highPercent) {
    Histograms hist(size_t(std::min(image.channels, 4)), std::vector<std::uint64_t>(65536, 0));
    accumulate(hist, image.pixels.data(), size_t(image.width) * size_t(image.height), image.channels);
    return stretchFromHistograms(hist, lowPercent, highPercent);
}

std::filesystem::path defaultCacheDir() {
    if (const char* c = std::getenv("SEASONVIEW_CACHE"); c && *c) return c;
    if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) return std::filesystem::path(x) / "seasonview";
    if (const char* h = std::getenv("HOME"); h && *h) return std::filesystem::path(h) / ".cache" / "seasonview";
    return std::filesystem::temp_directory_path() / "seasonview-cache";
}

namespace {

/// What a stretch file holds, digested: a flipped digit in `low` or `high` that still reads as a number in range
/// is caught by it.
std::string stretchDigest(const std::string& key, int channels, const std::vector<float>& low,
                          const std::vector<float>& high) {
    std::string text = key + "|" + std::to_string(channels);
    char buf[64];
    for (size_t c = 0; c < low.size() && c < high.size(); ++c) {
        std::snprintf(buf, sizeof buf, "|%.9g|%.9g", double(low[c]), double(high[c]));
        text += buf;
    }
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(stableHash64(text)));
    return buf;
}

/// The stretch stored in the cache under `key`, or computed by `compute` and stored (best effort).
Result<Stretch> cachedStretch(const std::string& key, const std::string& what, const std::filesystem::path& cacheDir,
                              const std::function<Result<Stretch>()>& compute) {
    char name[64];
    std::snprintf(name, sizeof name, "stretch-%016zx.json", std::hash<std::string>{}(key));
    const std::filesystem::path cached = cacheDir / name;
    // A stretch file that does not read back whole (cut, edited, flipped, another key) is computed again.
    if (auto j = readJsonFile(cached, "stretch"); j && jsonValue<std::string>(*j, "key", "") == key) {
        Stretch s;
        s.identity = false;
        s.channels = jsonValue<int>(*j, "channels", 0);
        const auto low = jsonValue<std::vector<float>>(*j, "low", {});
        const auto high = jsonValue<std::vector<float>>(*j, "high", {});
        bool whole = s.channels >= 1 && s.channels <= 4 && low.size() == size_t(s.channels) && high.size() == low.size() &&
                     jsonValue<std::string>(*j, "digest", "") == stretchDigest(key, s.channels, low, high);
        for (size_t c = 0; whole && c < low.size(); ++c) {
            whole = std::isfinite(low[c]) && std::isfinite(high[c]) && low[c] < high[c];
            s.low[c] = low[c];
            s.high[c] = high[c];
        }
        if (whole) return s;
    }
    auto computed = compute();
    if (!computed) return computed.error();
    const Stretch s = *computed;
    const std::vector<float> low(s.low.begin(), s.low.begin() + s.channels), high(s.high.begin(), s.high.begin() + s.channels);
    nlohmann::json j = {{"key", key},
                        {"file", what},
                        {"percentiles", {kStretchLowPercent, kStretchHighPercent}},
                        {"channels", s.channels},
                        {"low", low},
                        {"high", high},
                        {"digest", stretchDigest(key, s.channels, low, high)}};
    std::error_code ec;
    std::filesystem::create_directories(cacheDir, ec);
    std::string err;
    (void)writeTextAtomic(cached, j.dump(2) + "\n", err); // best effort
    return s;
}

std::string percentilesKey() {
    return std::to_string(kStretchLowPercent) + "-" + std::to_string(kStretchHighPercent);
}

/// Histograms of every tile's valid pixels (their mask band: nodata, alpha or mask), tile by tile, bands of rows.
Result<Stretch> mosaicStretch(const RasterMosaic& m) {
    const int channels = std::min(m.bands, 4);
    Histograms hist(size_t(channels), std::vector<std::uint64_t>(65536, 0));
    for (const RasterInfo& t : m.tiles) {
        auto ds = gdal::openRaster(t.path);
        if (!ds) return ds.error();
        std::vector<int> bands;
        for (int b = 1; b <= t.channels && int(bands.size()) < channels; ++b)
            if (b != t.alphaBand) bands.push_back(b);
        GDALRasterBand* mask = (*ds)->GetRasterBand(bands.front())->GetMaskBand();
        constexpr int kRows = 256;
        std::vector<std::uint16_t> px(size_t(t.width) * kRows * size_t(channels));
        std::vector<std::uint8_t> valid(size_t(t.width) * kRows);
        for (int y = 0; y < t.height; y += kRows) {
            const int rows = std::min(kRows, t.height - y);
            gdal::ErrorCapture errors;
            CPLErr err = (*ds)->RasterIO(GF_Read, 0, y, t.width, rows, px.data(), t.width, rows, GDT_UInt16, channels,
                                         bands.data(), 2 * channels, 2 * channels * GSpacing(t.width), 2, nullptr);
            if (err == CE_None)
                err = mask->RasterIO(GF_Read, 0, y, t.width, rows, valid.data(), t.width, rows, GDT_Byte, 0, 0, nullptr);
            if (err != CE_None || errors.lostData())
                return gdal::readFailure(t.path.string(), errors, y, y + rows);
            const size_t n = size_t(rows) * size_t(t.width);
            for (size_t c = 0; c < size_t(channels); ++c)
                for (size_t i = 0; i < n; ++i)
                    if (valid[i]) ++hist[c][px[i * size_t(channels) + c]];
        }
    }
    return stretchFromHistograms(hist, kStretchLowPercent, kStretchHighPercent);
}

} // namespace

const char* stretchModeName(StretchMode m) {
    switch (m) {
    case StretchMode::Auto: return "auto";
    case StretchMode::None: return "none";
    case StretchMode::Percentile: return "percentile";
    }
    return "?";
}

Result<StretchMode> parseStretchMode(const std::string& name) {
    for (StretchMode m : {StretchMode::Auto, StretchMode::None, StretchMode::Percentile})
        if (name == stretchModeName(m)) return m;
    return Error{"--stretch '" + name + "': expected auto|none|percentile"};
}

namespace {

/// The stretch a mode gives without looking at the pixels, if any: identity for 8-bit (Auto, None), the full
/// 16-bit range for None.
std::optional<Stretch> fixedStretch(SampleType type, int channels, StretchMode mode) {
    Stretch s;
    s.channels = channels;
    if (type == SampleType::U8 && mode != StretchMode::Percentile) return s;
    if (type != SampleType::U8 && mode == StretchMode::None) {
        s.identity = false;
        s.low.fill(0.0f);
        s.high.fill(65535.0f);
        return s;
    }
    return std::nullopt;
}

} // namespace

Result<Stretch> stretchFor(const RasterInfo& info, const std::filesystem::path& cacheDir, StretchMode mode) {
    if (auto fixed = fixedStretch(info.type, info.channels, mode)) return *fixed;
    std::error_code ec;
    const std::filesystem::path abs = std::filesystem::weakly_canonical(std::filesystem::absolute(info.path, ec), ec);
    const auto size = std::filesystem::file_size(info.path, ec);
    const auto mtime = std::filesystem::last_write_time(info.path, ec).time_since_epoch().count();
    const std::string key = abs.string() + "|" + std::to_string(size) + "|" + std::to_string(mtime) + "|" +
                            percentilesKey() + (info.type == SampleType::U8 ? "|8-bit" : "");
    return cachedStretch(key, abs.string(), cacheDir,
                         [&] { return streamedStretch(info.path, kStretchLowPercent, kStretchHighPercent); });
}

Result<Stretch> stretchFor(const RasterMosaic& mosaic, const std::filesystem::path& cacheDir, StretchMode mode) {
    if (auto fixed = fixedStretch(mosaic.type, mosaic.bands, mode)) return *fixed;
    if (mosaic.tiles.size() == 1 && !mosaic.hasNodata()) return stretchFor(mosaic.tiles.front(), cacheDir, mode);
    return cachedStretch("mosaic|" + mosaic.key + "|" + percentilesKey() +
                             (mosaic.type == SampleType::U8 ? "|8-bit" : ""),
                         mosaic.tiles.front().path.string(),
                         cacheDir, [&] { return mosaicStretch(mosaic); });
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
                    // Alpha is coverage, not reflectance: scaled to 8 bits, never stretched.
                    const auto a = img.pixels[i * size_t(img.channels) + size_t(img.channels - 1)];
                    out.pixels[i * 4 + 3] = std::uint8_t(info.type == SampleType::U16 ? a >> 8 : a);
                    break;
                }
                out.pixels[i * 4 + size_t(c)] =
                    stretch.apply(src, float(img.pixels[i * size_t(img.channels) + size_t(src)]));
            }
        }
    };
    // Through BandReader, which reads what OpenImageIO cannot (JPEG orthophotos' YCbCr tiles) and decodes on all cores.
    auto reader = BandReader::open(info.path, 1024);
    if (!reader) return reader.error();
    auto whole = [&](auto sample) -> Status {
        using T = decltype(sample);
        Image<T> img;
        img.width = reader->width();
        img.height = reader->height();
        img.channels = std::min(reader->channels(), 4);
        img.pixels.resize(size_t(img.width) * size_t(img.height) * size_t(img.channels));
        const SampleType type = sizeof(T) == 1 ? SampleType::U8 : SampleType::U16;
        for (int y = 0; y < img.height; y += reader->bandRows()) {
            const int y1 = std::min(img.height, y + reader->bandRows());
            T* rows = img.pixels.data() + size_t(y) * size_t(img.width) * size_t(img.channels);
            if (auto st = reader->read(y, y1, img.channels, type, rows); !st) return st;
        }
        fill(img);
        return Ok{};
    };
    const Status st = info.type == SampleType::U8 ? whole(std::uint8_t{}) : whole(std::uint16_t{});
    if (!st) return st.error();
    return out;
}

} // namespace seasonview
