#include "BandReader.h"

#include <OpenImageIO/imageio.h>

#include <algorithm>

namespace seasonview {

struct BandReader::Input {
    std::unique_ptr<OIIO::ImageInput> in;
};

BandReader::BandReader(BandReader&&) noexcept = default;
BandReader& BandReader::operator=(BandReader&&) noexcept = default;
BandReader::~BandReader() = default;

Result<BandReader> BandReader::open(const std::filesystem::path& path, int preferredRows) {
    BandReader r;
    r.m_path = path;
    r.m_in = std::make_unique<Input>();
    r.m_in->in = OIIO::ImageInput::open(path.string());
    if (!r.m_in->in) {
        std::error_code ec;
        if (!std::filesystem::exists(path, ec)) return fileError(path.string(), "file not found");
        const std::string e = firstLine(OIIO::geterror());
        return fileError(path.string(), "not a readable image" + (e.empty() ? std::string() : " (" + e + ")"));
    }
    const OIIO::ImageSpec& spec = r.m_in->in->spec();
    r.m_width = spec.width;
    r.m_height = spec.height;
    r.m_channels = spec.nchannels;
    switch (spec.format.basetype) {
    case OIIO::TypeDesc::UINT8: r.m_type = SampleType::U8; break;
    case OIIO::TypeDesc::UINT16: r.m_type = SampleType::U16; break;
    case OIIO::TypeDesc::INT16: r.m_type = SampleType::I16; break;
    case OIIO::TypeDesc::FLOAT: r.m_type = SampleType::F32; break;
    default: return fileError(path.string(), std::string("unsupported sample type ") + spec.format.c_str());
    }
    if (spec.tile_width > 0 && spec.tile_height > 0 && spec.tile_depth <= 1) {
        r.m_tileHeight = spec.tile_height;
        r.m_bandRows = r.m_tileHeight * std::max(1, preferredRows / r.m_tileHeight);
    } else {
        r.m_bandRows = std::max(1, preferredRows);
    }
    return r;
}

Status BandReader::read(int y0, int y1, int channels, SampleType type, void* out) const {
    assert((type == SampleType::U8 || type == SampleType::U16) && "BandReader::read(): 8- or 16-bit only");
    const OIIO::TypeDesc t = type == SampleType::U16 ? OIIO::TypeDesc::UINT16 : OIIO::TypeDesc::UINT8;
    OIIO::ImageInput& in = *m_in->in;
    const bool ok = m_tileHeight > 0 ? in.read_tiles(0, 0, 0, m_width, y0, y1, 0, 1, 0, channels, t, out)
                                     : in.read_scanlines(0, 0, y0, y1, 0, 0, channels, t, out);
    if (ok) return Ok{};
    const std::string e = firstLine(in.geterror());
    return fileError(m_path.string(), "truncated or corrupt image data" + (e.empty() ? std::string() : " (" + e + ")"));
}

} // namespace seasonview
