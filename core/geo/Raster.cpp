#include "Raster.h"

#include "GdalSupport.h"
#include "GeoTiffStreamWriter.h"
#include "ImageStreamWriter.h"
#include "TiffSupport.h"

#include <ogr_spatialref.h>

#include <algorithm>
#include <cmath>

namespace seasonview {

namespace {

/// The georeferencing GDAL reads (GeoTIFF keys, world files, .prj, VRT, JP2 boxes, ...): a north-up affine grid.
/// Sets info.georef, or geotransformWithoutCrs; errors for rotated/sheared or degenerate grids.
Status readGeoreference(GDALDataset& ds, const std::filesystem::path& path, const std::optional<Crs>& assumedCrs,
                        RasterInfo& info) {
    double gt[6] = {0, 1, 0, 0, 0, 1};
    const bool hasTransform = ds.GetGeoTransform(gt) == CE_None;
    const OGRSpatialReference* srs = ds.GetSpatialRef();
    if (!hasTransform) return Ok{}; // a plain image (PNG mask, photo)
    if (gt[2] != 0.0 || gt[4] != 0.0) return fileError(path.string(), "rotated or sheared rasters are not supported");
    Georef g;
    g.pixelSize = {gt[1], -gt[5]};
    g.origin = {gt[0], gt[3]};
    if (!(g.pixelSize.x > 0.0) || !(g.pixelSize.y > 0.0) || !std::isfinite(g.origin.x) || !std::isfinite(g.origin.y))
        return fileError(path.string(), "invalid georeferencing (pixel size must be positive, north-up)");
    if (srs && !srs->IsEmpty()) {
        char* wkt = nullptr;
        const char* options[] = {"FORMAT=WKT2_2019", nullptr};
        srs->exportToWkt(&wkt, options);
        auto crs = Crs::fromWkt(wkt ? wkt : "");
        CPLFree(wkt);
        if (!crs) return fileError(path.string(), "unsupported CRS (" + crs.message() + ")");
        g.crs = *crs;
    } else if (assumedCrs) {
        g.crs = *assumedCrs;
    } else {
        info.geotransformWithoutCrs = true;
        return Ok{};
    }
    info.georef = g;
    return Ok{};
}

template <typename T>
Result<Image<T>> readPixels(const std::filesystem::path& path, int maxChannels, SampleType want) {
    auto ds = gdal::openRaster(path);
    if (!ds) return ds.error();
    Image<T> img;
    img.width = (*ds)->GetRasterXSize();
    img.height = (*ds)->GetRasterYSize();
    img.channels = std::min((*ds)->GetRasterCount(), maxChannels);
    const std::uint64_t bytes = std::uint64_t(img.width) * std::uint64_t(img.height) * std::uint64_t(img.channels) *
                                sizeof(T);
    if (bytes > kMaxWholeImageBytes)
        return fileError(path.string(), std::to_string(img.width) + "x" + std::to_string(img.height) +
                                            " pixels are too many to hold whole (" + std::to_string(bytes >> 20) +
                                            " MiB; the limit is " + std::to_string(kMaxWholeImageBytes >> 20) + " MiB)");
    img.pixels.resize(size_t(img.width) * size_t(img.height) * size_t(img.channels));
    std::vector<int> bands(size_t(img.channels));
    for (int b = 0; b < img.channels; ++b) bands[size_t(b)] = b + 1;
    gdal::ErrorCapture errors;
    const GSpacing pixel = GSpacing(sizeof(T)) * img.channels;
    const CPLErr err = (*ds)->RasterIO(GF_Read, 0, 0, img.width, img.height, img.pixels.data(), img.width, img.height,
                                       gdal::gdalTypeOf(want), img.channels, bands.data(), pixel,
                                       pixel * img.width, GSpacing(sizeof(T)), nullptr);
    // A warning during a read is lost data too (libtiff reports some short reads as warnings).
    if (err != CE_None || errors.lostData()) return gdal::readFailure(path.string(), errors, 0, img.height);
    return img;
}

} // namespace

const char* sampleTypeName(SampleType t) {
    switch (t) {
    case SampleType::U8: return "uint8";
    case SampleType::U16: return "uint16";
    case SampleType::I16: return "int16";
    case SampleType::F32: return "float32";
    }
    return "?";
}

Result<RasterInfo> readRasterInfo(const std::filesystem::path& path, const std::optional<Crs>& assumedCrs) {
    auto opened = gdal::openRaster(path);
    if (!opened) return opened.error();
    GDALDataset& ds = **opened;
    RasterInfo info;
    info.path = path;
    info.width = ds.GetRasterXSize();
    info.height = ds.GetRasterYSize();
    info.channels = ds.GetRasterCount();
    info.driver = ds.GetDriver() ? ds.GetDriver()->GetDescription() : "";
    GDALRasterBand* first = ds.GetRasterBand(1);
    const auto type = gdal::sampleTypeOf(first->GetRasterDataType());
    if (!type)
        return fileError(path.string(), std::string("unsupported sample type ") +
                                            GDALGetDataTypeName(first->GetRasterDataType()) +
                                            " (seasonview reads integer and floating-point bands)");
    info.type = *type;
    if (info.driver == "GTiff") {
        std::string error;
        if (TIFF* t = tiff::open(path, "rm", &error)) {
            info.tiled = TIFFIsTiled(t) != 0;
            TIFFClose(t);
        }
    } else {
        int bx = 0, by = 0;
        first->GetBlockSize(&bx, &by);
        info.tiled = by > 1 && bx < info.width;
    }
    for (int b = 1; b <= info.channels; ++b)
        if (ds.GetRasterBand(b)->GetColorInterpretation() == GCI_AlphaBand) info.alphaBand = b;
    int hasNodata = 0;
    const double nodata = first->GetNoDataValue(&hasNodata);
    if (hasNodata) info.nodata = nodata;
    const int flags = first->GetMaskFlags();
    info.nodataKind = (flags & GMF_ALL_VALID) ? NodataKind::None
                      : (flags & GMF_NODATA)  ? NodataKind::Value
                      : (flags & GMF_ALPHA) || info.alphaBand ? NodataKind::Alpha
                                                              : NodataKind::Mask;
    if (info.alphaBand && info.nodataKind == NodataKind::None) info.nodataKind = NodataKind::Alpha;
    if (auto st = readGeoreference(ds, path, assumedCrs, info); !st) return st.error();
    return info;
}

Result<Image<std::uint8_t>> readImageU8(const std::filesystem::path& path, int maxChannels) {
    return readPixels<std::uint8_t>(path, maxChannels, SampleType::U8);
}
Result<Image<std::uint16_t>> readImageU16(const std::filesystem::path& path, int maxChannels) {
    return readPixels<std::uint16_t>(path, maxChannels, SampleType::U16);
}
Result<Image<float>> readImageF32(const std::filesystem::path& path, int maxChannels) {
    return readPixels<float>(path, maxChannels, SampleType::F32);
}

const char* tiffCompressionName(TiffCompression c) {
    switch (c) {
    case TiffCompression::Deflate: return "deflate";
    case TiffCompression::Zstd: return "zstd";
    case TiffCompression::Jpeg: return "jpeg";
    }
    return "?";
}

Status writeGeoTiff(const std::filesystem::path& path, const void* data, SampleType type, int width, int height,
                    int channels, const Georef& georef, const GeoTiffWriteOptions& options) {
    assert(width > 0 && height > 0 && channels > 0 && "writeGeoTiff(): empty raster");
    auto writer = GeoTiffStreamWriter::open(path, width, height, channels, type, georef, options);
    if (!writer) return writer.error();
    if (auto st = writer->writeRows(0, height, data); !st) return st;
    return writer->finish();
}

Status writeImageAtomic(const std::filesystem::path& path, const std::uint8_t* data, int width, int height, int channels) {
    auto writer = ImageStreamWriter::open(path, width, height, channels);
    if (!writer) return writer.error();
    if (auto st = writer->writeRows(0, height, data); !st) return st;
    return writer->finish();
}

} // namespace seasonview
