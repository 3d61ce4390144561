#include "BandReader.h"

#include "GdalSupport.h"
#include "JpegSupport.h"
#include "ParallelIndices.h"
#include "TiffSupport.h"
#include "WebSource.h"

#include <libdeflate.h>
#include <zstd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <string>
#include <thread>

namespace seasonview {

namespace {

struct DecompressorDeleter {
    void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
    void operator()(ZSTD_DCtx* d) const { ZSTD_freeDCtx(d); }
};

// The TIFF horizontal predictor undone on the first `bytes` bytes of a row (a prefix sum per channel, so a row may
// be cut after the columns that are needed), 8- or 16-bit samples in native byte order.
void undoPredictor8(std::uint8_t* row, size_t bytes, size_t stride) {
    for (size_t k = stride; k < bytes; ++k) row[k] = std::uint8_t(row[k] + row[k - stride]);
}

void undoPredictor16(std::uint8_t* row, size_t bytes, size_t stride) {
    const size_t n = bytes / 2;
    for (size_t k = stride; k < n; ++k) {
        std::uint16_t a, b;
        std::memcpy(&a, row + 2 * k, 2);
        std::memcpy(&b, row + 2 * (k - stride), 2);
        a = std::uint16_t(a + b);
        std::memcpy(row + 2 * k, &a, 2);
    }
}

// The same for 8-bit RGB, written to `dst`: the three running sums stay in registers, three times faster than the
// loop above, whose every byte waits for the store of the byte three before it.
void undoPredictorRgb8(const std::uint8_t* src, std::uint8_t* dst, size_t pixels) {
    std::uint8_t r = 0, g = 0, b = 0;
    for (size_t i = 0; i < pixels; ++i, src += 3, dst += 3) {
        r = std::uint8_t(r + src[0]);
        g = std::uint8_t(g + src[1]);
        b = std::uint8_t(b + src[2]);
        dst[0] = r;
        dst[1] = g;
        dst[2] = b;
    }
}

/// A libjpeg decompressor, one per decoding thread.
struct JpegDecoder {
    jpeg_decompress_struct cinfo{};
    jpeg::ErrorManager error;
    bool created = false;
    JpegDecoder() {
        error.install(cinfo);
        if (setjmp(error.jump)) return;
        jpeg_create_decompress(&cinfo);
        created = true;
    }
    ~JpegDecoder() { jpeg_destroy_decompress(&cinfo); } // safe on a partly created object
    JpegDecoder(const JpegDecoder&) = delete;
    JpegDecoder& operator=(const JpegDecoder&) = delete;
};

/// One JPEG tile or strip of a TIFF (an abbreviated stream whose tables are the JPEGTABLES tag, or a complete one)
/// into exactly width × height × components bytes, as libtiff's JPEG codec (tif_jpeg.c) decodes it with
/// JPEGCOLORMODE_RGB, GDAL's way: YCbCr converted to RGB with libjpeg's default upsampling and IDCT, other
/// photometrics' components as they are. Like libtiff it tolerates libjpeg's warnings (extraneous bytes, a missing
/// end marker) and crops a strip coded taller than the rows it holds. False on a libjpeg error, or when the stream's
/// width, components or height (less than the block's) do not fit; `error.message` says what libjpeg said.
bool decodeJpeg(JpegDecoder& d, const std::vector<std::uint8_t>& tables, const std::vector<std::uint8_t>& data,
                std::uint8_t* out, int width, int height, int components, bool ycbcr) {
    jpeg_decompress_struct& c = d.cinfo;
    if (!d.created) return false;
    if (setjmp(d.error.jump)) {
        jpeg_abort_decompress(&c);
        return false;
    }
    if (!tables.empty()) {
        jpeg_mem_src(&c, tables.data(), static_cast<unsigned long>(tables.size()));
        if (jpeg_read_header(&c, FALSE) != JPEG_HEADER_TABLES_ONLY) {
            jpeg_abort_decompress(&c);
            return false;
        }
    }
    jpeg_mem_src(&c, data.data(), static_cast<unsigned long>(data.size()));
    if (jpeg_read_header(&c, TRUE) != JPEG_HEADER_OK || int(c.image_width) != width || int(c.image_height) < height ||
        c.num_components != components) {
        std::snprintf(d.error.message, sizeof d.error.message, "JPEG stream of %ux%u, %d components in a %dx%d block",
                      c.image_width, c.image_height, c.num_components, width, height);
        jpeg_abort_decompress(&c);
        return false;
    }
    c.jpeg_color_space = ycbcr ? JCS_YCbCr : JCS_UNKNOWN;
    c.out_color_space = ycbcr ? JCS_RGB : JCS_UNKNOWN;
    jpeg_start_decompress(&c);
    if (c.output_components != components || int(c.output_width) != width) {
        jpeg_abort_decompress(&c);
        return false;
    }
    const size_t rowBytes = size_t(width) * size_t(components);
    while (int(c.output_scanline) < height) {
        JSAMPROW row = out + size_t(c.output_scanline) * rowBytes;
        if (jpeg_read_scanlines(&c, &row, 1) != 1) {
            jpeg_abort_decompress(&c);
            return false;
        }
    }
    if (c.output_scanline < c.output_height) jpeg_abort_decompress(&c); // a taller strip: the rest is not ours
    else jpeg_finish_decompress(&c);
    return true;
}

} // namespace

// Deflate, Zstandard and JPEG TIFFs, the kinds GeoTiffStreamWriter writes and most GeoTIFFs and orthophotos are,
// decoded here rather than by GDAL: the compressed tiles (or strips) of a band are read raw through libtiff and
// decoded on all cores, deflate by libdeflate (about twice as fast as zlib), Zstandard by libzstd, JPEG by libjpeg as
// libtiff's codec decodes it for GDAL (YCbCr to RGB). Only layouts where the result is certain to equal GDAL's:
// unsigned 8/16-bit, contiguous RGB or grey with any extra samples (alpha is read raw, as GDAL does; JPEG: 8-bit
// YCbCr, RGB or grey), native byte order, predictor none or horizontal. Anything else, and any tile that does not
// decode, goes to GDAL.
struct RawTiff {
    TIFF* tif = nullptr;
    std::string error;                // libtiff's last message about this file
    bool tiled = false;
    int blockWidth = 0, blockHeight = 0; // a tile, or a strip (full width, rows per strip)
    int samples = 0, sampleBytes = 1, predictor = 1, threads = 1;
    bool zstd = false, jpeg = false;     // else deflate
    bool ycbcr = false;                  // JPEG: YCbCr converted to RGB
    std::vector<std::uint8_t> jpegTables; // JPEG: the JPEGTABLES tag (quantisation and Huffman tables)
    std::vector<std::vector<std::uint8_t>> compressed;                                   // blocks of a block row
    std::vector<std::vector<std::uint8_t>> scratch;                                      // per thread
    std::vector<std::unique_ptr<libdeflate_decompressor, DecompressorDeleter>> inflaters; // per thread (deflate)
    std::vector<std::unique_ptr<ZSTD_DCtx, DecompressorDeleter>> zstdContexts;            // per thread (zstd)
    std::vector<std::unique_ptr<JpegDecoder>> jpegDecoders;                              // per thread (JPEG)
    std::string failure; // what libjpeg said of the last block that did not decode, or why it could not be read
    // The last read found a block damaged (past the end of the file, cut short, or failing its decoder's checks):
    // final, not handed to GDAL. The own decoder only takes layouts it decodes as GDAL does, so its refusal is the
    // data's fault, and its words (which tile, which check) are the ones to report.
    bool damaged = false;
    std::uint64_t fileBytes = 0; // the file's size: no block may claim bytes past it
    ~RawTiff() {
        if (tif) TIFFClose(tif);
    }

