#include "PixelProbe.h"

#include "GdalSupport.h"

namespace seasonview {

struct PixelProbe::Impl {
    gdal::Dataset ds;
};

PixelProbe::PixelProbe(PixelProbe&&) noexcept = default;
PixelProbe& PixelProbe::operator=(PixelProbe&&) noexcept = default;
PixelProbe::~PixelProbe() = default;

Result<PixelProbe> PixelProbe::open(const std::filesystem::path& path) {
    auto ds = gdal::openRaster(path);
    if (!ds) return ds.error();
    PixelProbe p;
    p.m_impl = std::make_unique<Impl>();
    p.m_impl->ds = std::move(*ds);
    p.m_width = p.m_impl->ds->GetRasterXSize();
    p.m_height = p.m_impl->ds->GetRasterYSize();
    p.m_bands = p.m_impl->ds->GetRasterCount();
    return p;
}

std::optional<std::vector<std::uint8_t>> PixelProbe::at(int x, int y) const {
    if (x < 0 || y < 0 || x >= m_width || y >= m_height) return std::nullopt;
    std::vector<std::uint8_t> v(static_cast<size_t>(m_bands));
    gdal::ErrorCapture quiet;
    if (m_impl->ds->RasterIO(GF_Read, x, y, 1, 1, v.data(), 1, 1, GDT_Byte, m_bands, nullptr, m_bands, m_bands, 1,
                             nullptr) != CE_None)
        return std::nullopt;
    return v;
}

} // namespace seasonview
