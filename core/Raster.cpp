#include "Raster.h"

#include "AtomicFile.h"

#include <OpenImageIO/imageio.h>
#include <geokeys.h>
#include <geotiffio.h>
#include <xtiffio.h>

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstring>
#include <mutex>

namespace seasonview {

namespace {

constexpr ttag_t kTagGdalNodata = 42113;

thread_local std::string t_tiffError;

void tiffErrorHandler(const char* module, const char* fmt, va_list ap) {
    char buf[512];
    std::vsnprintf(buf, sizeof buf, fmt, ap);
    t_tiffError = (module ? std::string(module) + ": " : std::string()) + buf;
}
void tiffWarningHandler(const char*, const char*, va_list) {} // unknown private tags etc.: not the user's problem

TIFFExtendProc g_parentExtender = nullptr;
void gdalTagExtender(TIFF* tif) {
    static const TIFFFieldInfo info[] = {
        {kTagGdalNodata, -1, -1, TIFF_ASCII, FIELD_CUSTOM, 1, 0, const_cast<char*>("GDALNoDataValue")}};
    TIFFMergeFieldInfo(tif, info, 1);
    if (g_parentExtender) g_parentExtender(tif);
}

void initTiff() {
    static std::once_flag once;
    std::call_once(once, [] {
        TIFFSetErrorHandler(tiffErrorHandler);
        TIFFSetWarningHandler(tiffWarningHandler);
        XTIFFInitialize(); // registers the GeoTIFF tags
        g_parentExtender = TIFFSetTagExtender(gdalTagExtender);
    });
}

std::string firstLine(std::string s) {
    auto nl = s.find('\n');
    if (nl != std::string::npos) s.resize(nl);
    while (!s.empty() && (s.back() == ' ' || s.back() == '.')) s.pop_back();
    return s;
}

bool isTiffExtension(const std::filesystem::path& p) {
    std::string e = p.extension().string();
    std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return e == ".tif" || e == ".tiff" || e == ".gtif";
}

struct TiffCloser {
    void operator()(TIFF* t) const { XTIFFClose(t); }
};
struct GtifCloser {
    void operator()(GTIF* g) const { GTIFFree(g); }
};

// Reads GeoTIFF tags. Returns an empty optional when the file has none; an error for unsupported CRS.
Result<std::optional<Georef>> readGeoTags(const std::filesystem::path& path, std::optional<double>& nodata) {
    initTiff();
    std::unique_ptr<TIFF, TiffCloser> tif(XTIFFOpen(path.c_str(), "r"));
    if (!tif) return std::optional<Georef>{};
    char* nodataText = nullptr;
    if (TIFFGetField(tif.get(), kTagGdalNodata, &nodataText) && nodataText) {
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

Status writeGeoTiff(const std::filesystem::path& path, const void* data, SampleType type, int width, int height,
                    int channels, const Georef& georef, const GeoTiffWriteOptions& options) {
    assert(width > 0 && height > 0 && channels > 0 && "writeGeoTiff(): empty raster");
    initTiff();
    const int bytesPerSample = type == SampleType::U8 ? 1 : type == SampleType::F32 ? 4 : 2;
    const std::uint64_t rawBytes = std::uint64_t(width) * std::uint64_t(height) * std::uint64_t(channels) *
                                   std::uint64_t(bytesPerSample);
    std::filesystem::path tmp = temporaryPathFor(path);
    t_tiffError.clear();
    // BigTIFF past 2 GB of raw samples: deflate may not shrink noisy imagery below the classic 4 GB limit.
    TIFF* tif = XTIFFOpen(tmp.c_str(), rawBytes > (std::uint64_t(2) << 30) ? "w8" : "w");
    if (!tif) return fileError(path.string(), "cannot create file (" + t_tiffError + ")");
    auto fail = [&](const std::string& what) {
        XTIFFClose(tif);
        discardTemporary(tmp);
        return fileError(path.string(), what + (t_tiffError.empty() ? "" : " (" + t_tiffError + ")"));
    };
    TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, std::uint32_t(width));
    TIFFSetField(tif, TIFFTAG_IMAGELENGTH, std::uint32_t(height));
    TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, std::uint16_t(channels));
    TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, std::uint16_t(bytesPerSample * 8));
    TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT,
                 type == SampleType::F32 ? SAMPLEFORMAT_IEEEFP : type == SampleType::I16 ? SAMPLEFORMAT_INT
                                                                                          : SAMPLEFORMAT_UINT);
    TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
    TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, channels >= 3 ? PHOTOMETRIC_RGB : PHOTOMETRIC_MINISBLACK);
    if (channels == 4 || channels == 2) {
        std::uint16_t extra = EXTRASAMPLE_UNASSALPHA;
        TIFFSetField(tif, TIFFTAG_EXTRASAMPLES, std::uint16_t(1), &extra);
    }
    TIFFSetField(tif, TIFFTAG_COMPRESSION, COMPRESSION_ADOBE_DEFLATE);
    TIFFSetField(tif, TIFFTAG_ZIPQUALITY, std::clamp(options.deflateLevel, 1, 9));
    TIFFSetField(tif, TIFFTAG_PREDICTOR, type == SampleType::F32 ? PREDICTOR_FLOATINGPOINT : PREDICTOR_HORIZONTAL);
    if (options.nodata) {
        char text[64];
        std::snprintf(text, sizeof text, "%.17g", *options.nodata);
        TIFFSetField(tif, kTagGdalNodata, text);
    }
    double scale[3] = {georef.pixelSize.x, georef.pixelSize.y, 0.0};
    double tie[6] = {0.0, 0.0, 0.0, georef.origin.x, georef.origin.y, 0.0};
    TIFFSetField(tif, TIFFTAG_GEOPIXELSCALE, 3, scale);
    TIFFSetField(tif, TIFFTAG_GEOTIEPOINTS, 6, tie);
    GTIF* gt = GTIFNew(tif);
    if (!gt) return fail("cannot write GeoTIFF keys");
    GTIFKeySet(gt, GTModelTypeGeoKey, TYPE_SHORT, 1, georef.crs.isGeographic() ? ModelTypeGeographic : ModelTypeProjected);
    GTIFKeySet(gt, GTRasterTypeGeoKey, TYPE_SHORT, 1, RasterPixelIsArea);
    if (georef.crs.isGeographic()) GTIFKeySet(gt, GeographicTypeGeoKey, TYPE_SHORT, 1, georef.crs.epsg);
    else GTIFKeySet(gt, ProjectedCSTypeGeoKey, TYPE_SHORT, 1, georef.crs.epsg);
    GTIFWriteKeys(gt);
    GTIFFree(gt);

    const auto* src = static_cast<const std::uint8_t*>(data);
    const size_t pixelBytes = size_t(channels) * size_t(bytesPerSample);
    if (options.tileSize > 0) {
        const int ts = options.tileSize;
        TIFFSetField(tif, TIFFTAG_TILEWIDTH, std::uint32_t(ts));
        TIFFSetField(tif, TIFFTAG_TILELENGTH, std::uint32_t(ts));
        std::vector<std::uint8_t> tile(size_t(ts) * size_t(ts) * pixelBytes);
        for (int ty = 0; ty < height; ty += ts)
            for (int tx = 0; tx < width; tx += ts) {
                std::fill(tile.begin(), tile.end(), std::uint8_t(0));
                const int w = std::min(ts, width - tx), h = std::min(ts, height - ty);
                for (int y = 0; y < h; ++y)
                    std::memcpy(&tile[size_t(y) * size_t(ts) * pixelBytes],
                                src + (size_t(ty + y) * size_t(width) + size_t(tx)) * pixelBytes, size_t(w) * pixelBytes);
                if (TIFFWriteEncodedTile(tif, TIFFComputeTile(tif, std::uint32_t(tx), std::uint32_t(ty), 0, 0),
                                         tile.data(), tmsize_t(tile.size())) < 0)
                    return fail("write failed");
            }
    } else {
        TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, std::uint32_t(16));
        // libtiff's predictor works in place: hand it a copy, never the caller's const buffer.
        std::vector<std::uint8_t> row(size_t(width) * pixelBytes);
        for (int y = 0; y < height; ++y) {
            std::memcpy(row.data(), src + size_t(y) * size_t(width) * pixelBytes, row.size());
            if (TIFFWriteScanline(tif, row.data(), std::uint32_t(y), 0) < 0) return fail("write failed");
        }
    }
    if (!TIFFWriteDirectory(tif)) return fail("write failed");
    XTIFFClose(tif);
    std::string err;
    if (!commitTemporary(tmp, path, err)) return fileError(path.string(), err);
    return Ok{};
}

Status writeImageAtomic(const std::filesystem::path& path, const std::uint8_t* data, int width, int height, int channels) {
    std::filesystem::path tmp = temporaryPathFor(path);
    auto out = OIIO::ImageOutput::create(path.string());
    if (!out) return fileError(path.string(), "unsupported output image format (use .png or .tif)");
    OIIO::ImageSpec spec(width, height, channels, OIIO::TypeDesc::UINT8);
    if (!out->open(tmp.string(), spec)) {
        std::string e = firstLine(out->geterror());
        return fileError(path.string(), "cannot create file" + (e.empty() ? std::string() : " (" + e + ")"));
    }
    if (!out->write_image(OIIO::TypeDesc::UINT8, data) || !out->close()) {
        std::string e = firstLine(out->geterror());
        out.reset();
        discardTemporary(tmp);
        return fileError(path.string(), "write failed" + (e.empty() ? std::string() : " (" + e + ")"));
    }
    out.reset();
    std::string err;
    if (!commitTemporary(tmp, path, err)) return fileError(path.string(), err);
    return Ok{};
}

} // namespace seasonview
