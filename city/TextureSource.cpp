#include "TextureSource.h"
#include "Raster.h"

#include "AtlasCodec.h"
#include "ParallelIndices.h"

#include <OpenImageIO/imageio.h>
#include <glm/common.hpp>

#include <algorithm>
#include <cmath>
#include <optional>

namespace seasonview::city {

std::uint64_t SourceTexture::bytes() const {
    std::uint64_t n = 0;
    for (const auto& m : mips) n += m.size();
    return n;
}

namespace {

glm::vec4 bilinear(const std::vector<std::uint8_t>& img, glm::ivec2 size, glm::dvec2 uv, bool repeat) {
    const double fx = uv.x * size.x - 0.5, fy = uv.y * size.y - 0.5;
    const double x0f = std::floor(fx), y0f = std::floor(fy);
    const float ax = float(fx - x0f), ay = float(fy - y0f);
    auto wrap = [&](long long v, int n) {
        if (repeat) {
            const long long m = v % n;
            return int(m < 0 ? m + n : m);
        }
        return int(std::clamp<long long>(v, 0, n - 1));
    };
    const long long x0 = (long long)x0f, y0 = (long long)y0f;
    const int xs[2] = {wrap(x0, size.x), wrap(x0 + 1, size.x)};
    const int ys[2] = {wrap(y0, size.y), wrap(y0 + 1, size.y)};
    glm::vec4 acc(0.0f);
    for (int j = 0; j < 2; ++j)
        for (int i = 0; i < 2; ++i) {
            const float w = (i ? ax : 1.0f - ax) * (j ? ay : 1.0f - ay);
            const std::uint8_t* p = &img[(std::size_t(ys[j]) * std::size_t(size.x) + std::size_t(xs[i])) * 4];
            acc += w * glm::vec4(p[0], p[1], p[2], p[3]);
        }
    return acc;
}

} // namespace

glm::vec4 SourceTexture::sample(glm::dvec2 uv, double texelsPerSample) const {
    const double lod = std::clamp(std::log2(std::max(texelsPerSample, 1.0)), double(firstLevel), double(mips.size() - 1));
    const int l0 = int(std::floor(lod));
    const int l1 = std::min(l0 + 1, int(mips.size()) - 1);
    const float f = float(lod - l0);
    const glm::vec4 a = bilinear(mips[std::size_t(l0)], sizes[std::size_t(l0)], uv, repeat);
    if (f <= 0.0f || l1 == l0) return a;
    return a * (1.0f - f) + bilinear(mips[std::size_t(l1)], sizes[std::size_t(l1)], uv, repeat) * f;
}

Result<SourceTexture> readSourceTexture(const CityTexture& texture) {
    auto in = OIIO::ImageInput::open(texture.path);
    if (!in) return fileError(texture.path, "cannot open texture: " + firstLine(OIIO::geterror()));
    const OIIO::ImageSpec spec = in->spec();
    if (spec.width <= 0 || spec.height <= 0 || spec.nchannels < 1) return fileError(texture.path, "empty texture");
    const std::uint64_t bytes = std::uint64_t(spec.width) * std::uint64_t(spec.height) * std::uint64_t(spec.nchannels);
    if (bytes > kMaxWholeImageBytes)
        return fileError(texture.path, "texture of " + std::to_string(spec.width) + "x" + std::to_string(spec.height) +
                                           " is over the limit of " + std::to_string(kMaxWholeImageBytes >> 20) + " MiB");
    std::vector<std::uint8_t> px(bytes);
    // A decoder's warning is lost data too (a JPEG cut short decodes as grey after "Premature end of JPEG file",
    // which OpenImageIO records as an error but still calls a success).
    if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::UINT8, px.data()) || in->has_error())
        return fileError(texture.path, "cannot read texture: " + firstLine(in->geterror()));
    SourceTexture t;
    t.channels = spec.nchannels >= 4 ? 4 : 3;
    t.repeat = texture.repeat;
    const int w = spec.width, h = spec.height, n = spec.nchannels;
    std::vector<std::uint8_t> rgba(std::size_t(w) * std::size_t(h) * 4);
    for (int y = 0; y < h; ++y) // flip: row 0 of the result is the image's bottom row
        for (int x = 0; x < w; ++x) {
            const std::uint8_t* s = &px[(std::size_t(h - 1 - y) * std::size_t(w) + std::size_t(x)) * std::size_t(n)];
            std::uint8_t* d = &rgba[(std::size_t(y) * std::size_t(w) + std::size_t(x)) * 4];
            d[0] = s[0];
            d[1] = n >= 3 ? s[1] : s[0];
            d[2] = n >= 3 ? s[2] : s[0];
            d[3] = n >= 4 ? s[3] : (n == 2 ? s[1] : 255);
        }
    t.mips.push_back(std::move(rgba));
    t.sizes.push_back({w, h});
    addBoxMips(t);
    return t;
}

