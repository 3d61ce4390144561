#include "AtlasCodec.h"

#include "ParallelIndices.h"
#include "TextureSource.h"

#include <cstring>

#define STB_DXT_IMPLEMENTATION
#define STB_DXT_STATIC
#include <stb/stb_dxt.h>

#include <libdeflate.h>

#include <algorithm>
#include <cstring>
#include <memory>

namespace seasonview::city {

const char* atlasFormatName(AtlasFormat f) { return f == AtlasFormat::Bc ? "bc" : "deflate"; }

int atlasLevels(int size) {
    int n = 1;
    while (size > 4) {
        size /= 2;
        ++n;
    }
    return n;
}

std::uint64_t atlasLevelBytes(AtlasFormat format, bool alpha, int size, int level) {
    const std::uint64_t s = std::uint64_t(std::max(4, size >> level));
    if (format == AtlasFormat::Bc) return (s / 4) * (s / 4) * (alpha ? 16u : 8u);
    return s * s * (alpha ? 4u : 3u);
}

std::vector<std::uint8_t> halveRgba(const std::vector<std::uint8_t>& rgba, int size) {
    return halveRgbaBox(rgba, {size, size}); // the original textures' mips use the same filter
}

void dilateRgba(std::vector<std::uint8_t>& rgba, int size, const std::vector<std::uint8_t>& covered) {
    const std::size_t n = std::size_t(size) * std::size_t(size);
    std::vector<std::uint32_t> queue;
    queue.reserve(n);
    std::vector<std::uint8_t> done(covered.begin(), covered.begin() + std::ptrdiff_t(n));
    for (std::uint32_t i = 0; i < n; ++i)
        if (done[i]) queue.push_back(i);
    if (queue.empty()) return;
    for (std::size_t head = 0; head < queue.size(); ++head) {
        const std::uint32_t i = queue[head];
        const int x = int(i % std::uint32_t(size)), y = int(i / std::uint32_t(size));
        auto visit = [&](int xx, int yy) {
            if (xx < 0 || yy < 0 || xx >= size || yy >= size) return;
            const std::uint32_t j = std::uint32_t(yy) * std::uint32_t(size) + std::uint32_t(xx);
            if (done[j]) return;
            done[j] = 1;
            std::copy_n(&rgba[std::size_t(i) * 4], 4, &rgba[std::size_t(j) * 4]);
            queue.push_back(j);
        };
        visit(x - 1, y);
        visit(x + 1, y);
        visit(x, y - 1);
        visit(x, y + 1);
    }
}

namespace {

void appendBc(std::vector<std::uint8_t>& out, const std::vector<std::uint8_t>& rgba, int size, bool alpha, int threads) {
    const std::size_t stride = alpha ? 16 : 8, rowBytes = std::size_t(size / 4) * stride;
    const std::size_t at = out.size();
    out.resize(at + rowBytes * std::size_t(size / 4));
    // Rows of blocks are independent: each thread writes its own rows.
    parallelIndices(size / 4, threads, [&](int row, int) {
        std::uint8_t block[64];
        const int by = row * 4;
        for (int bx = 0; bx < size; bx += 4) {
            for (int y = 0; y < 4; ++y)
                std::memcpy(block + y * 16, &rgba[(std::size_t(by + y) * std::size_t(size) + std::size_t(bx)) * 4], 16);
            stb_compress_dxt_block(&out[at + std::size_t(row) * rowBytes + std::size_t(bx / 4) * stride], block,
                                   alpha ? 1 : 0, STB_DXT_HIGHQUAL);
        }
    });
}

void appendRaw(std::vector<std::uint8_t>& out, const std::vector<std::uint8_t>& rgba, bool alpha) {
    if (alpha) {
        out.insert(out.end(), rgba.begin(), rgba.end());
        return;
    }
    for (std::size_t i = 0; i < rgba.size(); i += 4) out.insert(out.end(), rgba.begin() + std::ptrdiff_t(i), rgba.begin() + std::ptrdiff_t(i + 3));
}

std::uint64_t chainBytes(AtlasFormat format, bool alpha, int size) {
    std::uint64_t n = 0;
    for (int l = 0; l < atlasLevels(size); ++l) n += atlasLevelBytes(format, alpha, size, l);
    return n;
}

std::vector<std::uint8_t> inflate(const std::vector<std::uint8_t>& blob, std::size_t size) {
    std::vector<std::uint8_t> raw(size);
    std::unique_ptr<libdeflate_decompressor, void (*)(libdeflate_decompressor*)> d(libdeflate_alloc_decompressor(),
                                                                                  libdeflate_free_decompressor);
    std::size_t actual = 0;
    if (!d || libdeflate_deflate_decompress(d.get(), blob.data(), blob.size(), raw.data(), raw.size(), &actual) !=
                  LIBDEFLATE_SUCCESS ||
        actual != size)
        return {};
    return raw;
}

void decodeColours(const std::uint8_t* b, std::uint8_t pal[4][4], bool forceFour) {
    const unsigned c0 = unsigned(b[0] | (b[1] << 8)), c1 = unsigned(b[2] | (b[3] << 8));
    auto expand = [](unsigned c, std::uint8_t* o) {
        o[0] = std::uint8_t(((c >> 11) & 31) * 255 / 31);
        o[1] = std::uint8_t(((c >> 5) & 63) * 255 / 63);
        o[2] = std::uint8_t((c & 31) * 255 / 31);
        o[3] = 255;
    };
    expand(c0, pal[0]);
    expand(c1, pal[1]);
    for (int k = 0; k < 3; ++k) {
        if (forceFour || c0 > c1) {
            pal[2][k] = std::uint8_t((2 * pal[0][k] + pal[1][k] + 1) / 3);
            pal[3][k] = std::uint8_t((pal[0][k] + 2 * pal[1][k] + 1) / 3);
        } else {
            pal[2][k] = std::uint8_t((pal[0][k] + pal[1][k]) / 2);
            pal[3][k] = 0;
        }
    }
    pal[2][3] = 255;
    pal[3][3] = (forceFour || c0 > c1) ? 255 : 0;
}

} // namespace

std::vector<std::uint8_t> encodeAtlas(AtlasFormat format, bool alpha, const std::vector<std::uint8_t>& rgba, int size,
                                      int threads) {
    std::vector<std::uint8_t> chain;
    chain.reserve(chainBytes(format, alpha, size));
    std::vector<std::uint8_t> level = rgba;
    int s = size;
    for (int l = 0; l < atlasLevels(size); ++l) {
        if (format == AtlasFormat::Bc) appendBc(chain, level, s, alpha, s >= 64 ? threads : 1);
        else appendRaw(chain, level, alpha);
        if (l + 1 < atlasLevels(size)) {
            level = halveRgba(level, s);
            s /= 2;
        }
    }
    if (format == AtlasFormat::Bc) return chain;
    std::unique_ptr<libdeflate_compressor, void (*)(libdeflate_compressor*)> c(libdeflate_alloc_compressor(6),
                                                                              libdeflate_free_compressor);
    std::vector<std::uint8_t> out(libdeflate_deflate_compress_bound(c.get(), chain.size()));
    out.resize(libdeflate_deflate_compress(c.get(), chain.data(), chain.size(), out.data(), out.size()));
    return out;
}

std::vector<std::uint8_t> atlasLevelData(AtlasFormat format, bool alpha, const std::vector<std::uint8_t>& blob,
                                         int size, int level) {
    std::uint64_t offset = 0;
    for (int l = 0; l < level; ++l) offset += atlasLevelBytes(format, alpha, size, l);
    const std::uint64_t n = atlasLevelBytes(format, alpha, size, level);
    if (format == AtlasFormat::Bc) {
        if (blob.size() != chainBytes(format, alpha, size)) return {};
        return {blob.begin() + std::ptrdiff_t(offset), blob.begin() + std::ptrdiff_t(offset + n)};
    }
    const auto raw = inflate(blob, chainBytes(format, alpha, size));
    if (raw.empty()) return {};
    return {raw.begin() + std::ptrdiff_t(offset), raw.begin() + std::ptrdiff_t(offset + n)};
}

std::vector<std::uint8_t> decodeBc(const std::uint8_t* blocks, int size, bool alpha) {
    std::vector<std::uint8_t> out(std::size_t(size) * std::size_t(size) * 4);
    const std::size_t stride = alpha ? 16 : 8;
    std::size_t b = 0;
    for (int by = 0; by < size; by += 4)
        for (int bx = 0; bx < size; bx += 4, ++b) {
            const std::uint8_t* blk = blocks + b * stride;
            std::uint8_t a[16];
            std::fill(a, a + 16, std::uint8_t(255));
            if (alpha) {
                std::uint8_t ap[8];
                ap[0] = blk[0];
                ap[1] = blk[1];
                for (int k = 2; k < 8; ++k)
                    ap[k] = ap[0] > ap[1] ? std::uint8_t(((8 - k) * ap[0] + (k - 1) * ap[1]) / 7)
                                          : (k < 6 ? std::uint8_t(((6 - k) * ap[0] + (k - 1) * ap[1]) / 5)
                                                   : std::uint8_t(k == 6 ? 0 : 255));
                std::uint64_t bits = 0;
                for (int k = 0; k < 6; ++k) bits |= std::uint64_t(blk[2 + k]) << (8 * k);
                for (int k = 0; k < 16; ++k) a[k] = ap[(bits >> (3 * k)) & 7];
                blk += 8;
            }
            std::uint8_t pal[4][4];
            decodeColours(blk, pal, alpha);
            const std::uint32_t idx = std::uint32_t(blk[4] | (blk[5] << 8) | (blk[6] << 16) | (std::uint32_t(blk[7]) << 24));
            for (int k = 0; k < 16; ++k) {
                const int x = bx + (k % 4), y = by + (k / 4);
                std::uint8_t* o = &out[(std::size_t(y) * std::size_t(size) + std::size_t(x)) * 4];
                const std::uint8_t* c = pal[(idx >> (2 * k)) & 3];
                o[0] = c[0];
                o[1] = c[1];
                o[2] = c[2];
                o[3] = alpha ? a[k] : c[3];
            }
        }
    return out;
}

std::vector<std::uint8_t> decodeAtlasRgba(AtlasFormat format, bool alpha, const std::vector<std::uint8_t>& blob, int size) {
    const auto level = atlasLevelData(format, alpha, blob, size, 0);
    if (level.empty()) return {};
    if (format == AtlasFormat::Bc) return decodeBc(level.data(), size, alpha);
    if (alpha) return level;
    std::vector<std::uint8_t> out(std::size_t(size) * std::size_t(size) * 4, 255);
    for (std::size_t i = 0, j = 0; i < level.size(); i += 3, j += 4) std::memcpy(&out[j], &level[i], 3);
    return out;
}

} // namespace seasonview::city
