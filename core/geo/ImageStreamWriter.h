#pragma once
// Streams an 8-bit image (format by extension: PNG through libpng, TIFF and the rest through OpenImageIO) top to
// bottom, a band of rows at a time, so that an image larger than memory can be written. A failed write (a full
// disk) is an error. Written to a temporary name next to the target and
// renamed by finish(): a failed or abandoned image never appears under its final name. For PNG the file does not
// depend on how the rows are split between writeRows() calls. Masks can be written fast (ImageEncoding::FastMask).
#include "Result.h"

#include <cstdint>
#include <filesystem>
#include <memory>

namespace seasonview {

/// How an image is compressed; the pixels are the same either way.
enum class ImageEncoding {
    Default,  // PNG: adaptive row filters, zlib level 6 (OpenImageIO's defaults), through libpng; other formats: OpenImageIO
    FastMask, // for images of long runs of a few values (masks): PNG written by libpng with no row filter and zlib's
              // run-length strategy at level 1, 3-5x faster than Default and smaller for masks; TIFF: deflate level 1
};

class ImageStreamWriter {
public:
    /// Creates the temporary file for a width×height image of `channels` 8-bit channels. Errors name the file
    /// (unsupported extension, cannot create).
    static Result<ImageStreamWriter> open(const std::filesystem::path& path, int width, int height, int channels,
                                          ImageEncoding encoding = ImageEncoding::Default);

    ImageStreamWriter(ImageStreamWriter&& other) noexcept;
    ImageStreamWriter& operator=(ImageStreamWriter&& other) noexcept;
    ImageStreamWriter(const ImageStreamWriter&) = delete;
    ImageStreamWriter& operator=(const ImageStreamWriter&) = delete;
    /// Without finish(), closes and deletes the temporary file.
    ~ImageStreamWriter();

    /// Appends rows [y0, y0 + rows): y0 must be rowsWritten(), y0 + rows at most the height. `data` holds rows ×
    /// width × channels bytes, row 0 of the band first.
    Status writeRows(int y0, int rows, const std::uint8_t* data);

    /// Closes the file and renames it to its final name. Call once, after all rows.
    Status finish();

    int rowsWritten() const { return m_rowsWritten; }

private:
    struct Impl; // the OpenImageIO or libpng output, kept out of this header
    ImageStreamWriter();
    Status fail(const std::string& what);
    void abandon();

    std::unique_ptr<Impl> m_impl;
    int m_width = 0, m_height = 0, m_channels = 0, m_rowsWritten = 0;
};

} // namespace seasonview