    /// Opens `path` when its layout qualifies (width × height as GDAL saw it), else null.
    static std::unique_ptr<RawTiff> open(const std::filesystem::path& path, int width, int height,
                                                int maxStripRows) {
        auto r = std::make_unique<RawTiff>();
        // "m": read tiles with pread, not through a memory map of the file: mapped pages count in RSS (a
        // 65536² pair's prepare showed 16.6 GB peak RSS, 15 GB of it the two mapped inputs), which is
        // alarming to users and to memory accounting although the kernel could drop them.
        r->tif = tiff::open(path, "rm", &r->error);
        if (!r->tif) return nullptr;
        std::error_code ec;
        r->fileBytes = std::filesystem::file_size(path, ec);
        TIFF* t = r->tif;
        std::uint32_t w = 0, h = 0;
        std::uint16_t compression = 0, planar = PLANARCONFIG_CONTIG, bits = 0, format = SAMPLEFORMAT_UINT,
                      photometric = 0, spp = 0, predictor = PREDICTOR_NONE, extraCount = 0;
        std::uint16_t* extra = nullptr;
        TIFFGetField(t, TIFFTAG_IMAGEWIDTH, &w);
        TIFFGetField(t, TIFFTAG_IMAGELENGTH, &h);
        TIFFGetField(t, TIFFTAG_COMPRESSION, &compression);
        TIFFGetFieldDefaulted(t, TIFFTAG_PLANARCONFIG, &planar);
        TIFFGetFieldDefaulted(t, TIFFTAG_BITSPERSAMPLE, &bits);
        TIFFGetFieldDefaulted(t, TIFFTAG_SAMPLEFORMAT, &format);
        TIFFGetField(t, TIFFTAG_PHOTOMETRIC, &photometric);
        TIFFGetFieldDefaulted(t, TIFFTAG_SAMPLESPERPIXEL, &spp);
        TIFFGetFieldDefaulted(t, TIFFTAG_PREDICTOR, &predictor);
        TIFFGetFieldDefaulted(t, TIFFTAG_EXTRASAMPLES, &extraCount, &extra);
        const bool deflate = compression == COMPRESSION_ADOBE_DEFLATE || compression == COMPRESSION_DEFLATE;
        r->zstd = compression == COMPRESSION_ZSTD;
        r->jpeg = compression == COMPRESSION_JPEG;
        r->ycbcr = r->jpeg && photometric == PHOTOMETRIC_YCBCR && spp == 3;
        const bool colours = (photometric == PHOTOMETRIC_RGB && spp >= 3) ||
                             (photometric == PHOTOMETRIC_MINISBLACK && spp >= 1) || r->ycbcr;
        if (r->jpeg) {
            // 8-bit YCbCr (what orthophotos use), RGB or grey; the tables shared by every tile. The JPEG codec has no
            // predictor tag.
            const bool layout = r->ycbcr || (photometric == PHOTOMETRIC_RGB && spp == 3) ||
                                (photometric == PHOTOMETRIC_MINISBLACK && spp == 1);
            if (!layout || bits != 8 || extraCount > 0) return nullptr;
            predictor = PREDICTOR_NONE;
            std::uint32_t count = 0;
            void* tables = nullptr;
            if (TIFFGetField(t, TIFFTAG_JPEGTABLES, &count, &tables) && tables && count > 0)
                r->jpegTables.assign(static_cast<std::uint8_t*>(tables), static_cast<std::uint8_t*>(tables) + count);
        }
        if (int(w) != width || int(h) != height || !(deflate || r->zstd || r->jpeg) || planar != PLANARCONFIG_CONTIG ||
            !colours || (bits != 8 && bits != 16) || format != SAMPLEFORMAT_UINT ||
            (bits == 16 && TIFFIsByteSwapped(t)) || (predictor != PREDICTOR_NONE && predictor != PREDICTOR_HORIZONTAL))
            return nullptr;
        r->tiled = TIFFIsTiled(t) != 0;
        if (r->tiled) {
            std::uint32_t tw = 0, th = 0;
            TIFFGetField(t, TIFFTAG_TILEWIDTH, &tw);
            TIFFGetField(t, TIFFTAG_TILELENGTH, &th);
            r->blockWidth = int(tw);
            r->blockHeight = int(th);
        } else {
            std::uint32_t rps = 0;
            TIFFGetFieldDefaulted(t, TIFFTAG_ROWSPERSTRIP, &rps);
            r->blockWidth = width;
            r->blockHeight = int(std::min<std::uint32_t>(rps, std::uint32_t(height)));
            if (r->blockHeight > maxStripRows) return nullptr; // huge strips: a band could not stay small
        }
        if (r->blockWidth <= 0 || r->blockHeight <= 0) return nullptr;
        r->samples = spp;
        r->sampleBytes = bits / 8;
        r->predictor = predictor;
        r->threads = std::max(1, int(std::thread::hardware_concurrency()));
        for (int i = 0; i < r->threads; ++i) {
            if (r->jpeg) {
                r->jpegDecoders.push_back(std::make_unique<JpegDecoder>());
                if (!r->jpegDecoders.back()->created) return nullptr;
            } else if (r->zstd) {
                r->zstdContexts.emplace_back(ZSTD_createDCtx());
                if (!r->zstdContexts.back()) return nullptr;
            } else {
                r->inflaters.emplace_back(libdeflate_alloc_decompressor());
                if (!r->inflaters.back()) return nullptr;
            }
            r->scratch.emplace_back();
        }
        return r;
    }

