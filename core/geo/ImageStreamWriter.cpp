#include "ImageStreamWriter.h"

#include "AtomicFile.h"

#include <OpenImageIO/imageio.h>
#include <png.h>
#include <zlib.h>

#include <algorithm>
#include <cassert>
#include <cctype>
#include <csetjmp>
#include <cstdio>

namespace seasonview {

namespace {

bool isPng(const std::filesystem::path& p) {
    std::string e = p.extension().string();
    std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return e == ".png";
}

// libpng reports errors by longjmp back into the function that called it: the message is kept for our Error and
// nothing is printed.
void pngError(png_structp png, png_const_charp message) {
    if (auto* text = static_cast<std::string*>(png_get_error_ptr(png))) *text = message ? message : "";
    png_longjmp(png, 1);
}
void pngWarning(png_structp, png_const_charp) {}

} // namespace

struct ImageStreamWriter::Impl {
    std::filesystem::path path, tmp;
    std::unique_ptr<OIIO::ImageOutput> out; // OpenImageIO (Default encoding, and TIFF)
    // libpng (FastMask PNG): OpenImageIO 2.4 cannot choose the zlib strategy.
    std::FILE* file = nullptr;
    png_structp png = nullptr;
    png_infop info = nullptr;
    std::string pngMessage;

    bool open() const { return out || png; }
    void closePng() {
        if (png) png_destroy_write_struct(&png, &info);
        png = nullptr;
        info = nullptr;
        if (file) std::fclose(file);
        file = nullptr;
    }
};

namespace {

// The libpng calls, each in a function of its own with nothing to destroy between setjmp and a longjmp.
bool pngStart(png_structp png, png_infop info, std::FILE* file, int width, int height, int channels, bool fast) {
    if (setjmp(png_jmpbuf(png))) return false;
    png_init_io(png, file);
    const int colour = channels == 1   ? PNG_COLOR_TYPE_GRAY
                       : channels == 2 ? PNG_COLOR_TYPE_GRAY_ALPHA
                       : channels == 3 ? PNG_COLOR_TYPE_RGB
                                       : PNG_COLOR_TYPE_RGB_ALPHA;
    png_set_IHDR(png, info, png_uint_32(width), png_uint_32(height), 8, colour, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    if (fast) {
        png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_NONE);
        png_set_compression_level(png, 1);
        png_set_compression_strategy(png, Z_RLE);
    } else { // what OpenImageIO does: adaptive row filters, zlib level 6
        png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_ALL_FILTERS);
        png_set_compression_level(png, 6);
    }
    png_write_info(png, info);
    return true;
}

bool pngRows(png_structp png, const std::uint8_t* data, int rows, size_t rowBytes) {
    if (setjmp(png_jmpbuf(png))) return false;
    for (int r = 0; r < rows; ++r) png_write_row(png, data + size_t(r) * rowBytes);
    return true;
}

bool pngEnd(png_structp png) {
    if (setjmp(png_jmpbuf(png))) return false;
    png_write_end(png, nullptr);
    return true;
}

} // namespace

ImageStreamWriter::ImageStreamWriter() = default;
ImageStreamWriter::ImageStreamWriter(ImageStreamWriter&& other) noexcept { *this = std::move(other); }
ImageStreamWriter& ImageStreamWriter::operator=(ImageStreamWriter&& other) noexcept {
    if (this != &other) {
        abandon();
        m_impl = std::move(other.m_impl);
        m_width = other.m_width;
        m_height = other.m_height;
        m_channels = other.m_channels;
        m_rowsWritten = other.m_rowsWritten;
    }
    return *this;
}
ImageStreamWriter::~ImageStreamWriter() { abandon(); }

void ImageStreamWriter::abandon() {
    if (!m_impl || !m_impl->open()) return;
    if (m_impl->out) {
        m_impl->out->close();
        m_impl->out.reset();
    }
    m_impl->closePng();
    discardTemporary(m_impl->tmp);
}

