#pragma once
// Scene inputs on the web. A URL (http:// or https://) given for a season or the DEM is read through GDAL's
// /vsicurl/ file system: HTTP range requests for the headers and the tiles a read touches, as a Cloud-Optimized
// GeoTIFF is meant to be read (any raster GDAL reads by ranges works; a COG's layout keeps the requests few).
// Every request names seasonview in its User-Agent, times out, and is retried with backoff on 429, 500 and 502–504
// (GDAL's reads of tiles and ranges by GDAL's backoff; seasonview's own requests, the HEADs, tile probes and
// capabilities, also on timeouts and resets, waiting as long as a 429's or 503's Retry-After says).
// Before the raster is opened, one HEAD request asks the server for the file: an HTTP error is one line naming the
// URL and the status, and the answer's size, Last-Modified and ETag are the input's identity for the caches.
#include "Crs.h"
#include "Result.h"

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>

namespace seasonview::web {

/// Whether an input as the user gave it is a URL (http:// or https://).
bool isUrl(std::string_view input);
/// The name GDAL opens a URL by ("/vsicurl/URL").
std::filesystem::path gdalPath(const std::string& url);
/// Whether a path is such a name.
bool isRemote(const std::filesystem::path& path);
/// The URL of such a name (itself for any other path).
std::string urlOf(const std::filesystem::path& path);
/// What caches key a URL on: "URL|size|Last-Modified|ETag", from a HEAD request. Errors, one line naming the URL:
/// an HTTP status of 400 or more ("HTTP 404"), no answer (the transfer library's words), no size. Asked once per
/// process (the answer is kept).
Result<std::string> identity(const std::string& url);
/// The User-Agent every request sends ("seasonview/VERSION").
std::string userAgent();

/// Whether an input is an XYZ or TMS tile service: a URL template with {z}, {x} and {y} (256-pixel tiles of Web
/// Mercator, rows from the top, as OpenStreetMap's and most services') or {-y} (TMS: rows from the bottom).
bool isTileTemplate(std::string_view input);

/// The tile cache's default bound (--web-cache-mb).
inline constexpr double kDefaultWebCacheMb = 1024.0;

/// Connections to a service's host at once, per reader (GDAL dataset) of a description.
inline constexpr int kDefaultConnections = 4;

/// How a run uses tile services. `offline`: only the disk cache (GDAL's OfflineMode: a tile not cached is no data,
/// the zoom must have been found by an earlier run); `cacheMb`: the bound of the on-disk tile cache, in MiB;
/// `maxConnections`: per reader of the description (streaming runs several readers, each with a share of the bound).
struct ServiceOptions {
    bool offline = false;
    double cacheMb = kDefaultWebCacheMb;
    int maxConnections = kDefaultConnections;
};

/// Bounds a tile cache folder to `maxBytes`: removes the least recently fetched tiles (oldest modification time
/// first) until the files left hold no more. Returns the bytes removed. Tiles are kept without expiry otherwise
/// (GDAL's own expiry and cleaner are off): the pyramids made from them do not expire either.
long long trimTileCache(const std::filesystem::path& tilesDir, long long maxBytes);

/// The part of a tile service a scene reads: a rectangle in the service's CRS (Web Mercator, EPSG:3857, for XYZ and
/// TMS templates; the tile matrix set's for a WMTS) and the pixel size wanted there, in that CRS's units (the zoom
/// chosen is the coarsest whose pixels are not larger).
struct TileArea {
    double minX = 0, minY = 0, maxX = 0, maxY = 0;
    double pixelSize = 1;
};

/// A GDAL WMS description of the service over `area`, written into cacheDir/web/ (the same content, the same file:
/// its identity keys the pyramid cache), its tiles cached by GDAL in cacheDir/web/tiles/ so that a second run fetches
/// none. The zoom: the coarsest not coarser than area.pixelSize, or, where the service has no tile at the area's
/// centre at that zoom (404 or 204), the finest it has (at most 23 requests). Tiles missing when read (404, 204)
/// are no data; other HTTP errors, a web page instead of an image and failed transfers are errors naming the tile's
/// URL. At most 4 connections, seasonview's User-Agent, 30 s timeout, retries on 429, 500 and 502-504. The tile cache is
/// bounded to options.cacheMb (trimTileCache) before the service is read. A TMS template
/// ({-y}) is described over the whole world (GDAL counts TMS rows from its window's bottom) and cut to the area by a
/// VRT next to it, which is what is returned then.
Result<std::filesystem::path> describeTileService(const std::string& url, const TileArea& area,
                                                  const std::filesystem::path& cacheDir,
                                                  const ServiceOptions& options = {});

/// Whether an input is a WMTS layer: an http(s) URL of a WMTS GetCapabilities document ("wmts" in it) with a
/// `layer=NAME` query parameter, optionally `tilematrixset=ID` and `style=ID` (removed from the URL fetched).
bool isWmts(std::string_view input);

/// A GDAL WMTS description (GDAL_WMTS XML) of a WMTS layer over the area `areaIn` gives in the tile matrix set's CRS,
/// written into cacheDir/web/ as describeTileService writes its own: the capabilities document fetched once and
/// kept there (a second run, or --offline, asks the server for nothing), the tile matrix chosen by its scale (the
/// coarsest whose pixels are not larger than the area's pixel size, else the finest), the same connections,
/// User-Agent, timeout, tile cache and bound. Errors, one line naming the URL: HTTP errors, a web page or another
/// document instead of WMTS capabilities, a layer, tile matrix set or style the service does not list (naming those
/// it does).
Result<std::filesystem::path> describeWmts(const std::string& url,
                                           const std::function<Result<TileArea>(const Crs&)>& areaIn,
                                           const std::filesystem::path& cacheDir, const ServiceOptions& options = {});

/// A read of a tile service's description (describeTileService's XML or VRT, describeWmts's XML with a RESTful
/// template) failed with GDAL's words `message`
/// ("... Unable to download block X, Y ..."; GDAL 3.6 leaves the URL out): the tile's URL and status, found by asking
/// the server again for the tiles that block can be at its zoom and the three coarser (at most 4 requests), as the
/// one line "TILE_URL: HTTP 500 (reading DESCRIPTION)". Nothing when `description` is no such file or no tile fails.
std::optional<Error> tileFailure(const std::filesystem::path& description, const std::string& message);

/// A read of a tile service's description failed with GDAL's words `message`, which name an HTTP status of a busy
/// server (429, 503) or gateway (502, 504); GDAL 3.6's tile drivers fail the block at once and never read
/// Retry-After: how many seconds to wait before reading again. The failed block's tile is asked for once more: what
/// its Retry-After says on 429 or 503 (at most 60 s), `fallback` when it names none or the server is still busy, 0
/// when the tile now answers. Nothing when the message names no such status (a 500 is the server's fault: no wait
/// makes it right) or the tile now answers otherwise.
std::optional<double> busyWait(const std::filesystem::path& description, const std::string& message, double fallback);

/// A read of pixels [x0, x1) × [y0, y1) of a service description failed in a way GDAL does not tie to a tile (a tile
/// that does not decode: a body cut short, garbage): the first of the tiles under them (at most 64) that the server
/// now answers with an error or garbage, as tileFailure's one line. Nothing when none does.
std::optional<Error> tileFailureIn(const std::filesystem::path& description, long long x0, long long y0, long long x1,
                                   long long y1);

/// The bytes in the disk tile cache of the tile of block (col, row) of a service description (describeTileService's
/// XML or TMS cut, describeWmts's XML; blocks of 256 pixels from the description's first): GDAL keeps each tile as
/// the file named by the MD5 of its URL under the description's cache path. Nothing when it is not in the cache.
std::optional<long long> cachedTileBytes(const std::filesystem::path& description, long long col, long long row);

/// The tiles a service description covers at its zoom (describeTileService's XYZ window or TMS cut: what a read of
/// the whole area fetches); nothing for other files (a WMTS description: GDAL chooses its tiles).
std::optional<long long> serviceTileCount(const std::filesystem::path& description);

/// What a tile cache folder gained since this was made (the tiles reads fetched from the service): the files written
/// since, and their bytes. Scans the folder on each call.
class TileFetchCounter {
public:
    explicit TileFetchCounter(std::filesystem::path tilesDir);
    struct Count {
        long long tiles = 0, bytes = 0;
    };
    Count fetched() const;

private:
    std::filesystem::path m_dir;
    std::filesystem::file_time_type m_start;
};

/// The identity caches key a GDAL service description on (a GDAL_WMS or GDAL_WMTS XML file, written by
/// describeTileService or by the user): its content less the elements that do not change its pixels (OfflineMode,
/// Cache, MaxConnections, Timeout, UserAgent), so that an offline run or another cache bound finds the same pyramid.
/// Empty for any other file.
std::optional<std::string> serviceIdentity(const std::filesystem::path& file);

/// While alive, GDAL opens `path`, when it is a URL, without listing its folder or asking for side files (.aux.xml,
/// .ovr, .msk: requests that a web server answers 404 or with a listing page); local files still find theirs
/// (world files, .prj). Set for this thread only.
class RemoteOpen {
public:
    explicit RemoteOpen(const std::filesystem::path& path);
    ~RemoteOpen();
    RemoteOpen(const RemoteOpen&) = delete;
    RemoteOpen& operator=(const RemoteOpen&) = delete;

private:
    bool m_set = false;
    std::string m_previous;
    bool m_hadPrevious = false;
};

} // namespace seasonview::web
