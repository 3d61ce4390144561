// GeoTIFF and other rasters: header, georeferencing and every tile or strip, through the paths the commands take
// (readRasterInfo, the own parallel tile decoder BandReader, whole-image reads for masks and textures).
#include "FuzzSupport.h"

#include "BandReader.h"
#include "Raster.h"

#include <vector>

using namespace seasonview;

SEASONVIEW_FUZZ_TARGET(raster) {
    const auto path = fuzz::writeInput(data, size, "input.tif");
    auto info = readRasterInfo(path);
    if (!info) return 0;
    // Reading more than 64 MB of pixels is a slow input, not a finding (sizes over the limits are refused: the
    // resource-limit tests prove that); what is read must decode or fail cleanly.
    const std::uint64_t px = std::uint64_t(info->width) * std::uint64_t(info->height);
    if (px * 4 > (std::uint64_t(64) << 20)) return 0;
    if (auto r = BandReader::open(path, 64)) {
        std::vector<std::uint8_t> band(std::size_t(r->width()) * std::size_t(r->bandRows()) * 4 * 2);
        const SampleType t = r->type() == SampleType::U8 ? SampleType::U8 : SampleType::U16;
        const int channels = std::min(4, r->channels());
        for (int y = 0; y < r->height() && channels >= 1; y += r->bandRows()) {
            if (!r->read(y, std::min(r->height(), y + r->bandRows()), channels, t, band.data())) break;
        }
    }
    (void)readImageU8(path, 4);
    (void)readImageF32(path, 1);
    return 0;
}
