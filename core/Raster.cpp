#include "Raster.h"

#include "GeoTiffStreamWriter.h"
#include "ImageStreamWriter.h"
#include "TiffSupport.h"

#include <OpenImageIO/imageio.h>
#include <geokeys.h>
#include <geotiffio.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <memory>

namespace seasonview {

namespace {

bool isTiffExtension(const std::filesystem::path& p) {
    std::string e = p.extension().string();
    std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return e == ".tif" || e == ".tiff" || e == ".gtif";
}

struct TiffCloser {
    void operator()(TIFF* t) const { TIFFClose(t); }
};
struct GtifCloser {
    void operator()(GTIF* g) const { GTIFFree(g); }
};

// Reads GeoTIFF tags. Returns an empty optional when the file has none; an error for unsupported CRS.
Result<std::optional<Georef>> readGeoTags(const std::filesystem::path& path, std::optional<double>& nodata) {
    std::string tiffError;
    std::unique_ptr<TIFF, TiffCloser> tif(tiff::open(path, "rm", &tiffError)); // tags only: no memory map
    if (!tif) return std::optional<Georef>{};
    char* nodataText = nullptr;
    if (TIFFGetField(tif.get(), tiff::kTagGdalNodata, &nodataText) && nodataText) {
        char* end = nullptr;
        double v = std::strtod(nodataText, &end);
        if (end != nodataText) nodata = v;
    }
    std::uint16_t n = 0;
    double* scale = nullptr;
    double* tie = nullptr;
    double* matrix = nullptr;
    bool hasScale = TIFFGetField(tif.get(), TIFFTAG_GEOPIXELSCALE, &n, &scale) && n >= 2;
    std::uint16_t nt = 0;
    bool hasTie = TIFFGetField(tif.get(), TIFFTAG_GEOTIEPOINTS, &nt, &tie) && nt >= 6;
    std::uint16_t nm = 0;
    bool hasMatrix = TIFFGetField(tif.get(), TIFFTAG_GEOTRANSMATRIX, &nm, &matrix) && nm >= 16;
    if (!((hasScale && hasTie) || hasMatrix)) return std::optional<Georef>{};

    std::unique_ptr<GTIF, GtifCloser> gt(GTIFNew(tif.get()));
    if (!gt) return fileError(path.string(), "unreadable GeoTIFF key directory");
    unsigned short modelType = 0, rasterType = RasterPixelIsArea, code = 0;
    GTIFKeyGet(gt.get(), GTModelTypeGeoKey, &modelType, 0, 1);
    GTIFKeyGet(gt.get(), GTRasterTypeGeoKey, &rasterType, 0, 1);
    int epsg = 0;
    if (modelType == ModelTypeProjected) {
        if (GTIFKeyGet(gt.get(), ProjectedCSTypeGeoKey, &code, 0, 1)) epsg = code;
    } else if (modelType == ModelTypeGeographic) {
        if (GTIFKeyGet(gt.get(), GeographicTypeGeoKey, &code, 0, 1)) epsg = code;
        else epsg = 4326; // geographic without a datum code: assume WGS84
    }
    if (epsg == 0 || epsg == KvUserDefined)
        return fileError(path.string(), "unknown CRS (no EPSG code in the GeoTIFF keys; reproject to UTM or EPSG:4326)");
    Result<Crs> crs = Crs::fromEpsg(epsg);
    if (!crs) return fileError(path.string(), crs.message());

    Georef g;
    g.crs = *crs;
    if (hasScale && hasTie) {
        g.pixelSize = {scale[0], scale[1]};
        g.origin = {tie[3] - tie[0] * scale[0], tie[4] + tie[1] * scale[1]};
    } else {
        if (matrix[1] != 0.0 || matrix[4] != 0.0)
            return fileError(path.string(), "rotated or sheared rasters are not supported");
        g.pixelSize = {matrix[0], -matrix[5]};
        g.origin = {matrix[3], matrix[7]};
    }
    if (!(g.pixelSize.x > 0.0) || !(g.pixelSize.y > 0.0) || !std::isfinite(g.origin.x) || !std::isfinite(g.origin.y))
        return fileError(path.string(), "invalid georeferencing (pixel size must be positive, north-up)");
    if (rasterType == RasterPixelIsPoint) { // tiepoint names the pixel centre
        g.origin.x -= 0.5 * g.pixelSize.x;
        g.origin.y += 0.5 * g.pixelSize.y;
    }
    return std::optional<Georef>{g};
}

std::string oiioOpenError(const std::filesystem::path& path) {
    std::string e = firstLine(OIIO::geterror());
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) return "file not found";
    if (std::filesystem::is_directory(path, ec)) return "is a directory, not an image";
    if (std::filesystem::file_size(path, ec) == 0) return "empty file, not an image";
    return "not a readable image" + (e.empty() ? std::string() : " (" + e + ")");
}

template <typename T>
Result<Image<T>> readPixels(const std::filesystem::path& path, int maxChannels, OIIO::TypeDesc want) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) return fileError(path.string(), "file not found");
    auto in = OIIO::ImageInput::open(path.string());
    if (!in) return fileError(path.string(), oiioOpenError(path));
    const OIIO::ImageSpec& spec = in->spec();
    Image<T> img;
    img.width = spec.width;
    img.height = spec.height;
    img.channels = std::min(spec.nchannels, maxChannels);
    if (img.width <= 0 || img.height <= 0 || img.channels <= 0) return fileError(path.string(), "image has no pixels");
    img.pixels.resize(size_t(img.width) * size_t(img.height) * size_t(img.channels));
    bool ok = false;
    if (want == OIIO::TypeDesc::FLOAT && spec.format != OIIO::TypeDesc::FLOAT) {
        // OpenImageIO normalises integers when converting to float; heights need the raw values, so read the
        // native type and cast.
        const OIIO::TypeDesc native = spec.format;
        std::vector<std::uint8_t> raw(img.pixels.size() * native.size());
        ok = in->read_image(0, 0, 0, img.channels, native, raw.data());
        if (ok) {
            auto cast = [&](auto tag) {
                using S = decltype(tag);
                const S* p = reinterpret_cast<const S*>(raw.data());
                for (size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = T(p[i]);
            };
            switch (native.basetype) {
            case OIIO::TypeDesc::INT16: cast(std::int16_t{}); break;
            case OIIO::TypeDesc::UINT16: cast(std::uint16_t{}); break;
            case OIIO::TypeDesc::UINT8: cast(std::uint8_t{}); break;
            case OIIO::TypeDesc::INT8: cast(std::int8_t{}); break;
            case OIIO::TypeDesc::INT32: cast(std::int32_t{}); break;
            case OIIO::TypeDesc::UINT32: cast(std::uint32_t{}); break;
            case OIIO::TypeDesc::DOUBLE: cast(double{}); break;
            default: return fileError(path.string(), std::string("unsupported sample type ") + native.c_str());
            }
        }
    } else {
        ok = in->read_image(0, 0, 0, img.channels, want, img.pixels.data());
    }
    if (!ok) {
        std::string e = firstLine(in->geterror());
        return fileError(path.string(), "truncated or corrupt image data" + (e.empty() ? std::string() : " (" + e + ")"));
    }
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

Result<RasterInfo> readRasterInfo(const std::filesystem::path& path) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) return fileError(path.string(), "file not found");
    auto in = OIIO::ImageInput::open(path.string());
    if (!in) return fileError(path.string(), oiioOpenError(path));
    const OIIO::ImageSpec& spec = in->spec();
    RasterInfo info;
    info.path = path;
    info.width = spec.width;
    info.height = spec.height;
    info.channels = spec.nchannels;
    info.tiled = spec.tile_width > 0;
    switch (spec.format.basetype) {
    case OIIO::TypeDesc::UINT8: info.type = SampleType::U8; break;
    case OIIO::TypeDesc::UINT16: info.type = SampleType::U16; break;
    case OIIO::TypeDesc::INT16: info.type = SampleType::I16; break;
    case OIIO::TypeDesc::FLOAT: info.type = SampleType::F32; break;
    default:
        return fileError(path.string(), std::string("unsupported sample type ") + spec.format.c_str() +
                                            " (seasonview reads uint8, uint16, int16 and float32)");
    }
    if (info.width <= 0 || info.height <= 0) return fileError(path.string(), "image has no pixels");
    if (isTiffExtension(path) || in->format_name() == std::string("tiff")) {
        auto geo = readGeoTags(path, info.nodata);
        if (!geo) return geo.error();
        info.georef = *geo;
    }
    return info;
}

Result<Image<std::uint8_t>> readImageU8(const std::filesystem::path& path, int maxChannels) {
    return readPixels<std::uint8_t>(path, maxChannels, OIIO::TypeDesc::UINT8);
}
Result<Image<std::uint16_t>> readImageU16(const std::filesystem::path& path, int maxChannels) {
    return readPixels<std::uint16_t>(path, maxChannels, OIIO::TypeDesc::UINT16);
}
Result<Image<float>> readImageF32(const std::filesystem::path& path, int maxChannels) {
    return readPixels<float>(path, maxChannels, OIIO::TypeDesc::FLOAT);
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