void addBoxMips(SourceTexture& t) {
    while (t.sizes.back().x > 1 || t.sizes.back().y > 1) {
        const glm::ivec2 s = t.sizes.back();
        t.mips.push_back(halveRgbaBox(t.mips.back(), s));
        t.sizes.push_back(glm::max(s / 2, glm::ivec2(1)));
    }
}

std::vector<std::uint8_t> halveRgbaBox(const std::vector<std::uint8_t>& src, glm::ivec2 s) {
    const glm::ivec2 d = glm::max(s / 2, glm::ivec2(1));
    std::vector<std::uint8_t> dst(std::size_t(d.x) * std::size_t(d.y) * 4);
    for (int y = 0; y < d.y; ++y)
        for (int x = 0; x < d.x; ++x)
            for (int c = 0; c < 4; ++c) {
                int sum = 0, cnt = 0;
                for (int yy = 2 * y; yy < std::min(2 * y + 2 + (y == d.y - 1 ? s.y % 2 : 0), s.y); ++yy)
                    for (int xx = 2 * x; xx < std::min(2 * x + 2 + (x == d.x - 1 ? s.x % 2 : 0), s.x); ++xx) {
                        sum += src[(std::size_t(yy) * std::size_t(s.x) + std::size_t(xx)) * 4 + std::size_t(c)];
                        ++cnt;
                    }
                dst[(std::size_t(y) * std::size_t(d.x) + std::size_t(x)) * 4 + std::size_t(c)] =
                    std::uint8_t((sum + cnt / 2) / std::max(cnt, 1));
            }
    return dst;
}

TextureCache::TextureCache(const std::vector<CityTexture>& textures, std::uint64_t capacityBytes)
    : TextureCache([&textures](int t) { return readSourceTexture(textures[std::size_t(t)]); }, capacityBytes) {}

TextureCache::TextureCache(std::function<Result<SourceTexture>(int)> read, std::uint64_t capacityBytes)
    : m_read(std::move(read)), m_capacity(capacityBytes) {}

void TextureCache::insert(int texture, std::shared_ptr<const SourceTexture> ptr) {
    ++m_reads;
    m_bytes += ptr->bytes();
    m_lru.push_front(texture);
    m_entries.emplace(texture, Entry{std::move(ptr), m_lru.begin()});
    m_peak = std::max(m_peak, m_bytes);
    while (m_bytes > m_capacity && m_lru.size() > 1) {
        const int victim = m_lru.back();
        m_lru.pop_back();
        m_bytes -= m_entries[victim].tex->bytes();
        m_entries.erase(victim);
    }
}

void TextureCache::dropFinerMips(int texture, SourceTexture& t) const {
    if (std::size_t(texture) >= m_finest.size() || m_finest[std::size_t(texture)] <= 0) return;
    t.firstLevel = std::min(m_finest[std::size_t(texture)], int(t.mips.size()) - 1);
    for (int l = 0; l < t.firstLevel; ++l) std::vector<std::uint8_t>().swap(t.mips[std::size_t(l)]);
}

Result<std::shared_ptr<const SourceTexture>> TextureCache::get(int texture) {
    if (auto it = m_entries.find(texture); it != m_entries.end()) {
        m_lru.splice(m_lru.begin(), m_lru, it->second.pos);
        return it->second.tex;
    }
    auto t = m_read(texture);
    if (!t) return t.error();
    dropFinerMips(texture, *t);
    auto ptr = std::make_shared<const SourceTexture>(std::move(*t));
    insert(texture, ptr);
    return ptr;
}

Status TextureCache::prefetch(const std::vector<int>& textures, int threads) {
    std::vector<int> missing;
    for (int t : textures)
        if (!m_entries.count(t) && std::find(missing.begin(), missing.end(), t) == missing.end()) missing.push_back(t);
    std::vector<std::optional<Result<SourceTexture>>> read(missing.size());
    parallelIndices(int(missing.size()), threads,
                    [&](int i, int) {
                        const int texture = missing[std::size_t(i)];
                        read[std::size_t(i)] = m_read(texture);
                        // On the worker, at once: a batch holds the reduced textures, not their full mips.
                        if (*read[std::size_t(i)]) dropFinerMips(texture, read[std::size_t(i)]->value());
                    });
    for (std::size_t i = 0; i < missing.size(); ++i) {
        if (!*read[i]) return read[i]->error();
        insert(missing[i], std::make_shared<const SourceTexture>(std::move(read[i]->value())));
    }
    return Ok{};
}

} // namespace seasonview::city
