#include "GeoTiffStreamWriter.h"

#include "AtomicFile.h"
#include "GdalSupport.h"
#include "JpegSupport.h"
#include "ParallelIndices.h"
#include "TiffSupport.h"
#include "ZstdTileCheck.h"

#include <libdeflate.h>
#include <zstd.h>

#include <algorithm>
#include <bit>
#include <cassert>
#include <csetjmp>
#include <cstring>
#include <thread>
#include <utility>

namespace seasonview {

namespace {

constexpr int kRowsPerStrip = 16;

int bytesOf(SampleType t) { return t == SampleType::U8 ? 1 : t == SampleType::F32 ? 4 : 2; }

// The TIFF predictors, applied in place to one row of a tile or strip exactly as libtiff's encoder would
// (tif_predict.c), so that readers undo them and the files match what libtiff writes itself.

// Predictor 2 on 8-bit samples: each byte minus the same channel of the pixel to its left, modulo 256.
void horizontalDiff8(std::uint8_t* row, size_t bytes, size_t stride) {
    for (size_t k = bytes - 1; k >= stride; --k) row[k] = std::uint8_t(row[k] - row[k - stride]);
}

// Predictor 2 on 16-bit samples (native byte order, as libtiff writes them), modulo 65536.
void horizontalDiff16(std::uint8_t* row, size_t bytes, size_t stride) {
    const size_t n = bytes / 2;
    for (size_t k = n - 1; k >= stride; --k) {
        std::uint16_t a, b;
        std::memcpy(&a, row + 2 * k, 2);
        std::memcpy(&b, row + 2 * (k - stride), 2);
        a = std::uint16_t(a - b);
        std::memcpy(row + 2 * k, &a, 2);
    }
}

// Predictor 3 (floating point, Adobe TIFF tech note 3): the row's samples split into byte planes, most significant
// byte first, then byte differences across the whole row with the pixel's channel count as stride.
void floatingPointDiff(std::uint8_t* row, size_t bytes, size_t stride, std::vector<std::uint8_t>& tmp) {
    constexpr size_t bps = 4;
    const size_t wc = bytes / bps;
    tmp.assign(row, row + bytes);
    for (size_t count = 0; count < wc; ++count)
        for (size_t byte = 0; byte < bps; ++byte) {
            const size_t plane = std::endian::native == std::endian::big ? byte : bps - byte - 1;
            row[plane * wc + count] = tmp[bps * count + byte];
        }
    horizontalDiff8(row, bytes, stride);
}

struct CompressorDeleter {
    void operator()(libdeflate_compressor* c) const { libdeflate_free_compressor(c); }
    void operator()(ZSTD_CCtx* c) const { ZSTD_freeCCtx(c); }
};

/// A libjpeg compressor, one per encoding thread, writing into `out` (no libjpeg-owned buffer to free after an error).
struct JpegEncoder {
    jpeg_compress_struct cinfo{};
    jpeg::ErrorManager error;
    jpeg_destination_mgr dest{};
    std::vector<std::uint8_t>* out = nullptr;
    bool created = false;
    JpegEncoder() {
        error.install(cinfo);
        if (setjmp(error.jump)) return;
        jpeg_create_compress(&cinfo);
        cinfo.client_data = this;
        dest.init_destination = [](j_compress_ptr c) {
            auto* self = static_cast<JpegEncoder*>(c->client_data);
            self->out->resize(std::max<size_t>(self->out->capacity(), 1 << 16));
            self->dest.next_output_byte = self->out->data();
            self->dest.free_in_buffer = self->out->size();
        };
        dest.empty_output_buffer = [](j_compress_ptr c) -> boolean {
            auto* self = static_cast<JpegEncoder*>(c->client_data);
            const size_t used = self->out->size();
            self->out->resize(used * 2);
            self->dest.next_output_byte = self->out->data() + used;
            self->dest.free_in_buffer = self->out->size() - used;
            return TRUE;
        };
        dest.term_destination = [](j_compress_ptr c) {
            auto* self = static_cast<JpegEncoder*>(c->client_data);
            self->out->resize(self->out->size() - self->dest.free_in_buffer);
        };
        cinfo.dest = &dest;
        created = true;
    }
    ~JpegEncoder() { jpeg_destroy_compress(&cinfo); } // safe on a partly created object
    JpegEncoder(const JpegEncoder&) = delete;
    JpegEncoder& operator=(const JpegEncoder&) = delete;
};

/// One tile or strip of 8-bit RGB into `out` as a complete JPEG stream (its own tables: TIFF's JPEGTables tag is
/// optional, TIFF Technical Note 2; no JFIF marker, as libtiff writes), YCbCr with 2×2 subsampled chroma (libjpeg's
/// default, the file's YCbCrSubsampling). `out` empty on failure.
void compressJpeg(JpegEncoder& e, const std::uint8_t* rgb, int width, int height, int quality,
                  std::vector<std::uint8_t>& out) {
    jpeg_compress_struct& c = e.cinfo;
    out.clear();
    if (!e.created) return;
    e.out = &out;
    if (setjmp(e.error.jump)) {
        jpeg_abort_compress(&c);
        out.clear();
        return;
    }
    c.image_width = JDIMENSION(width);
    c.image_height = JDIMENSION(height);
    c.input_components = 3;
    c.in_color_space = JCS_RGB;
    jpeg_set_defaults(&c); // JCS_YCbCr, Y sampled 2×2, Cb and Cr 1×1
    c.write_JFIF_header = FALSE;
    jpeg_set_quality(&c, std::clamp(quality, 1, 100), TRUE);
    jpeg_start_compress(&c, TRUE);
    const size_t rowBytes = size_t(width) * 3;
    while (c.next_scanline < c.image_height) {
        JSAMPROW row = const_cast<JSAMPROW>(rgb + size_t(c.next_scanline) * rowBytes);
        jpeg_write_scanlines(&c, &row, 1);
    }
    jpeg_finish_compress(&c);
}

} // namespace

struct GeoTiffStreamWriter::Encoder {
    TiffCompression compression = TiffCompression::Deflate;
    int zstdLevel = 1, jpegQuality = 90;
    std::vector<std::unique_ptr<libdeflate_compressor, CompressorDeleter>> compressors; // per thread (deflate)
    std::vector<std::unique_ptr<JpegEncoder>> jpegs;                                     // per thread (JPEG)
    std::vector<std::unique_ptr<ZSTD_CCtx, CompressorDeleter>> zstd;                     // per thread (zstd)
    std::vector<std::vector<std::uint8_t>> block, planes;                                 // per thread
    std::vector<std::vector<std::uint8_t>> compressed; // per block of a chunk, in order, reused across block rows
};

GeoTiffStreamWriter::GeoTiffStreamWriter() = default;

Result<GeoTiffStreamWriter> GeoTiffStreamWriter::open(const std::filesystem::path& path, int width, int height,
                                                      int channels, SampleType type,
                                                      const std::optional<Georef>& georef,
                                                      const GeoTiffWriteOptions& options) {
    assert(width > 0 && height > 0 && channels > 0 && "GeoTiffStreamWriter::open(): empty raster");
    assert(options.tileSize >= 0 && options.tileSize % 16 == 0 &&
           "GeoTiffStreamWriter::open(): the tile size must be 0 (strips) or a positive multiple of 16");
    GeoTiffStreamWriter w;
    w.m_path = path;
    w.m_tmp = temporaryPathFor(path);
    w.m_width = width;
    w.m_height = height;
    w.m_channels = channels;
    w.m_type = type;
    w.m_sampleBytes = bytesOf(type);
    w.m_threads = options.threads > 0 ? options.threads : std::max(1, int(std::thread::hardware_concurrency()));
    w.m_tiled = options.tileSize > 0;
    w.m_blockWidth = w.m_tiled ? options.tileSize : width;
    w.m_blockHeight = w.m_tiled ? options.tileSize : kRowsPerStrip;
    w.m_error = std::make_unique<std::string>();
    const std::uint64_t rawBytes =
        std::uint64_t(width) * std::uint64_t(height) * std::uint64_t(channels) * std::uint64_t(w.m_sampleBytes);
    // BigTIFF past 2 GiB of raw samples by default: deflate may not bring noisy imagery under the classic 4 GiB
    // offset limit.
    w.m_bigTiff = rawBytes > options.bigTiffAbove;
    w.m_tif = tiff::open(w.m_tmp, w.m_bigTiff ? "w8" : "w", w.m_error.get());
    if (!w.m_tif) {
        discardTemporary(w.m_tmp); // libtiff creates the file before it fails to write the header (a full disk)
        return fileError(path.string(), "cannot create file (" + *w.m_error + ")");
    }

    TIFF* t = w.m_tif;
    TIFFSetField(t, TIFFTAG_IMAGEWIDTH, std::uint32_t(width));
    TIFFSetField(t, TIFFTAG_IMAGELENGTH, std::uint32_t(height));
    TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, std::uint16_t(channels));
    TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, std::uint16_t(w.m_sampleBytes * 8));
    TIFFSetField(t, TIFFTAG_SAMPLEFORMAT,
                 type == SampleType::F32 ? SAMPLEFORMAT_IEEEFP : type == SampleType::I16 ? SAMPLEFORMAT_INT
                                                                                          : SAMPLEFORMAT_UINT);
    TIFFSetField(t, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
    const bool jpeg = options.compression == TiffCompression::Jpeg;
    if (jpeg && (type != SampleType::U8 || channels != 3))
        return w.fail("JPEG compression takes 8-bit RGB only").error();
    TIFFSetField(t, TIFFTAG_PHOTOMETRIC,
                 jpeg ? PHOTOMETRIC_YCBCR : channels >= 3 ? PHOTOMETRIC_RGB : PHOTOMETRIC_MINISBLACK);
    if (channels == 4 || channels == 2) {
        std::uint16_t extra = options.associatedAlpha ? EXTRASAMPLE_ASSOCALPHA : EXTRASAMPLE_UNASSALPHA;
        TIFFSetField(t, TIFFTAG_EXTRASAMPLES, std::uint16_t(1), &extra);
    }
    // The tiles are compressed here and written raw: a ZSTD tile is one Zstandard frame, as libtiff's codec
    // (tif_zstd.c) writes and reads it; a deflate tile one zlib stream.
    // The codec must be configured in libtiff even though the tiles are compressed here: only a configured codec
    // registers the predictor tag, and a file without it would hold differenced bytes as if they were pixels.
    // A JPEG tile is one complete JPEG stream (tables included), YCbCr 4:2:0, no predictor.
    const std::uint16_t codec = jpeg                                             ? COMPRESSION_JPEG
                                : options.compression == TiffCompression::Zstd ? COMPRESSION_ZSTD
                                                                                : COMPRESSION_ADOBE_DEFLATE;
    if (!TIFFIsCODECConfigured(codec))
        return w.fail(std::string("this libtiff has no ") + tiffCompressionName(options.compression) +
                      " codec (write deflate instead)")
            .error();
    if (!TIFFSetField(t, TIFFTAG_COMPRESSION, codec) ||
        (jpeg ? !TIFFSetField(t, TIFFTAG_YCBCRSUBSAMPLING, std::uint16_t(2), std::uint16_t(2))
              : !TIFFSetField(t, TIFFTAG_PREDICTOR,
                              type == SampleType::F32 ? PREDICTOR_FLOATINGPOINT : PREDICTOR_HORIZONTAL)))
        return w.fail("cannot set the compression tags").error();
    if (jpeg) {
        // What libtiff's own JPEG encoder (and GDAL) write for YCbCr: full-range codes, as JPEG's YCbCr is.
        float referenceBlackWhite[6] = {0.0f, 255.0f, 128.0f, 255.0f, 128.0f, 255.0f};
        if (!TIFFSetField(t, TIFFTAG_REFERENCEBLACKWHITE, referenceBlackWhite))
            return w.fail("cannot set the YCbCr reference tag").error();
    }
    w.m_georef = georef;
    w.m_nodata = options.nodata;
    if (options.nodata && !tiff::writeNodataTag(t, *options.nodata)) return w.fail("cannot write the nodata tag").error();
    if (w.m_tiled) {
        TIFFSetField(t, TIFFTAG_TILEWIDTH, std::uint32_t(options.tileSize));
        TIFFSetField(t, TIFFTAG_TILELENGTH, std::uint32_t(options.tileSize));
    } else {
        TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, std::uint32_t(kRowsPerStrip));
    }

    w.m_encoder = std::make_unique<Encoder>();
    const size_t blockBytes =
        size_t(w.m_blockWidth) * size_t(w.m_blockHeight) * size_t(channels) * size_t(w.m_sampleBytes);
    w.m_encoder->compression = options.compression;
    w.m_encoder->zstdLevel = std::clamp(options.zstdLevel, 1, ZSTD_maxCLevel());
    w.m_encoder->jpegQuality = std::clamp(options.jpegQuality, 1, 100);
    for (int i = 0; i < w.m_threads; ++i) {
        if (jpeg) {
            w.m_encoder->jpegs.push_back(std::make_unique<JpegEncoder>());
            if (!w.m_encoder->jpegs.back()->created) return w.fail("cannot create the JPEG compressor").error();
        } else if (options.compression == TiffCompression::Zstd) {
            w.m_encoder->zstd.emplace_back(ZSTD_createCCtx());
            // Every frame carries a checksum of its content (libzstd verifies it when decoding, in libtiff's codec
            // and in BandReader's): a damaged tile fails to decode rather than decoding to wrong pixels.
            if (ZSTD_CCtx* c = w.m_encoder->zstd.back().get()) {
                ZSTD_CCtx_setParameter(c, ZSTD_c_compressionLevel, w.m_encoder->zstdLevel);
                ZSTD_CCtx_setParameter(c, ZSTD_c_checksumFlag, 1);
            }
            if (!w.m_encoder->zstd.back()) return w.fail("out of memory for the compressor").error();
        } else {
            w.m_encoder->compressors.emplace_back(
                libdeflate_alloc_compressor(std::clamp(options.deflateLevel, 1, 12)));
            if (!w.m_encoder->compressors.back()) return w.fail("out of memory for the compressor").error();
        }
        w.m_encoder->block.emplace_back(blockBytes);
        w.m_encoder->planes.emplace_back();
    }
    return w;
}

