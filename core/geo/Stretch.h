#pragma once
// Display stretch of imagery: 16-bit (e.g. Sentinel-2 reflectance x10000) mapped to 8-bit by a robust per-band
// linear stretch between the 0.5 and 99.5 percentiles. Computed once per file and stored in the cache, never
// per tile (tiles would otherwise get different colours).
#include "Raster.h"
#include "RasterMosaic.h"
#include "Result.h"

#include <array>
#include <cstdint>
#include <filesystem>

namespace seasonview {

struct Stretch {
    int channels = 0;
    std::array<float, 4> low{0, 0, 0, 0};    // sample value mapped to 0
    std::array<float, 4> high{255, 255, 255, 255}; // sample value mapped to 255
    bool identity = true; // 8-bit input: no change

    /// Maps one sample of band `c` to 0..255.
    std::uint8_t apply(int c, float v) const {
        if (identity) return std::uint8_t(v < 0 ? 0 : v > 255 ? 255 : v);
        const float t = (v - low[size_t(c)]) / (high[size_t(c)] - low[size_t(c)]) * 255.0f + 0.5f;
        return std::uint8_t(t < 0 ? 0 : t > 255 ? 255 : t);
    }
};

constexpr double kStretchLowPercent = 0.5, kStretchHighPercent = 99.5;

/// How a season's samples become display (and segmentation) colour:
/// - Auto: 16-bit data through the percentile stretch, 8-bit data as they are (what orthophotos in natural colour
///   need);
/// - Percentile: the per-band 0.5–99.5 % stretch for 8-bit data too (8-bit deliveries of radiometric data, such as
///   top-of-atmosphere reflectance scaled into a byte, whose colour is not balanced for display);
/// - None: samples as they are (16-bit data scaled by 1/257).
enum class StretchMode { Auto, None, Percentile };
const char* stretchModeName(StretchMode m);
/// The mode called `name` ("auto", "none", "percentile"); an error names --stretch.
Result<StretchMode> parseStretchMode(const std::string& name);

/// Percentile stretch of a 16-bit image (per band; zero samples, the usual nodata fill, are ignored).
Stretch computeStretch(const Image<std::uint16_t>& image, double lowPercent = kStretchLowPercent,
                       double highPercent = kStretchHighPercent);

/// The cache folder: $SEASONVIEW_CACHE, else $XDG_CACHE_HOME/seasonview, else ~/.cache/seasonview.
std::filesystem::path defaultCacheDir();

/// The stretch of an imagery file as `mode` says: identity for 8-bit (Auto, None), a full-range scale for 16-bit
/// (None), else percentiles read from `cacheDir` (keyed by absolute path, size and modification time) or computed
/// from the pixels (streamed in bands of rows: bounded memory for any size) and stored there. A cache that cannot be written is not an
/// error (the stretch is just recomputed next time).
Result<Stretch> stretchFor(const RasterInfo& info, const std::filesystem::path& cacheDir,
                           StretchMode mode = StretchMode::Auto);

/// The stretch of a season delivered as a mosaic: identity for 8-bit; a single file without nodata as above;
/// otherwise the percentiles of every tile's valid pixels (nodata values, alpha and masks honoured, zeros ignored)
/// at their own resolution, so that all tiles share one stretch. Cached like the above, keyed by the mosaic.
Result<Stretch> stretchFor(const RasterMosaic& mosaic, const std::filesystem::path& cacheDir,
                           StretchMode mode = StretchMode::Auto);

/// 8-bit RGBA pixels of an imagery file with its stretch applied (alpha 255 unless the file has alpha).
Result<Image<std::uint8_t>> readDisplayRgba(const RasterInfo& info, const Stretch& stretch);

} // namespace seasonview
