#pragma once
// The resampling kernel of GridReader's warp for nearest and bilinear (what its auto resampling picks for tiles on
// the grid's lattice and for tiles at most 1.5 times finer): plain C++, no GDAL. Where each output pixel samples its
// source comes from a lattice of exact PROJ transformations, interpolated in between; the taps are weighted by the
// source's validity (nodata, alpha, mask), so no data never bleeds into data. GDAL's general warp kernel, which it
// takes as soon as a source has a mask and the destination an alpha band, was 2-3 times slower on the same work
// (README); GridReader keeps GDAL's warper for average, cubic and lanczos.
#include <glm/vec2.hpp>

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

namespace seasonview {

/// Source pixel coordinates (continuous, top-left corner origin) of the centres of output pixels [x0, x1) × [y0, y1),
/// exact on a lattice of `step` pixels and bilinear in between.
class SourceLattice {
public:
    /// `map` converts output pixel-centre coordinates to source pixel coordinates in place (NaN where it cannot).
    /// The step starts at 32 pixels and is halved (down to 2) until the interpolation is within `maxError` source
    /// pixels at every cell's centre.
    static SourceLattice build(int x0, int y0, int x1, int y1, const std::function<void(std::span<glm::dvec2>)>& map,
                               double maxError = 0.05);
    /// The source coordinates of output pixel (x, y)'s centre.
    glm::dvec2 at(int x, int y) const;
    /// The bounding box of every lattice point (source pixels); empty (min > max) when none is finite.
    glm::dvec2 min() const { return m_min; }
    glm::dvec2 max() const { return m_max; }
    int step() const { return m_step; }

private:
    int m_x0 = 0, m_y0 = 0, m_cols = 0, m_rows = 0, m_step = 32;
    std::vector<glm::dvec2> m_points; // (m_rows + 1) × (m_cols + 1)
    glm::dvec2 m_min{0.0}, m_max{-1.0};
};

/// A window of a source raster: interleaved samples and a validity byte per pixel (non-zero: data).
template <typename T> struct SourceWindow {
    int x0 = 0, y0 = 0, width = 0, height = 0, channels = 0; // in source pixels
    std::vector<T> samples;
    std::vector<std::uint8_t> valid;
};

/// Resamples output rows [y0, y1), columns [x0, x1) from `src` (nearest, or bilinear weighted by validity: the mean of
/// the valid taps' weights must reach one half) into `out` (rows of `outWidth` pixels × src.channels samples, row 0
/// of `out` is output row `outRow0`, its column 0 output column `outCol0`) and sets `coverage` to 255 where the source had data, over whatever an earlier
/// source wrote there; elsewhere both are left as they are. Parallel over rows on `threads` threads.
template <typename T>
void resampleWindow(const SourceLattice& lattice, const SourceWindow<T>& src, bool bilinear, int x0, int y0, int x1,
                    int y1, T* out, std::uint8_t* coverage, int outWidth, int outRow0, int outCol0, int threads);

extern template void resampleWindow<std::uint8_t>(const SourceLattice&, const SourceWindow<std::uint8_t>&, bool, int,
                                                  int, int, int, std::uint8_t*, std::uint8_t*, int, int, int, int);
extern template void resampleWindow<std::uint16_t>(const SourceLattice&, const SourceWindow<std::uint16_t>&, bool, int,
                                                   int, int, int, std::uint16_t*, std::uint8_t*, int, int, int, int);
extern template void resampleWindow<float>(const SourceLattice&, const SourceWindow<float>&, bool, int, int, int, int,
                                           float*, std::uint8_t*, int, int, int, int);

} // namespace seasonview