GeoTiffStreamWriter::GeoTiffStreamWriter(GeoTiffStreamWriter&& other) noexcept { *this = std::move(other); }

GeoTiffStreamWriter& GeoTiffStreamWriter::operator=(GeoTiffStreamWriter&& other) noexcept {
    if (this != &other) {
        abandon();
        m_path = std::move(other.m_path);
        m_tmp = std::move(other.m_tmp);
        m_tif = std::exchange(other.m_tif, nullptr);
        m_width = other.m_width;
        m_height = other.m_height;
        m_channels = other.m_channels;
        m_sampleBytes = other.m_sampleBytes;
        m_threads = other.m_threads;
        m_type = other.m_type;
        m_blockWidth = other.m_blockWidth;
        m_blockHeight = other.m_blockHeight;
        m_tiled = other.m_tiled;
        m_bigTiff = other.m_bigTiff;
        m_rowsWritten = other.m_rowsWritten;
        m_error = std::move(other.m_error);
        m_encoder = std::move(other.m_encoder);
        m_pending = std::move(other.m_pending);
        m_georef = std::move(other.m_georef);
        m_nodata = other.m_nodata;
        m_pendingRows = other.m_pendingRows;
    }
    return *this;
}

GeoTiffStreamWriter::~GeoTiffStreamWriter() { abandon(); }

