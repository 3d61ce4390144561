#pragma once
// libtiff plumbing shared by the GeoTIFF reader (Raster.cpp) and the streaming writer (GeoTiffStreamWriter.cpp):
// one-time registration of the GeoTIFF and GDAL tags, per-file error messages, and the georeferencing tags.
// Internal to core: other modules go through Raster.h and GeoTiffStreamWriter.h.
#include "Raster.h"

#include <tiffio.h>
#include <xtiffio.h> // the GeoTIFF tags (TIFFTAG_GEOPIXELSCALE, ...)

#include <filesystem>
#include <optional>
#include <string>

namespace seasonview::tiff {

/// GDAL's private tag holding the nodata value as text.
constexpr ttag_t kTagGdalNodata = 42113;

/// Registers the GeoTIFF tags (libgeotiff) and GDAL's nodata tag and silences libtiff's global handlers.
/// Idempotent and thread-safe; every TIFF open in core calls it first.
void init();

/// Opens a TIFF (libtiff `mode`: "r", "w", "w8" for BigTIFF) with its own error handler: libtiff's last message
/// about this file goes to `*error`, which must outlive the handle. Returns nullptr on failure (`*error` says why).
TIFF* open(const std::filesystem::path& path, const char* mode, std::string* error);

/// Writes the GeoTIFF georeferencing of `georef` (model pixel scale, tie point, GeoKeys with the EPSG code,
/// PixelIsArea) and, when given, GDAL's nodata tag. Call before the first tile or strip. False on failure.
bool writeGeoTags(TIFF* tif, const Georef& georef, const std::optional<double>& nodata);

} // namespace seasonview::tiff
