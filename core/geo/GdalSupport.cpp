#include "GdalSupport.h"

#include "WebSource.h"

#include <cpl_conv.h>
#include <ogr_spatialref.h>

#include <mutex>

namespace seasonview::gdal {

void init() {
    static std::once_flag once;
    std::call_once(once, [] {
        // Reading must never write next to the user's data (GDAL's .aux.xml statistics and metadata files).
        CPLSetConfigOption("GDAL_PAM_ENABLED", "NO");
        // JPEG-in-TIFF (YCbCr) decoded to RGB by libjpeg, as every orthophoto reader does.
        CPLSetConfigOption("CONVERT_YCBCR_TO_RGB", "YES");
        // Inputs on the web (WebSource.h): requests that name us, time out, and are retried with backoff on 429, 500 and
        // 502-504 (GDAL's retry set). A URL's side files are not asked for: web::RemoteOpen.
        CPLSetConfigOption("GDAL_HTTP_USERAGENT", web::userAgent().c_str());
        CPLSetConfigOption("GDAL_HTTP_TIMEOUT", "30");
        CPLSetConfigOption("GDAL_HTTP_CONNECTTIMEOUT", "10");
        CPLSetConfigOption("GDAL_HTTP_MAX_RETRY", "3");
        CPLSetConfigOption("GDAL_HTTP_RETRY_DELAY", "1");
        GDALAllRegister();
        // Messages outside an ErrorCapture are dropped: every failure reaches the user as one Result line.
        CPLSetErrorHandler(CPLQuietErrorHandler);
        // The block cache bounds what GDAL keeps of decoded source tiles (its default is 5 % of RAM).
        GDALSetCacheMax64(std::int64_t(256) << 20);
    });
}

namespace {

/// Warnings that say nothing about the pixels read.
bool harmlessWarning(const std::string& text) {
    static const char* kHarmless[] = {"extraneous bytes before marker", "Unknown field with tag", "ASCII value for tag",
                                      "wrong data type", "Invalid TIFF directory", "Nonstandard tile",
                                      "Adobe transform", "TIFFReadDirectory", "TIFFFetchNormalTag"};
    for (const char* h : kHarmless)
        if (text.find(h) != std::string::npos) return true;
    return false;
}

} // namespace

ErrorCapture::ErrorCapture() {
    init();
    CPLPushErrorHandlerEx(
        [](CPLErr level, CPLErrorNum code, const char* text) {
            auto* self = static_cast<ErrorCapture*>(CPLGetErrorHandlerUserData());
            (void)code;
            if (!self) return;
            std::string line = firstLine(text ? text : "");
            if (level >= CE_Failure) {
                // A tile service's failed tile: this one says which (its block; the status from the lines GDAL adds,
                // the URL it leaves empty), not the missing cache file GDAL reports first (web::tileFailure).
                const std::string all = text ? text : "";
                const bool download = line.find("Unable to download block") != std::string::npos;
                if (download) {
                    if (const auto st = all.find("HTTP status code: "); st != std::string::npos)
                        line += " (HTTP " + all.substr(st + 18, all.find_first_not_of("0123456789", st + 18) - st - 18) + ")";
                    if (self->m_failure.find("Unable to download block") == std::string::npos) self->m_failure = line;
                }
                if (self->m_failure.empty()) self->m_failure = line;
            } else if (level == CE_Warning) {
                if (self->m_warning.empty()) self->m_warning = line;
                if (!harmlessWarning(line)) {
                    self->m_dataWarning = true;
                    if (self->m_dataWarningText.empty()) self->m_dataWarningText = line;
                }
            }
        },
        this);
}

ErrorCapture::~ErrorCapture() { CPLPopErrorHandler(); }

Error readFailure(const std::string& file, const ErrorCapture& errors, int y0, int y1, const std::string& why) {
    std::string w = why.empty() ? errors.message() : why;
    // libtiff names row 2^32-1 when a strip fails before its first row is decoded: the rows are said here instead.
    for (const std::string bogus : {" at scanline 4294967295", " at row 4294967295"})
        if (const auto at = w.find(bogus); at != std::string::npos) w.erase(at, bogus.size());
    std::string rows = y0 < 0 ? std::string() : " in row " + std::to_string(y0);
    if (y0 >= 0 && y1 - 1 > y0) rows = " in rows " + std::to_string(y0) + "-" + std::to_string(y1 - 1);
    return fileError(file, "truncated or corrupt image data" + rows + (w.empty() ? std::string() : " (" + w + ")"));
}

Status checkRasterLimits(GDALDataset& ds, const std::string& file) {
    const std::int64_t w = ds.GetRasterXSize(), h = ds.GetRasterYSize(), bands = ds.GetRasterCount();
    if (w > kMaxRasterSide || h > kMaxRasterSide)
        return fileError(file, "declared size " + std::to_string(w) + "x" + std::to_string(h) +
                                   " is over the limit of " + std::to_string(kMaxRasterSide) + " pixels a side");
    if (bands > kMaxRasterBands)
        return fileError(file, "declares " + std::to_string(bands) + " bands, over the limit of " +
                                   std::to_string(kMaxRasterBands));
    int bx = 0, by = 0;
    ds.GetRasterBand(1)->GetBlockSize(&bx, &by);
    bx = std::max(bx, 1);
    by = std::max(by, 1);
    const std::int64_t blocks = ((w + bx - 1) / bx) * ((h + by - 1) / by);
    if (blocks > kMaxRasterBlocks)
        return fileError(file, "declares " + std::to_string(blocks) + " tiles or strips of " + std::to_string(bx) +
                                   "x" + std::to_string(by) + ", over the limit of " + std::to_string(kMaxRasterBlocks));
    const std::int64_t blockBytes = std::int64_t(bx) * by * bands *
                                    std::max(1, GDALGetDataTypeSizeBytes(ds.GetRasterBand(1)->GetRasterDataType()));
    if (blockBytes > kMaxRasterBlockBytes)
        return fileError(file, "declares a tile or strip of " + std::to_string(bx) + "x" + std::to_string(by) + " (" +
                                   std::to_string(blockBytes >> 20) + " MiB decoded), over the limit of " +
                                   std::to_string(kMaxRasterBlockBytes >> 20) + " MiB");
    return Ok{};
}

Result<Dataset> openRaster(const std::filesystem::path& path) {
    init();
    std::error_code ec;
    const bool remote = web::isRemote(path); // a URL (WebSource.h): GDAL asks the server
    if (!remote && !std::filesystem::exists(path, ec)) return fileError(path.string(), "file not found");
    if (!remote && std::filesystem::is_directory(path, ec)) return fileError(path.string(), "is a directory, not an image");
    if (!remote && std::filesystem::is_regular_file(path, ec) && std::filesystem::file_size(path, ec) == 0)
        return fileError(path.string(), "empty file, not an image");
    ErrorCapture errors;
    const web::RemoteOpen quiet(path);
    Dataset ds(GDALDataset::FromHandle(
        GDALOpenEx(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY | GDAL_OF_VERBOSE_ERROR, nullptr, nullptr, nullptr)));
    if (!ds) {
        std::string why = errors.message();
        if (remote) // GDAL names the URL by its /vsicurl/ path: the user gave the URL
            for (size_t at; (at = why.find("/vsicurl/")) != std::string::npos;) why.erase(at, 9);
        return fileError(remote ? web::urlOf(path) : path.string(),
                         "not a readable image" + (why.empty() ? std::string() : " (" + why + ")"));
    }
    if (ds->GetRasterCount() < 1 || ds->GetRasterXSize() < 1 || ds->GetRasterYSize() < 1)
        return fileError(path.string(), "image has no pixels");
    if (auto st = checkRasterLimits(*ds, path.string()); !st) return st.error();
    return ds;
}

std::optional<SampleType> sampleTypeOf(GDALDataType t) {
    switch (t) {
    case GDT_Byte: return SampleType::U8;
    case GDT_UInt16: return SampleType::U16;
    case GDT_Int16: return SampleType::I16;
    case GDT_Float32:
    case GDT_Float64:
    case GDT_Int32:
    case GDT_UInt32:
    case GDT_Int64:
    case GDT_UInt64: return SampleType::F32;
    default: return std::nullopt;
    }
}

GDALDataType gdalTypeOf(SampleType t) {
    switch (t) {
    case SampleType::U8: return GDT_Byte;
    case SampleType::U16: return GDT_UInt16;
    case SampleType::I16: return GDT_Int16;
    case SampleType::F32: return GDT_Float32;
    }
    return GDT_Byte;
}

Status stampGeoreference(const std::filesystem::path& tiff, const Georef& georef, const std::optional<double>& nodata) {
    init();
    ErrorCapture errors;
    const char* drivers[] = {"GTiff", nullptr};
    Dataset ds(GDALDataset::FromHandle(
        GDALOpenEx(tiff.c_str(), GDAL_OF_RASTER | GDAL_OF_UPDATE, drivers, nullptr, nullptr)));
    auto fail = [&](const char* what) {
        const std::string why = errors.message();
        return fileError(tiff.string(), std::string(what) + (why.empty() ? std::string() : " (" + why + ")"));
    };
    if (!ds) return fail("cannot open to write its georeferencing");
    double gt[6] = {georef.origin.x, georef.pixelSize.x, 0.0, georef.origin.y, 0.0, -georef.pixelSize.y};
    OGRSpatialReference srs;
    if (srs.importFromWkt(georef.crs.wkt().c_str()) != OGRERR_NONE) return fail("cannot express its CRS");
    srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    if (ds->SetGeoTransform(gt) != CE_None || ds->SetSpatialRef(&srs) != CE_None)
        return fail("cannot write its georeferencing");
    ds->SetMetadataItem("AREA_OR_POINT", "Area");
    if (nodata)
        for (int b = 1; b <= ds->GetRasterCount(); ++b)
            if (ds->GetRasterBand(b)->SetNoDataValue(*nodata) != CE_None) return fail("cannot write its nodata value");
    GDALDataset* raw = ds.release();
    GDALClose(GDALDataset::ToHandle(raw));
    if (errors.failed()) return fail("cannot write its georeferencing");
    return Ok{};
}

} // namespace seasonview::gdal
