#include "TiffSupport.h"

#include "GdalSupport.h"

#include <cstdarg>
#include <cstdio>
#include <mutex>

namespace seasonview::tiff {

namespace {

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
        // GDAL owns libtiff's global handlers (it routes them to CPLError, which core captures per call); the files
        // opened here get per-handle handlers instead.
        gdal::init();
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

bool writeNodataTag(TIFF* tif, double nodata) {
    char text[64];
    std::snprintf(text, sizeof text, "%.17g", nodata);
    return TIFFSetField(tif, kTagGdalNodata, text) != 0;
}

} // namespace seasonview::tiff
