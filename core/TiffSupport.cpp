#include "TiffSupport.h"

#include <geokeys.h>
#include <geotiffio.h>

#include <cstdarg>
#include <cstdio>
#include <mutex>

namespace seasonview::tiff {

namespace {

// Files opened by OpenImageIO report through libtiff's global handlers; OpenImageIO reports its own errors.
void ignoreGlobal(const char*, const char*, va_list) {} // unknown private tags etc.: not the user's problem

TIFFExtendProc g_parentExtender = nullptr;
void gdalTagExtender(TIFF* tif) {
    static const TIFFFieldInfo info[] = {
        {kTagGdalNodata, -1, -1, TIFF_ASCII, FIELD_CUSTOM, 1, 0, const_cast<char*>("GDALNoDataValue")}};
    TIFFMergeFieldInfo(tif, info, 1);
    if (g_parentExtender) g_parentExtender(tif);
}

// Per-handle handlers (libtiff >= 4.5): keep the message for our Error, print nothing.
int rememberError(TIFF*, void* user, const char* module, const char* fmt, va_list ap) {
    char buf[512];
    std::vsnprintf(buf, sizeof buf, fmt, ap);
    *static_cast<std::string*>(user) = (module ? std::string(module) + ": " : std::string()) + buf;
    return 1;
}
int ignoreWarning(TIFF*, void*, const char*, const char*, va_list) { return 1; }

} // namespace

void init() {
    static std::once_flag once;
    std::call_once(once, [] {
        TIFFSetErrorHandler(ignoreGlobal);
        TIFFSetWarningHandler(ignoreGlobal);
        XTIFFInitialize(); // registers the GeoTIFF tags
        g_parentExtender = TIFFSetTagExtender(gdalTagExtender);
    });
}

TIFF* open(const std::filesystem::path& path, const char* mode, std::string* error) {
    init();
    error->clear();
    TIFFOpenOptions* opts = TIFFOpenOptionsAlloc();
    TIFFOpenOptionsSetErrorHandlerExtR(opts, rememberError, error);
    TIFFOpenOptionsSetWarningHandlerExtR(opts, ignoreWarning, nullptr);
    TIFF* tif = TIFFOpenExt(path.c_str(), mode, opts);
    TIFFOpenOptionsFree(opts);
    return tif;
}

bool writeGeoTags(TIFF* tif, const Georef& georef, const std::optional<double>& nodata) {
    if (nodata) {
        char text[64];
        std::snprintf(text, sizeof text, "%.17g", *nodata);
        TIFFSetField(tif, kTagGdalNodata, text);
    }
    double scale[3] = {georef.pixelSize.x, georef.pixelSize.y, 0.0};
    double tie[6] = {0.0, 0.0, 0.0, georef.origin.x, georef.origin.y, 0.0};
    TIFFSetField(tif, TIFFTAG_GEOPIXELSCALE, 3, scale);
    TIFFSetField(tif, TIFFTAG_GEOTIEPOINTS, 6, tie);
    GTIF* gt = GTIFNew(tif);
    if (!gt) return false;
    GTIFKeySet(gt, GTModelTypeGeoKey, TYPE_SHORT, 1,
               georef.crs.isGeographic() ? ModelTypeGeographic : ModelTypeProjected);
    GTIFKeySet(gt, GTRasterTypeGeoKey, TYPE_SHORT, 1, RasterPixelIsArea);
    if (georef.crs.isGeographic()) GTIFKeySet(gt, GeographicTypeGeoKey, TYPE_SHORT, 1, georef.crs.epsg);
    else GTIFKeySet(gt, ProjectedCSTypeGeoKey, TYPE_SHORT, 1, georef.crs.epsg);
    const bool ok = GTIFWriteKeys(gt) != 0;
    GTIFFree(gt);
    return ok;
}

} // namespace seasonview::tiff
