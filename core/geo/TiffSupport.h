#pragma once
// libtiff plumbing shared by the raw tile reader (BandReader.cpp) and the streaming writer (GeoTiffStreamWriter.cpp):
// one-time registration of GDAL's nodata tag, per-file error messages. The georeferencing tags are GDAL's to read and
// write (GdalSupport.h). Internal to core: other modules go through Raster.h and GeoTiffStreamWriter.h.
#include "Raster.h"

#include <tiffio.h>

#include <filesystem>
#include <optional>
#include <string>

namespace seasonview::tiff {

/// GDAL's private tag holding the nodata value as text.
constexpr ttag_t kTagGdalNodata = 42113;

/// Registers GDAL's nodata tag and silences libtiff's global handlers.
/// Idempotent and thread-safe; every TIFF open in core calls it first.
void init();

/// Opens a TIFF (libtiff `mode`: "r", "w", "w8" for BigTIFF) with its own error handler: libtiff's last message
/// about this file goes to `*error`, which must outlive the handle. Returns nullptr on failure (`*error` says why).
TIFF* open(const std::filesystem::path& path, const char* mode, std::string* error);

/// Writes GDAL's nodata tag. Call before the first tile or strip. False on failure.
bool writeNodataTag(TIFF* tif, double nodata);

} // namespace seasonview::tiff
