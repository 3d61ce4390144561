#include "ImageStreamWriter.h"

#include "AtomicFile.h"

#include <OpenImageIO/imageio.h>

#include <cassert>

namespace seasonview {

struct ImageStreamWriter::Impl {
    std::filesystem::path path, tmp;
    std::unique_ptr<OIIO::ImageOutput> out;
};

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
    if (!m_impl || !m_impl->out) return;
    m_impl->out->close();
    m_impl->out.reset();
    discardTemporary(m_impl->tmp);
}

Status ImageStreamWriter::fail(const std::string& what) {
    const std::string e = m_impl->out ? firstLine(m_impl->out->geterror()) : std::string();
    abandon();
    return fileError(m_impl->path.string(), what + (e.empty() ? std::string() : " (" + e + ")"));
}

Result<ImageStreamWriter> ImageStreamWriter::open(const std::filesystem::path& path, int width, int height,
                                                  int channels) {
    assert(width > 0 && height > 0 && channels > 0 && "ImageStreamWriter::open(): empty image");
    ImageStreamWriter w;
    w.m_impl = std::make_unique<Impl>();
    w.m_impl->path = path;
    w.m_impl->tmp = temporaryPathFor(path);
    w.m_width = width;
    w.m_height = height;
    w.m_channels = channels;
    w.m_impl->out = OIIO::ImageOutput::create(path.string());
    if (!w.m_impl->out) return fileError(path.string(), "unsupported output image format (use .png or .tif)");
    const OIIO::ImageSpec spec(width, height, channels, OIIO::TypeDesc::UINT8);
    if (!w.m_impl->out->open(w.m_impl->tmp.string(), spec)) {
        std::string e = firstLine(w.m_impl->out->geterror());
        w.m_impl->out.reset();
        return fileError(path.string(), "cannot create file" + (e.empty() ? std::string() : " (" + e + ")"));
    }
    return w;
}

Status ImageStreamWriter::writeRows(int y0, int rows, const std::uint8_t* data) {
    assert(m_impl && m_impl->out && "ImageStreamWriter::writeRows(): the file is finished or failed");
    assert(y0 == m_rowsWritten && rows >= 0 && y0 + rows <= m_height &&
           "ImageStreamWriter::writeRows(): rows must follow the rows written so far, within the image");
    if (rows == 0) return Ok{};
    if (!m_impl->out->write_scanlines(y0, y0 + rows, 0, OIIO::TypeDesc::UINT8, data)) return fail("write failed");
    m_rowsWritten += rows;
    return Ok{};
}

Status ImageStreamWriter::finish() {
    assert(m_impl && m_impl->out && "ImageStreamWriter::finish(): already finished or failed");
    assert(m_rowsWritten == m_height && "ImageStreamWriter::finish(): rows missing");
    if (!m_impl->out->close()) return fail("write failed");
    m_impl->out.reset();
    std::string err;
    if (!commitTemporary(m_impl->tmp, m_impl->path, err)) return fileError(m_impl->path.string(), err);
    return Ok{};
}

} // namespace seasonview
