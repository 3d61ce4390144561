#include "Plot.h"

#include "Raster.h"

#include <stb/stb_easy_font.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace seasonview::app {

namespace {

using Rgb = std::array<std::uint8_t, 3>;
const Rgb kColors[] = {{214, 39, 40}, {31, 119, 180}, {44, 160, 44}, {255, 127, 14}, {148, 103, 189}, {23, 190, 207}};

struct Canvas {
    int w, h;
    std::vector<std::uint8_t> px;
    Canvas(int width, int height) : w(width), h(height), px(size_t(width) * size_t(height) * 3, 255) {}
    void set(int x, int y, Rgb c) {
        if (x < 0 || y < 0 || x >= w || y >= h) return;
        std::copy(c.begin(), c.end(), px.begin() + std::ptrdiff_t((size_t(y) * size_t(w) + size_t(x)) * 3));
    }
    void rect(int x0, int y0, int x1, int y1, Rgb c) {
        for (int y = std::max(0, y0); y < std::min(h, y1); ++y)
            for (int x = std::max(0, x0); x < std::min(w, x1); ++x) set(x, y, c);
    }
    void line(double x0, double y0, double x1, double y1, Rgb c) {
        const int n = int(std::max(std::fabs(x1 - x0), std::fabs(y1 - y0))) + 1;
        for (int i = 0; i <= n; ++i) {
            const double t = double(i) / n;
            const int x = int(std::lround(x0 + (x1 - x0) * t)), y = int(std::lround(y0 + (y1 - y0) * t));
            set(x, y, c);
            set(x, y + 1, c); // 2 px wide
        }
    }
    // stb_easy_font: quads of 4 vertices (x, y, z, rgba) in pixels; drawn at `scale`.
    void text(int x, int y, const std::string& s, Rgb c, int scale = 2) {
        static char buffer[60000];
        const int quads = stb_easy_font_print(0, 0, const_cast<char*>(s.c_str()), nullptr, buffer, sizeof buffer);
        for (int q = 0; q < quads; ++q) {
            const float* v0 = reinterpret_cast<const float*>(buffer + q * 64);
            const float* v2 = reinterpret_cast<const float*>(buffer + q * 64 + 32);
            rect(x + int(v0[0]) * scale, y + int(v0[1]) * scale, x + int(v2[0]) * scale, y + int(v2[1]) * scale, c);
        }
    }
};

std::string fmt(double v) {
    char b[32];
    if (std::fabs(v) >= 1e6) std::snprintf(b, sizeof b, "%.3gM", v / 1e6);
    else if (std::fabs(v) >= 1e4) std::snprintf(b, sizeof b, "%.3gk", v / 1e3);
    else if (std::fabs(v) >= 100 || v == std::floor(v)) std::snprintf(b, sizeof b, "%.0f", v);
    else std::snprintf(b, sizeof b, "%.2g", v);
    return b;
}

} // namespace

Status writeLinePlot(const std::filesystem::path& out, const std::vector<PlotPanel>& panels, const std::string& xLabel,
                     int width, int height) {
    Canvas cv(width, height);
    const int left = 90, right = 300, top = 20, bottom = 50, gap = 40;
    const int panelH = (height - top - bottom - gap * int(panels.size() - 1)) / std::max<int>(1, int(panels.size()));
    const Rgb black{0, 0, 0}, grey{225, 225, 225};
    size_t samples = 0;
    for (const auto& p : panels)
        for (const auto& s : p.series) samples = std::max(samples, s.y.size());
    for (size_t pi = 0; pi < panels.size(); ++pi) {
        const PlotPanel& p = panels[pi];
        const int y0 = top + int(pi) * (panelH + gap), y1 = y0 + panelH, x0 = left, x1 = width - right;
        double lo = p.yMin, hi = p.yMax;
        if (hi < lo) {
            lo = 0.0;
            hi = 0.0;
            for (const auto& s : p.series)
                for (double v : s.y)
                    if (std::isfinite(v)) hi = std::max(hi, v);
            hi = hi > 0 ? hi * 1.1 : 1.0;
        }
        for (int g = 0; g <= 4; ++g) { // grid and y labels
            const int y = y1 - (y1 - y0) * g / 4;
            cv.rect(x0, y, x1, y + 1, grey);
            cv.text(8, y - 6, fmt(lo + (hi - lo) * g / 4.0), black);
        }
        cv.rect(x0, y0, x0 + 1, y1, black);
        cv.rect(x0, y1, x1, y1 + 1, black);
        cv.text(x0 + 8, y0 + 4, p.title, black);
        for (size_t si = 0; si < p.series.size(); ++si) {
            const Rgb c = kColors[si % 6];
            const auto& y = p.series[si].y;
            auto px = [&](size_t i) { return x0 + double(x1 - x0) * double(i) / double(std::max<size_t>(1, samples - 1)); };
            auto py = [&](double v) { return y1 - double(y1 - y0) * std::clamp((v - lo) / (hi - lo), 0.0, 1.0); };
            // Measured samples joined in order across unmeasured ones (coverage every 100th frame), each marked with
            // a dot where the series has gaps, so sparse samples show too.
            const bool sparse = std::any_of(y.begin(), y.end(), [](double v) { return !std::isfinite(v); });
            std::size_t last = y.size();
            for (size_t i = 0; i < y.size(); ++i) {
                if (!std::isfinite(y[i])) continue;
                if (last < y.size()) cv.line(px(last), py(y[last]), px(i), py(y[i]), c);
                if (sparse) {
                    const int cx = int(std::lround(px(i))), cy = int(std::lround(py(y[i])));
                    cv.rect(cx - 1, cy - 1, cx + 2, cy + 2, c);
                }
                last = i;
            }
            cv.rect(x1 + 12, y0 + 10 + int(si) * 22, x1 + 32, y0 + 22 + int(si) * 22, c);
            cv.text(x1 + 38, y0 + 8 + int(si) * 22, p.series[si].label, black);
        }
    }
    cv.text(left, height - 30, xLabel + " (0 .. " + std::to_string(samples > 0 ? samples - 1 : 0) + ")", black);
    return writeImageAtomic(out, cv.px.data(), width, height, 3);
}

} // namespace seasonview::app
