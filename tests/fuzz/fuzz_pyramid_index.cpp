// Pyramid indexes (<cache>/pyramids/<hash>/pyramid.json) checked against their level files, as `render`,
// `segment` and the viewer open a prepared pyramid: the input is the index; the folder holds a real 300x200
// pyramid's level files (written once per process by prepare from a generated image).
#include "FuzzSupport.h"

#include "ImagePyramid.h"
#include "Raster.h"
#include "Scene.h"

#include <cstdlib>

using namespace seasonview;

namespace {

struct Prepared {
    std::optional<ImageryLayer> layer;
    std::filesystem::path cache, index;
};

const Prepared& prepared() {
    static const Prepared p = [] {
        Prepared r;
        const auto dir = fuzz::workDir();
        Image<std::uint8_t> img;
        img.width = 300;
        img.height = 200;
        img.channels = 3;
        img.pixels.resize(300 * 200 * 3);
        for (std::size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = std::uint8_t(i * 7 % 251);
        Georef g;
        g.crs = Crs::utm(32, true);
        g.origin = {405000.0, 5758000.0};
        if (!writeGeoTiff(dir / "source.tif", img.pixels.data(), SampleType::U8, 300, 200, 3, g).ok()) std::abort();
        auto layer = openImageryLayer(SourceList(dir / "source.tif"), "leaf-on", dir / "cache");
        if (!layer) std::abort();
        r.layer = std::move(*layer);
        r.cache = dir / "cache";
        PrepareOptions o;
        o.cacheDir = r.cache;
        o.tileSize = 64;
        auto report = preparePyramid(*r.layer, o);
        if (!report) std::abort();
        r.index = report->pyramid.folder / "pyramid.json";
        return r;
    }();
    return p;
}

} // namespace

SEASONVIEW_FUZZ_TARGET(pyramid_index) {
    const Prepared& p = prepared();
    std::filesystem::rename(fuzz::writeInput(data, size, "pyramid.json"), p.index);
    (void)openPyramid(*p.layer, p.cache);
    return 0;
}