void GeoTiffStreamWriter::abandon() {
    if (!m_tif) return;
    TIFFClose(m_tif);
    m_tif = nullptr;
    discardTemporary(m_tmp);
}

Status GeoTiffStreamWriter::fail(const std::string& what) {
    abandon();
    return fileError(m_path.string(), what + (m_error->empty() ? std::string() : " (" + *m_error + ")"));
}

Status GeoTiffStreamWriter::writeRows(int y0, int rows, const void* data) {
    assert(m_tif && "GeoTiffStreamWriter::writeRows(): the file is finished or failed");
    assert(y0 == m_rowsWritten && rows >= 0 && y0 + rows <= m_height &&
           "GeoTiffStreamWriter::writeRows(): rows must follow the rows written so far, within the image");
    (void)y0;
    const size_t rowBytes = size_t(m_width) * size_t(m_channels) * size_t(m_sampleBytes);
    const auto* src = static_cast<const std::uint8_t*>(data);
    while (rows > 0) {
        const int blockY = m_rowsWritten - m_pendingRows;
        const int need = std::min(m_blockHeight, m_height - blockY);
        if (m_pendingRows == 0 && rows >= need) { // a whole block row in the caller's buffer: no copy
            if (auto st = encodeBlockRow(src, blockY, need); !st) return st;
            src += size_t(need) * rowBytes;
            rows -= need;
            m_rowsWritten += need;
            continue;
        }
        const int take = std::min(rows, need - m_pendingRows);
        m_pending.resize(size_t(m_blockHeight) * rowBytes);
        std::memcpy(m_pending.data() + size_t(m_pendingRows) * rowBytes, src, size_t(take) * rowBytes);
        src += size_t(take) * rowBytes;
        rows -= take;
        m_pendingRows += take;
        m_rowsWritten += take;
        if (m_pendingRows == need) {
            m_pendingRows = 0;
            if (auto st = encodeBlockRow(m_pending.data(), blockY, need); !st) return st;
        }
    }
    return Ok{};
}

