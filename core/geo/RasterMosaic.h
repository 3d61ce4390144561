#pragma once
// A scene input as the user gives it: one raster file (any format GDAL reads, a VRT included), a folder (every
// raster in it), a glob, or a list of these. Resolved to the files it names, each opened through GDAL and checked
// against the first (bands, sample type, CRS), so that a mosaic of tiles with gaps, overlaps and nodata collars
// can be read as one raster on any grid (GridReader.h).
#include "Raster.h"
#include "Result.h"

#include <glm/vec2.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace seasonview {

/// What the user gave for one input: files, folders, globs, VRTs (paths as given: relative to the working
/// directory, or made absolute by the manifest's reader). Converts from a single path.
struct SourceList {
    std::vector<std::filesystem::path> items;

    SourceList() = default;
    SourceList(std::filesystem::path p) { // NOLINT: a single path is the common case
        if (!p.empty()) items.push_back(std::move(p));
    }
    SourceList(const char* p) : SourceList(std::filesystem::path(p)) {} // NOLINT
    SourceList(std::vector<std::filesystem::path> list) : items(std::move(list)) {} // NOLINT
    bool empty() const { return items.empty(); }
    /// "a.tif", or "tiles/ (and 2 more)": how messages name it.
    std::string describe() const;
};

/// The rasters an input resolves to.
struct RasterMosaic {
    std::vector<RasterInfo> tiles;  // sorted by path; every one georeferenced in `crs`
    Crs crs;
    int bands = 0;                  // bands other than alpha, the same in every tile
    SampleType type = SampleType::U8;
    glm::dvec2 min{0.0}, max{0.0};  // union of the tiles' extents, in crs units
    /// Identity for caches: every tile's canonical path, size and modification time (and an assumed CRS).
    std::string key;
    /// True when some tile marks pixels as no data (nodata value, alpha band, mask).
    bool hasNodata() const;
    /// The tile with the smallest pixel area.
    const RasterInfo& finest() const;
};

/// The most tile files one mosaic opens (each is opened to read its header; a VRT of more counts as one).
inline constexpr std::size_t kMaxMosaicTiles = std::size_t(1) << 18;

/// Expands `sources` (files, folders, globs; a VRT is a file) and opens every raster: files in a folder that GDAL
/// does not take for a raster (world files, .prj, .aux.xml, .msk, text) are skipped. Tiles without a CRS take
/// `assumedCrs` (--crs). `role` names the input in messages ("leaf-on"). Errors, one line naming the file: a path
/// that does not exist, a glob that matches nothing, a folder with no rasters, an unreadable raster, a tile without
/// georeferencing or CRS (suggesting --crs), tiles that disagree with the first in band count, sample type or CRS.
Result<RasterMosaic> openMosaic(const SourceList& sources, const std::string& role,
                                const std::optional<Crs>& assumedCrs = {});

/// `path|size|mtime` of a file (canonical absolute path): what caches key a source file on. A URL: its HEAD
/// (web::identity); a GDAL service description: what it describes (web::serviceIdentity).
Result<std::string> fileIdentity(const std::filesystem::path& path);

} // namespace seasonview