    /// One block's compressed bytes into exactly `bytes` bytes (a short or overlong block is corrupt).
    bool decode(const std::vector<std::uint8_t>& c, std::uint8_t* out, size_t bytes, int worker) {
        if (jpeg) {
            const size_t rowBytes = size_t(blockWidth) * size_t(samples);
            return bytes % rowBytes == 0 && decodeJpeg(*jpegDecoders[size_t(worker)], jpegTables, c, out, blockWidth,
                                                       int(bytes / rowBytes), samples, ycbcr);
        }
        if (zstd) {
            const size_t n = ZSTD_decompressDCtx(zstdContexts[size_t(worker)].get(), out, bytes, c.data(), c.size());
            return !ZSTD_isError(n) && n == bytes;
        }
        return libdeflate_zlib_decompress(inflaters[size_t(worker)].get(), c.data(), c.size(), out, bytes, nullptr) ==
               LIBDEFLATE_SUCCESS;
    }

    /// Rows [y0, y1) (whole block rows, except at the bottom) of channels [0, channels) into `out`, samples of the
    /// file's own size. False when a block cannot be read or decoded (GDAL then tries and reports).
    bool read(int width, int height, int y0, int y1, int channels, std::uint8_t* out) {
        failure.clear();
        damaged = false;
        const size_t pixelBytes = size_t(samples) * size_t(sampleBytes);
        const size_t outPixel = size_t(channels) * size_t(sampleBytes);
        const size_t blockRowBytes = size_t(blockWidth) * pixelBytes;
        const int across = tiled ? (width + blockWidth - 1) / blockWidth : 1;
        const int stripsDown = (height + blockHeight - 1) / blockHeight;
        compressed.resize(size_t(across));
        for (int by = y0 / blockHeight; by * blockHeight < y1; ++by) {
            // The file is read in order by one thread (libtiff handles are not shared), inflated on all of them.
            for (int i = 0; i < across; ++i) {
                const std::uint32_t strile = std::uint32_t(tiled ? by * across + i : by);
                if (!tiled && by >= stripsDown) return false;
                const std::uint64_t size = TIFFGetStrileByteCount(tif, strile);
                // A damaged index may claim gigabytes: checked against the file before anything is allocated.
                const std::uint64_t offset = size == 0 ? 0 : TIFFGetStrileOffset(tif, strile);
                if (size > fileBytes || offset > fileBytes - size) {
                    damaged = true;
                    failure = std::string(tiled ? "tile " : "strip ") + std::to_string(strile) + ": " +
                              std::to_string(size) + " bytes at offset " + std::to_string(offset) +
                              " run past the end of the file (" + std::to_string(fileBytes) + " bytes)";
                    return false;
                }
                std::vector<std::uint8_t>& c = compressed[size_t(i)];
                c.resize(size_t(size));
                if (size == 0) continue; // a sparse block: zeros, as libtiff reads it
                const tmsize_t got = tiled ? TIFFReadRawTile(tif, strile, c.data(), tmsize_t(size))
                                           : TIFFReadRawStrip(tif, strile, c.data(), tmsize_t(size));
                if (got != tmsize_t(size)) {
                    damaged = true;
                    failure = std::string(tiled ? "tile " : "strip ") + std::to_string(strile) + ": read " +
                              std::to_string(std::max<tmsize_t>(got, 0)) + " of its " + std::to_string(size) + " bytes";
                    return false;
                }
            }
            const int blockY = by * blockHeight;
            const int rowsInBlock = tiled ? blockHeight : std::min(blockHeight, height - blockY);
            const int r0 = std::max(y0, blockY) - blockY, r1 = std::min({y1, blockY + blockHeight, height}) - blockY;
            std::atomic<bool> ok{true};
            parallelIndices(across, threads, [&](int i, int worker) {
                std::vector<std::uint8_t>& block = scratch[size_t(worker)];
                const size_t bytes = blockRowBytes * size_t(rowsInBlock);
                block.resize(bytes);
                const std::vector<std::uint8_t>& c = compressed[size_t(i)];
                if (c.empty()) std::memset(block.data(), 0, bytes);
                else if (!decode(c, block.data(), bytes, worker)) {
                    const bool first = ok.exchange(false);
                    // The first failure's words (only it writes).
                    if (first) {
                        const std::string which = std::string(tiled ? "tile " : "strip ") +
                                                  std::to_string(tiled ? by * across + i : by);
                        failure = jpeg   ? "JPEG " + which + ": " + jpegDecoders[size_t(worker)]->error.message
                                  : zstd ? "Zstandard " + which + " does not decode to its " + std::to_string(bytes) +
                                               " bytes"
                                         : "deflate " + which + " does not inflate to its " + std::to_string(bytes) +
                                               " bytes with a valid checksum";
                    }
                    return;
                }
                const int x0 = i * blockWidth, cols = std::min(blockWidth, width - x0);
                const size_t used = size_t(cols) * pixelBytes;
                for (int r = r0; r < r1; ++r) {
                    std::uint8_t* src = block.data() + size_t(r) * blockRowBytes;
                    std::uint8_t* dst = out + (size_t(blockY + r - y0) * size_t(width) + size_t(x0)) * outPixel;
                    if (predictor == PREDICTOR_HORIZONTAL && sampleBytes == 1 && samples == 3 && channels == 3) {
                        undoPredictorRgb8(src, dst, size_t(cols)); // the common case: undone while copied
                        continue;
                    }
                    if (predictor == PREDICTOR_HORIZONTAL) {
                        if (sampleBytes == 1) undoPredictor8(src, used, size_t(samples));
                        else undoPredictor16(src, used, size_t(samples));
                    }
                    if (channels == samples) {
                        std::memcpy(dst, src, used);
                    } else {
                        for (int x = 0; x < cols; ++x)
                            std::memcpy(dst + size_t(x) * outPixel, src + size_t(x) * pixelBytes, outPixel);
                    }
                }
            });
            if (!ok) {
                damaged = true;
                return false;
            }
        }
        return true;
    }
};

struct BandReader::Input {
    gdal::Dataset ds;
    std::unique_ptr<RawTiff> raw; // null: GDAL decodes everything
};

BandReader::BandReader(BandReader&&) noexcept = default;
BandReader& BandReader::operator=(BandReader&&) noexcept = default;
BandReader::~BandReader() = default;

Result<BandReader> BandReader::open(const std::filesystem::path& path, int preferredRows) {
    BandReader r;
    r.m_path = path;
    r.m_in = std::make_unique<Input>();
    auto ds = gdal::openRaster(path);
    if (!ds) return ds.error();
    r.m_in->ds = std::move(*ds);
    GDALDataset& d = *r.m_in->ds;
    r.m_width = d.GetRasterXSize();
    r.m_height = d.GetRasterYSize();
    r.m_channels = d.GetRasterCount();
    GDALRasterBand* first = d.GetRasterBand(1);
    const auto type = gdal::sampleTypeOf(first->GetRasterDataType());
    if (!type)
        return fileError(path.string(),
                         std::string("unsupported sample type ") + GDALGetDataTypeName(first->GetRasterDataType()));
    r.m_type = *type;
    int bx = 0, by = 0;
    first->GetBlockSize(&bx, &by);
    r.m_tileHeight = std::max(1, by);
    r.m_bandRows = r.m_tileHeight * std::max(1, preferredRows / r.m_tileHeight);
    const bool tiff = d.GetDriver() && std::string_view(d.GetDriver()->GetDescription()) == "GTiff";
    if (tiff && (r.m_type == SampleType::U8 || r.m_type == SampleType::U16)) {
        r.m_in->raw = RawTiff::open(path, r.m_width, r.m_height, std::max(preferredRows, 256));
        // Bands of whole strips, so that every band starts on a strip (tiles: already whole tile rows).
        if (r.m_in->raw && !r.m_in->raw->tiled) {
            const int strip = r.m_in->raw->blockHeight;
            r.m_bandRows = strip * std::max(1, preferredRows / strip);
        }
    }
    return r;
}

bool BandReader::decodesTilesItself() const { return m_in && m_in->raw != nullptr; }

Status BandReader::read(int y0, int y1, int channels, SampleType type, void* out) const {
    assert((type == SampleType::U8 || type == SampleType::U16) && "BandReader::read(): 8- or 16-bit only");
    assert(y0 % m_bandRows == 0 && y0 < y1 && y1 - y0 <= m_bandRows && y1 <= m_height && channels >= 1 &&
           channels <= m_channels && "BandReader::read(): whole bands of existing rows and channels");
    if (m_in->raw && type == m_type) {
        if (m_in->raw->read(m_width, m_height, y0, y1, channels, static_cast<std::uint8_t*>(out))) return Ok{};
        if (m_in->raw->damaged) return gdal::readFailure(m_path.string(), gdal::ErrorCapture(), y0, y1, m_in->raw->failure);
        ++m_handedOver;
    }
    int bands[4] = {1, 2, 3, 4};
    std::vector<int> many;
    if (channels > 4) {
        many.resize(size_t(channels));
        for (int c = 0; c < channels; ++c) many[size_t(c)] = c + 1;
    }
    const GSpacing sample = type == SampleType::U16 ? 2 : 1;
    // A tile service answering 429 or 5xx (GDAL 3.6's tile drivers fail the block at once, never reading
    // Retry-After): read again after what web::busyWait learns from the server, at most 3 times.
    for (int attempt = 0;; ++attempt) {
        gdal::ErrorCapture errors;
        const CPLErr err = m_in->ds->RasterIO(GF_Read, 0, y0, m_width, y1 - y0, out, m_width, y1 - y0,
                                              gdal::gdalTypeOf(type), channels, channels > 4 ? many.data() : bands,
                                              sample * channels, sample * channels * m_width, sample, nullptr);
        // A warning during a read is lost data too (libtiff reports some short reads as warnings).
        if (err == CE_None && !errors.lostData()) return Ok{};
        if (attempt < 3)
            if (const auto wait = web::busyWait(m_path, errors.message(), double(1 << attempt))) {
                std::this_thread::sleep_for(std::chrono::duration<double>(*wait));
                continue;
            }
        // The own decoder's words first when it tried.
        return gdal::readFailure(m_path.string(), errors, y0, y1,
                                 m_in->raw && !m_in->raw->failure.empty() ? m_in->raw->failure : std::string());
    }
}

} // namespace seasonview
