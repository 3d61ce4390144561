#pragma once
// The prepared form of one imagery layer that clipmaps stream from: a folder in the cache holding one tiled
// (256² by default), Zstandard-compressed 8-bit RGBA TIFF per mip level on the scene's working grid (the season
// warped onto it when it was delivered on another grid or as a mosaic), the layer's stored display stretch already
// applied, colour premultiplied by alpha (alpha 0 where the season has no data; coarser levels the box filter of
// the finer, so alpha is coverage), plus a manifest (pyramid.json) written last. Built once per source
// (`seasonview prepare`), reused while the source files are unchanged, rebuilt when they changed or when the cache is
// corrupt.
#include "Result.h"
#include "Scene.h"
#include "Progress.h"
#include "ToroidalWindow.h"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace seasonview {

struct PyramidLevel {
    std::filesystem::path file; // level_LL.tif inside the pyramid folder
    int width = 0, height = 0;  // level 0 = the source size; level k = ceil(level k-1 / 2), down to 1x1
};

/// What a pyramid's texels are: display RGBA, premultiplied (imagery), float heights (elevation,
/// terrain/ElevationPyramid.h) or one byte (the canopy layer's values, foliage/CanopyPyramid.h).
enum class TexelFormat { Rgba8, R32F, R8 };
/// Channels and bytes per texel of `format`.
inline int texelChannels(TexelFormat format) { return format == TexelFormat::Rgba8 ? 4 : 1; }
inline int texelBytes(TexelFormat format) { return format == TexelFormat::R8 ? 1 : 4; }

/// Reads texels of a level that has no file (a streamed level, app/StreamedPyramid.h): `texels` (level texel
/// coordinates) as rows of premultiplied RGBA8 into `rgba`, (0, 0, 0, 0) where the season has no data. Errors are one
/// line naming what failed (a tile's URL and its HTTP status). Called from the block loader's workers at once: must
/// be thread-safe.
using LevelTexelReader = std::function<Status(const TexelRect& texels, std::uint8_t* rgba)>;

/// The clipmap loader's workers when a layer streams (a streamed read waits on a service's round trips, so several
/// are in flight; app/StreamedPyramid.h gives each an equal share of the connections to the service).
inline constexpr int kStreamWorkers = 4;

struct ImagePyramid {
    std::filesystem::path folder;   // <cache>/pyramids/<key hash>
    std::string sourceKey;          // the sources' files (paths, sizes, mtimes), grid, stretch: what the cache belongs to
    int tileSize = 256;
    TexelFormat format = TexelFormat::Rgba8;
    std::vector<PyramidLevel> levels;
    /// Levels [0, streamedLevels) have no file (their `file` is empty): the clipmap's loader reads them through
    /// openStreamedLevel(level), made on the loader's thread at the level's first read. 0 for a prepared pyramid.
    int streamedLevels = 0;
    std::function<Result<LevelTexelReader>(int level)> openStreamedLevel;
    int width() const { return levels.empty() ? 0 : levels[0].width; }
    int height() const { return levels.empty() ? 0 : levels[0].height; }
};

struct PrepareOptions {
    std::filesystem::path cacheDir;  // pyramids go to cacheDir/pyramids/
    int tileSize = 256;
    bool force = false;              // rebuild even when up to date
    ProgressFn progress;             // fraction of this layer done, stage name
};

/// What preparing did: reused an up-to-date pyramid, or built it (and why).
struct PrepareReport {
    ImagePyramid pyramid;
    bool built = false;
    std::string reason;              // "not prepared yet", "source changed", "cache corrupt: ...", "forced"
    double seconds = 0.0;
};

/// Any pyramid's recipe: what it is made from (`name`, for messages and to find older versions of it; `identity`,
/// which changes whenever the texels would: the source files' paths, sizes and mtimes, the grid, the stretch, ...),
/// the level-0 size and format, and the builder that writes the level files (level_LL.tif, sizes
/// pyramidLevelSizes()) into a folder. The imagery overloads below fill it for an ImageryLayer.
struct PyramidSource {
    std::string name;
    std::string identity;
    int width = 0, height = 0;
    TexelFormat format = TexelFormat::Rgba8;
    std::function<Result<std::vector<PyramidLevel>>(const std::filesystem::path& folder, int tileSize,
                                                    const ProgressFn& progress)>
        build;
};

Result<PrepareReport> preparePyramid(const PyramidSource& source, const PrepareOptions& options);
Result<ImagePyramid> openPyramid(const PyramidSource& source, const std::filesystem::path& cacheDir);

/// The recipe of `layer`'s pyramid on its grid (`layer` must outlive it).
Result<PyramidSource> imagerySource(const ImageryLayer& layer);

/// Makes sure `layer` has an up-to-date, valid pyramid in the cache and returns it. Idempotent (an up-to-date
/// pyramid is only validated, not rebuilt) and atomic (built in a temporary folder, renamed into place, so a crash
/// never leaves a half pyramid that looks valid). Streams the source in bands of rows: memory stays bounded
/// (a few tile rows per level) whatever the image size. Errors name the source or the cache file.
Result<PrepareReport> preparePyramid(const ImageryLayer& layer, const PrepareOptions& options);

/// Why a level file does not hold what its pyramid's index says (`bytes` long, width×height texels of `format` in
/// tileSize² tiles), or "" when it does. Reads the header only. What opening a pyramid checks of every level before
/// the block loader reads its tiles.
std::string checkLevelFile(const std::filesystem::path& file, std::uintmax_t bytes, int width, int height,
                           int tileSize, TexelFormat format);

/// Marks a pyramid found damaged (a tile that does not decode) as no longer valid: its manifest is removed, so the next
/// prepare rebuilds it from its source.
void invalidatePyramid(const ImagePyramid& pyramid);

/// When `message` (one error line, which names its file first) names a file of a pyramid in `cacheDir` (imagery or
/// elevation), that pyramid is invalidated; returns whether it was. What commands do with a read error before they
/// prepare again.
bool invalidateDamagedPyramid(const std::string& message, const std::filesystem::path& cacheDir);

/// Opens an existing pyramid for `layer` without building: an error when it is missing, belongs to another
/// source (or an older version of it), or is corrupt (missing or truncated level files, wrong sizes).
Result<ImagePyramid> openPyramid(const ImageryLayer& layer, const std::filesystem::path& cacheDir);

} // namespace seasonview