Status GeoTiffStreamWriter::encodeBlockRow(const std::uint8_t* rows, int y0, int rowCount) {
    Encoder& enc = *m_encoder;
    const size_t pixelBytes = size_t(m_channels) * size_t(m_sampleBytes);
    const size_t blockRowBytes = size_t(m_blockWidth) * pixelBytes;
    // Tiles are always whole (padded with zeros); the last strip holds only the rows that remain.
    const int blockRows = m_tiled ? m_blockHeight : rowCount;
    const size_t blockBytes = blockRowBytes * size_t(blockRows);
    const size_t srcRowBytes = size_t(m_width) * pixelBytes;
    const int across = (m_width + m_blockWidth - 1) / m_blockWidth;
    // Compress a bounded chunk of tiles at a time so a very wide row never holds all its compressed tiles at once.
    const int chunk = std::max(16, m_threads * 8);
    enc.compressed.resize(size_t(std::min(chunk, across)));
    for (int first = 0; first < across; first += chunk) {
        const int count = std::min(chunk, across - first);
        parallelIndices(count, m_threads, [&](int i, int worker) {
            const int x0 = (first + i) * m_blockWidth;
            const size_t used = size_t(std::min(m_blockWidth, m_width - x0)) * pixelBytes;
            std::uint8_t* block = enc.block[size_t(worker)].data();
            for (int y = 0; y < blockRows; ++y) {
                std::uint8_t* dst = block + size_t(y) * blockRowBytes;
                const size_t copied = y < rowCount ? used : 0;
                if (copied) std::memcpy(dst, rows + size_t(y) * srcRowBytes + size_t(x0) * pixelBytes, copied);
                if (enc.compression == TiffCompression::Jpeg) {
                    // No predictor; edge tiles padded with their last column and row (zeros would ring into the
                    // image's edge pixels through the 8×8 blocks and the subsampled chroma).
                    if (copied == 0) {
                        std::memcpy(dst, dst - blockRowBytes, blockRowBytes); // y >= rowCount >= 1
                        continue;
                    }
                    for (size_t k = copied; k < blockRowBytes; k += pixelBytes)
                        std::memcpy(dst + k, dst + copied - pixelBytes, pixelBytes);
                    continue;
                }
                std::memset(dst + copied, 0, blockRowBytes - copied); // edge tiles: zero padding
                switch (m_type) {
                case SampleType::U8: horizontalDiff8(dst, blockRowBytes, size_t(m_channels)); break;
                case SampleType::U16:
                case SampleType::I16: horizontalDiff16(dst, blockRowBytes, size_t(m_channels)); break;
                case SampleType::F32:
                    floatingPointDiff(dst, blockRowBytes, size_t(m_channels), enc.planes[size_t(worker)]);
                    break;
                }
            }
            std::vector<std::uint8_t>& out = enc.compressed[size_t(i)];
            if (enc.compression == TiffCompression::Jpeg) {
                compressJpeg(*enc.jpegs[size_t(worker)], block, m_blockWidth, blockRows, enc.jpegQuality, out);
            } else if (enc.compression == TiffCompression::Zstd) {
                out.resize(ZSTD_compressBound(blockBytes));
                const size_t n =
                    ZSTD_compress2(enc.zstd[size_t(worker)].get(), out.data(), out.size(), block, blockBytes);
                out.resize(ZSTD_isError(n) ? 0 : n); // empty: reported as a failure below
                // A CRC-32 of the frame after it, so the reader checks the tile without decoding it (ZstdTileCheck.h).
                if (!out.empty()) appendTileChecksum(out);
            } else {
                libdeflate_compressor* c = enc.compressors[size_t(worker)].get();
                out.resize(libdeflate_zlib_compress_bound(c, blockBytes));
                out.resize(libdeflate_zlib_compress(c, block, blockBytes, out.data(), out.size()));
            }
        });
        for (int i = 0; i < count; ++i) {
            std::vector<std::uint8_t>& out = enc.compressed[size_t(i)];
            if (out.empty()) return fail("cannot compress a " + std::string(m_tiled ? "tile" : "strip"));
            const std::uint32_t x = std::uint32_t((first + i) * m_blockWidth);
            const tmsize_t written =
                out.empty() ? -1
                : m_tiled   ? TIFFWriteRawTile(m_tif, TIFFComputeTile(m_tif, x, std::uint32_t(y0), 0, 0), out.data(),
                                               tmsize_t(out.size()))
                            : TIFFWriteRawStrip(m_tif, TIFFComputeStrip(m_tif, std::uint32_t(y0), 0), out.data(),
                                                tmsize_t(out.size()));
            if (written < 0) return fail("cannot write " + std::string(m_tiled ? "tile" : "strip") + " (disk full?)");
        }
    }
    return Ok{};
}

Status GeoTiffStreamWriter::finish() {
    assert(m_tif && "GeoTiffStreamWriter::finish(): already finished or failed");
    assert(m_rowsWritten == m_height && "GeoTiffStreamWriter::finish(): rows missing");
    if (!TIFFWriteDirectory(m_tif)) return fail("cannot write the TIFF directory (disk full?)");
    TIFFClose(m_tif);
    m_tif = nullptr;
    m_encoder.reset();
    m_pending = {};
    // GDAL writes the georeferencing (GeoTIFF keys for any CRS PROJ knows) into the closed file before it gets its
    // name.
    if (m_georef)
        if (auto st = gdal::stampGeoreference(m_tmp, *m_georef, m_nodata); !st) {
            std::error_code ec;
            std::filesystem::remove(m_tmp, ec);
            return fileError(m_path.string(), st.message());
        }
    std::string err;
    if (!commitTemporary(m_tmp, m_path, err)) return fileError(m_path.string(), err);
    return Ok{};
}

} // namespace seasonview