Status ImageStreamWriter::fail(const std::string& what) {
    const std::string e = m_impl->out ? firstLine(m_impl->out->geterror()) : firstLine(m_impl->pngMessage);
    abandon();
    return fileError(m_impl->path.string(), what + (e.empty() ? std::string() : " (" + e + ")"));
}

Result<ImageStreamWriter> ImageStreamWriter::open(const std::filesystem::path& path, int width, int height,
                                                  int channels, ImageEncoding encoding) {
    assert(width > 0 && height > 0 && channels > 0 && "ImageStreamWriter::open(): empty image");
    ImageStreamWriter w;
    w.m_impl = std::make_unique<Impl>();
    Impl& impl = *w.m_impl;
    impl.path = path;
    impl.tmp = temporaryPathFor(path);
    w.m_width = width;
    w.m_height = height;
    w.m_channels = channels;
    // PNG through libpng, whose writes fail on a short fwrite (a full disk) where OpenImageIO's PNG writer reports
    // success.
    if (isPng(path) && channels <= 4) {
        impl.file = std::fopen(impl.tmp.c_str(), "wb");
        if (!impl.file) return fileError(path.string(), "cannot create file");
        std::setvbuf(impl.file, nullptr, _IOFBF, size_t(1) << 16); // fewer, larger writes
        impl.png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &impl.pngMessage, pngError, pngWarning);
        if (impl.png) impl.info = png_create_info_struct(impl.png);
        if (!impl.png || !impl.info || !pngStart(impl.png, impl.info, impl.file, width, height, channels,
                                                             encoding == ImageEncoding::FastMask))
            return w.fail("cannot create file").error();
        return w;
    }
    impl.out = OIIO::ImageOutput::create(path.string());
    if (!impl.out) return fileError(path.string(), "unsupported output image format (use .png or .tif)");
    OIIO::ImageSpec spec(width, height, channels, OIIO::TypeDesc::UINT8);
    if (encoding == ImageEncoding::FastMask) spec.attribute("compression", "zip:1");
    if (!impl.out->open(impl.tmp.string(), spec)) {
        std::string e = firstLine(impl.out->geterror());
        impl.out.reset();
        discardTemporary(impl.tmp); // the writer may have created the file before failing (a full disk)
        return fileError(path.string(), "cannot create file" + (e.empty() ? std::string() : " (" + e + ")"));
    }
    return w;
}

Status ImageStreamWriter::writeRows(int y0, int rows, const std::uint8_t* data) {
    assert(m_impl && m_impl->open() && "ImageStreamWriter::writeRows(): the file is finished or failed");
    assert(y0 == m_rowsWritten && rows >= 0 && y0 + rows <= m_height &&
           "ImageStreamWriter::writeRows(): rows must follow the rows written so far, within the image");
    if (rows == 0) return Ok{};
    const bool ok = m_impl->png ? pngRows(m_impl->png, data, rows, size_t(m_width) * size_t(m_channels))
                                : m_impl->out->write_scanlines(y0, y0 + rows, 0, OIIO::TypeDesc::UINT8, data);
    if (!ok) return fail("write failed");
    m_rowsWritten += rows;
    return Ok{};
}

Status ImageStreamWriter::finish() {
    assert(m_impl && m_impl->open() && "ImageStreamWriter::finish(): already finished or failed");
    assert(m_rowsWritten == m_height && "ImageStreamWriter::finish(): rows missing");
    if (m_impl->png) {
        if (!pngEnd(m_impl->png)) return fail("write failed");
        png_destroy_write_struct(&m_impl->png, &m_impl->info);
        m_impl->png = nullptr;
        const bool closed = std::fclose(m_impl->file) == 0;
        m_impl->file = nullptr;
        if (!closed) {
            discardTemporary(m_impl->tmp);
            return fileError(m_impl->path.string(), "write failed (disk full?)");
        }
    } else {
        if (!m_impl->out->close()) return fail("write failed");
        m_impl->out.reset();
    }
    std::string err;
    if (!commitTemporary(m_impl->tmp, m_impl->path, err)) return fileError(m_impl->path.string(), err);
    return Ok{};
}

} // namespace seasonview
