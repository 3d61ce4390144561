#include "CanopyPyramid.h"

#include "BlockLoader.h"
#include "GeoTiffStreamWriter.h"
#include "ParallelIndices.h"
#include "PyramidBuilder.h"
#include "StableHash.h"

#include <algorithm>
#include <cassert>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

namespace seasonview {

int canopyTopK(const SegmentationParams& params, int requestedTopK) {
    const int k = effectiveK(params);
    int top = requestedTopK > 0 ? requestedTopK : std::min(kSegMaxK, 3 * k);
    if (params.method == SegmentationMethod::Pixel) top = 1;
    return std::clamp(top | 1, k, kSegMaxK);
}

namespace {

std::string statsKey(const SegmentationStats& stats) {
    std::string bytes;
    for (const auto* luts : {&stats.lutOn, &stats.lutOff})
        for (const ChannelLut& lut : *luts) bytes.append(reinterpret_cast<const char*>(lut.data()), lut.size());
    char key[64];
    std::snprintf(key, sizeof key, "%016llx drop %d", static_cast<unsigned long long>(stableHash64(bytes)),
                  stats.dropThreshold);
    return key;
}

/// Level `level` of the canopy (size `w`×`h`) into `file`: bands of `tileSize` rows, each band's tiles derived in
/// parallel from both seasons' texels around them.
Status writeCanopyLevel(PyramidBlockSource& seasons, int level, int w, int h, const std::vector<CanopyGroup>& groups,
                        SegmentationMethod method, const SegmentationStats& stats, const std::filesystem::path& file,
                        int tileSize) {
    GeoTiffWriteOptions o;
    o.tileSize = tileSize;
    o.compression = TiffCompression::Zstd;
    auto out = GeoTiffStreamWriter::open(file, w, h, 1, SampleType::U8, std::nullopt, o);
    if (!out) return out.error();
    const int halo = canopyDeriveHalo(method, groups);
    const int threads = int(std::max(1u, std::thread::hardware_concurrency()));
    std::vector<std::uint8_t> band;
    for (int y0 = 0; y0 < h; y0 += tileSize) {
        const int y1 = std::min(h, y0 + tileSize), columns = (w + tileSize - 1) / tileSize;
        band.assign(size_t(w) * size_t(y1 - y0), 0);
        std::vector<std::string> errors(static_cast<size_t>(columns));
        parallelIndices(columns, threads, [&](int c, int) {
            const TexelRect t{c * tileSize, y0, std::min(w, (c + 1) * tileSize), y1};
            const TexelRect r{std::max(0, t.x0 - halo), std::max(0, t.y0 - halo), std::min(w, t.x1 + halo),
                              std::min(h, t.y1 + halo)};
            std::vector<std::uint8_t> on(size_t(r.area()) * 4), off(on.size()), values(size_t(t.area()));
            if (Status st = seasons.read(0, level, r, on.data()); !st) {
                errors[size_t(c)] = st.error().message;
                return;
            }
            if (Status st = seasons.read(1, level, r, off.data()); !st) {
                errors[size_t(c)] = st.error().message;
                return;
            }
            deriveCanopyTexels(on.data(), off.data(), r, {w, h}, t, method, stats, groups, values.data());
            for (int y = t.y0; y < t.y1; ++y)
                std::copy_n(values.begin() + std::ptrdiff_t(size_t(y - t.y0) * size_t(t.width())), t.width(),
                            band.begin() + std::ptrdiff_t(size_t(y - y0) * size_t(w) + size_t(t.x0)));
        });
        for (const std::string& e : errors)
            if (!e.empty()) return Error{e};
        if (Status st = out->writeRows(y0, y1 - y0, band.data()); !st) return st.error();
    }
    return out->finish();
}

} // namespace

PyramidSource canopyPyramidSource(const ImagePyramid& on, const ImagePyramid& off, const CanopyPyramidParams& params,
                                  const SegmentationStats& stats) {
    assert(on.streamedLevels == 0 && off.streamedLevels == 0 && on.levels.size() == off.levels.size() &&
           on.width() == off.width() && on.height() == off.height() && on.format == TexelFormat::Rgba8 &&
           "canopyPyramidSource(): the pair's two prepared pyramids on one grid");
    PyramidSource s;
    char p[128];
    std::snprintf(p, sizeof p, "method %d k %d layers %d top k %d", int(params.params.method),
                  effectiveK(params.params), params.layers, params.topK);
    // One pyramid per pair and parameters: older versions (the seasons changed) share the name and are removed.
    s.name = "canopy " + std::string(p) + " of " + on.folder.string() + " and " + off.folder.string();
    s.identity = "canopy r8|" + on.sourceKey + "|" + off.sourceKey + "|" + p + "|" + statsKey(stats);
    s.width = on.width();
    s.height = on.height();
    s.format = TexelFormat::R8;
    s.build = [&on, &off, params, stats](const std::filesystem::path& folder, int tileSize,
                                         const ProgressFn& progress) -> Result<std::vector<PyramidLevel>> {
        PyramidBlockSource seasons(pyramidLevelFiles({on, off}), 256, TexelFormat::Rgba8);
        const auto sizes = pyramidLevelSizes(on.width(), on.height());
        std::vector<PyramidLevel> levels;
        double done = 0.0, total = 0.0;
        for (const auto& [w, h] : sizes) total += double(w) * double(h);
        for (size_t k = 0; k < sizes.size(); ++k) {
            const auto [w, h] = sizes[k];
            if (progress) progress(done / total, ("canopy level " + std::to_string(k)).c_str());
            const std::vector<CanopyGroup> groups =
                canopyGroups(params.params, params.layers, params.topK, int(k));
            PyramidLevel level{folder / pyramidLevelFileName(int(k)), w, h};
            if (Status st = writeCanopyLevel(seasons, int(k), w, h, groups, params.params.method, stats, level.file,
                                             tileSize);
                !st)
                return st.error();
            levels.push_back(std::move(level));
            done += double(w) * double(h);
        }
        if (progress) progress(1.0, "canopy levels");
        return levels;
    };
    return s;
}

} // namespace seasonview
