#pragma once
// Direct streaming of a season from a tile service (--stream, issue 25): instead of preparing the season at full
// resolution (`prepare` fetches every tile of the area at the finest zoom), only its coarse levels are prepared, from
// the service at their own zoom (a level of at most kStreamPreparedSide texels a side: tens of tiles), and the finer
// levels are read block by block as the clipmaps' windows reach them: each level from the service at the zoom that
// matches its texel size (Tanner 1998 §4: each clip level is fed from the pyramid level of its own resolution),
// reprojected onto that level's grid (the working grid with 2^level times its pixel), the tiles kept in the bounded
// on-disk tile cache (--web-cache-mb). Frames never wait: a block not read yet is drawn from coarser levels.
#include "ImagePyramid.h"
#include "Result.h"
#include "Scene.h"

#include <filesystem>
#include <string>

namespace seasonview {

/// Levels at most this many texels a side are prepared: the default clipmap's resident coarse pyramid (ClipmapOptions
/// size 2048) is then on disk, and the pair statistics have millions of texels (a few hundred tiles to fetch at most).
/// A narrower clipmap reads the streamed level it keeps resident whole, when it starts.
inline constexpr int kStreamPreparedSide = 2048;

/// The grid of pyramid level `level` of `grid`: the same origin and CRS, 2^level times the pixel size, the level's
/// size (pyramidLevelSizes: halved, rounded up).
WorkingGrid levelGrid(const WorkingGrid& grid, int level);

/// The pyramid of `role` ("leafon" or "leafoff", a season from a tile service) streamed: the levels no wider than
/// kStreamPreparedSide prepared in the cache (preparePyramid of the season read at that level's zoom; reused when up
/// to date), the finer ones streamed (ImagePyramid::streamedLevels, openStreamedLevel). A season small enough to have
/// no finer level is prepared whole. Errors name the service (a tile's URL and status) or the cache file.
Result<PrepareReport> prepareStreamedPyramid(const Scene& scene, const std::string& role,
                                             const PrepareOptions& options);

/// The pyramid of season `role` ("leafon" or "leafoff") as the scene asks: streamed (prepareStreamedPyramid) when
/// the scene streams (--stream) and the season is a tile service, else prepared whole (preparePyramid).
Result<PrepareReport> prepareSeasonPyramid(const Scene& scene, const std::string& role, const PrepareOptions& options);

/// The streamed pyramids' prepared part for what reads whole levels (the pair statistics, the coverage probe): each
/// pyramid from the first level that all have on disk (`level` set to it), or the pyramids as they are (0).
std::vector<ImagePyramid> preparedPart(const std::vector<ImagePyramid>& pyramids, int* level = nullptr);

/// The service tiles under the blocks streamed levels were asked for since the last reset: the geometric minimum of
/// what streaming must fetch (each tile counted once, whichever level or season asked), and the regions read (each
/// a service request of its tiles, or their disk cache's). Counted from the first resetStreamTileCount() on (a bench;
/// the viewer and stills pay nothing for it).
struct StreamTileCount {
    long long tilesNeeded = 0;
    long long regionsRead = 0;
    /// The bytes of those tiles in the disk tile cache now (web::cachedTileBytes), and how many of them are not there
    /// (no data, 404; or trimmed by --web-cache-mb).
    long long bytesNeeded = 0;
    long long tilesNotCached = 0;
};
StreamTileCount streamTileCount();
void resetStreamTileCount();

/// An error for `what` (a renderer or command that reads every full-resolution texel: the reference renderer, the
/// segmentation) when any of `pyramids` is streamed; Ok otherwise.
Status refuseStreamed(const std::vector<ImagePyramid>& pyramids, const std::string& what);

} // namespace seasonview
