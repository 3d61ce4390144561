#pragma once
// Single pixels of a raster, read on demand through GDAL (its block cache keeps the tile around, so probing nearby
// pixels again is cheap): what the viewer's HUD asks under the cursor.
#include "Result.h"

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

namespace seasonview {

class PixelProbe {
public:
    /// Opens `path` for probing. Errors name the file.
    static Result<PixelProbe> open(const std::filesystem::path& path);
    PixelProbe(PixelProbe&&) noexcept;
    PixelProbe& operator=(PixelProbe&&) noexcept;
    ~PixelProbe();

    int width() const { return m_width; }
    int height() const { return m_height; }
    int bands() const { return m_bands; }
    /// Every band of pixel (x, y) as 8-bit samples (converted numerically); nothing outside the raster or when the
    /// read fails.
    std::optional<std::vector<std::uint8_t>> at(int x, int y) const;

private:
    PixelProbe() = default;
    struct Impl;
    std::unique_ptr<Impl> m_impl;
    int m_width = 0, m_height = 0, m_bands = 0;
};

} // namespace seasonview
