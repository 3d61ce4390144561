#pragma once
// The per-pair segmentation statistics of a prepared layer pair: the histograms of SegmentationStats.h computed once
// from level 0 of both seasons' image pyramids (clipmap/ImagePyramid.h: the source with its display stretch applied,
// the same 8-bit values `seasonview segment` feeds the CPU rule) and kept next to the pyramids as a small JSON file,
// so the GPU segmentation gets its equalisation tables and drop threshold without touching the full-resolution
// imagery again, and `seasonview segment` can skip its histogram pass.
#include "ImagePyramid.h"
#include "SegmentationStats.h"
#include "Progress.h"

#include <filesystem>
#include <optional>
#include <string>

namespace seasonview {

/// What preparing the pair histograms did.
struct PairHistogramsReport {
    std::filesystem::path file; // the cache file: <cacheDir>/pairstats/<key hash>.json
    bool built = false;         // computed from the pyramids (false: read back from `file`)
    std::string reason;         // why it was built: "not prepared yet", "cache corrupt: ..."
    double seconds = 0.0;
};

/// The pair's histograms (colour and drop) exactly as pairHistograms() of Segmentation.h gives them for the two
/// level-0 images held whole: every kSegHistogramStep-th pixel of every kSegHistogramStep-th image row. Streams both
/// level-0 TIFFs in bands of tile rows (memory: a few bands, whatever the size), the seasons on two threads.
/// Cached in `cacheDir`/pairstats/ keyed by both pyramids' sourceKey: reused when present and valid, rebuilt when
/// missing or corrupt, written under a temporary name and renamed. Call after both pyramids are prepared; `report`
/// (optional) says what happened. Errors are one line naming the file and the problem (a level-0 file truncated
/// or unreadable, the two levels of different sizes, the cache folder not writable).
Result<SegmentationHistograms> preparePairHistograms(const ImagePyramid& leafon, const ImagePyramid& leafoff,
                                                     const std::filesystem::path& cacheDir,
                                                     const ProgressFn& progress = {},
                                                     PairHistogramsReport* report = nullptr);

/// The cached histograms of the pair, or nothing when there are none or they are corrupt or belong to other
/// sources. Never computes and never writes.
std::optional<SegmentationHistograms> cachedPairHistograms(const ImagePyramid& leafon, const ImagePyramid& leafoff,
                                                           const std::filesystem::path& cacheDir);

/// The cache file of a pair (it may not exist).
std::filesystem::path pairHistogramsFile(const ImagePyramid& leafon, const ImagePyramid& leafoff,
                                         const std::filesystem::path& cacheDir);

} // namespace seasonview
