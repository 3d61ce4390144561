#include "ZstdTileCheck.h"

#include "TiffSupport.h"

#include <libdeflate.h>
#include <tiffio.h>
#include <zstd.h>

#include <algorithm>

namespace seasonview {

namespace {
// A skippable frame's magic number is 0x184D2A50..0x184D2A5F (RFC 8878 §3.1.2); ours, then the content's size.
constexpr std::uint32_t kSkippableMagic = 0x184D2A5E;
constexpr std::uint8_t kTag[4] = {'S', 'V', 'C', '1'};

void putLe32(std::uint8_t* p, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) p[i] = std::uint8_t(v >> (8 * i));
}
std::uint32_t getLe32(const std::uint8_t* p) {
    return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}
} // namespace

void appendTileChecksum(std::vector<std::uint8_t>& tile) {
    const std::uint32_t crc = libdeflate_crc32(0, tile.data(), tile.size());
    const size_t at = tile.size();
    tile.resize(at + kTileChecksumBytes);
    std::uint8_t* t = tile.data() + at;
    putLe32(t, kSkippableMagic);
    putLe32(t + 4, 8);
    std::copy(std::begin(kTag), std::end(kTag), t + 8);
    putLe32(t + 12, crc);
}

TileChecksum verifyTileChecksum(const std::uint8_t* tile, std::size_t bytes) {
    if (bytes < kTileChecksumBytes) return TileChecksum::Absent;
    const std::uint8_t* t = tile + bytes - kTileChecksumBytes;
    if (getLe32(t) != kSkippableMagic || getLe32(t + 4) != 8 || !std::equal(std::begin(kTag), std::end(kTag), t + 8))
        return TileChecksum::Absent;
    return libdeflate_crc32(0, tile, bytes - kTileChecksumBytes) == getLe32(t + 12) ? TileChecksum::Matches
                                                                                    : TileChecksum::Differs;
}

struct ZstdTileCheck::Decoder {
    struct Free {
        void operator()(ZSTD_DCtx* d) const { ZSTD_freeDCtx(d); }
    };
    std::unique_ptr<ZSTD_DCtx, Free> context{ZSTD_createDCtx()};
    std::vector<std::uint8_t> compressed, decoded;
};

ZstdTileCheck::ZstdTileCheck() : m_decoder(std::make_unique<Decoder>()) {}
ZstdTileCheck::~ZstdTileCheck() = default;

Status ZstdTileCheck::check(const std::filesystem::path& file, int x0, int y0, int x1, int y1) {
    if (x1 <= x0 || y1 <= y0) return Ok{};
    std::lock_guard<std::mutex> lock(m_mutex);
    std::error_code ec;
    const std::uintmax_t bytes = std::filesystem::file_size(file, ec);
    const auto modified = std::filesystem::last_write_time(file, ec);
    auto it = m_files.find(file.string());
    if (it != m_files.end() && (it->second.bytes != bytes || it->second.modified != modified)) {
        m_files.erase(it);
        it = m_files.end();
    }
    // The file is opened only when a tile of the rectangle has not been checked yet (or the file is new here).
    TIFF* tif = nullptr;
    struct Close {
        TIFF*& t;
        ~Close() {
            if (t) TIFFClose(t);
        }
    } closer{tif};
    std::string error;
    // "m": raw tiles read with read() rather than copied out of a mapping, whose page faults cost more than the copy
    // (docs/performance.md, step 12).
    const auto open = [&]() -> Status {
        if (!tif && !(tif = tiff::open(file, "rm", &error))) return fileError(file.string(), "cannot open (" + error + ")");
        return Ok{};
    };
    if (it == m_files.end()) {
        if (auto st = open(); !st) return st;
        File n;
        n.bytes = bytes;
        n.modified = modified;
        std::uint16_t compression = COMPRESSION_NONE;
        std::uint32_t width = 0, height = 0, tw = 0, th = 0;
        TIFFGetFieldDefaulted(tif, TIFFTAG_COMPRESSION, &compression);
        n.zstd = compression == COMPRESSION_ZSTD && TIFFIsTiled(tif) && TIFFGetField(tif, TIFFTAG_TILEWIDTH, &tw) &&
                 TIFFGetField(tif, TIFFTAG_TILELENGTH, &th) && TIFFGetField(tif, TIFFTAG_IMAGEWIDTH, &width) &&
                 TIFFGetField(tif, TIFFTAG_IMAGELENGTH, &height) && tw > 0 && th > 0 && width > 0 && height > 0;
        if (n.zstd) {
            n.width = int(width);
            n.height = int(height);
            n.tileWidth = int(tw);
            n.tileHeight = int(th);
            n.tilesAcross = int((width + tw - 1) / tw);
            n.checked.assign(size_t(TIFFNumberOfTiles(tif)), 0);
        }
        it = m_files.emplace(file.string(), std::move(n)).first;
    }
    File& f = it->second;
    if (!f.zstd) return Ok{};
    x0 = std::max(x0, 0), y0 = std::max(y0, 0), x1 = std::min(x1, f.width), y1 = std::min(y1, f.height);
    Decoder& d = *m_decoder;
    for (int ty = y0 / f.tileHeight; y1 > y0 && ty <= (y1 - 1) / f.tileHeight; ++ty)
        for (int tx = x0 / f.tileWidth; x1 > x0 && tx <= (x1 - 1) / f.tileWidth; ++tx) {
            const size_t i = size_t(ty) * size_t(f.tilesAcross) + size_t(tx);
            if (i >= f.checked.size() || f.checked[i]) continue;
            if (auto st = open(); !st) return st;
            const tmsize_t tileBytes = TIFFTileSize(tif);
            const auto tile = TIFFComputeTile(tif, std::uint32_t(tx * f.tileWidth), std::uint32_t(ty * f.tileHeight), 0, 0);
            const std::uint64_t size = TIFFGetStrileByteCount(tif, tile);
            const std::string where = "tile " + std::to_string(tile) + " (column " + std::to_string(tx) + ", row " +
                                      std::to_string(ty) + ")";
            // A tile larger than its decoded size plus Zstandard's framing and our trailer cannot be one of ours.
            if (size == 0 || size > ZSTD_compressBound(size_t(tileBytes)) + kTileChecksumBytes)
                return fileError(file.string(), where + " claims " + std::to_string(size) + " bytes");
            d.compressed.resize(size_t(size));
            if (TIFFReadRawTile(tif, tile, d.compressed.data(), tmsize_t(size)) != tmsize_t(size))
                return fileError(file.string(), where + " reads short");
            // Our tiles carry a CRC-32 of their bytes: no decode needed.
            switch (verifyTileChecksum(d.compressed.data(), d.compressed.size())) {
            case TileChecksum::Matches: f.checked[i] = 1; continue;
            case TileChecksum::Differs: return fileError(file.string(), where + " fails its CRC-32 checksum (damaged)");
            case TileChecksum::Absent: break;
            }
            d.decoded.resize(size_t(std::max<tmsize_t>(tileBytes, 1)));
            const size_t n = ZSTD_decompressDCtx(d.context.get(), d.decoded.data(), d.decoded.size(),
                                                 d.compressed.data(), d.compressed.size());
            if (ZSTD_isError(n))
                return fileError(file.string(), where + " does not decode (Zstandard: " + ZSTD_getErrorName(n) + ")");
            if (n != size_t(tileBytes))
                return fileError(file.string(), where + " decodes to " + std::to_string(n) + " bytes, not " +
                                                    std::to_string(tileBytes));
            f.checked[i] = 1;
        }
    return Ok{};
}

} // namespace seasonview
