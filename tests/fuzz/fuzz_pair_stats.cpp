// Pair-statistics cache files (<cache>/pairstats/*.json, the histograms `segment` and the GPU rule reuse). The
// pyramids the file is checked against take their keys and size from the input's own "leafon_key",
// "leafoff_key", "width" and "height" when it has them (so a real file from `prepare` in the corpus reads back
// whole, and mutations reach every check after the key's), else fixed ones.
#include "FuzzSupport.h"

#include "PairStats.h"

#include <nlohmann/json.hpp>

using namespace seasonview;

SEASONVIEW_FUZZ_TARGET(pair_stats) {
    ImagePyramid on, off;
    on.sourceKey = "on.tif|1|2";
    off.sourceKey = "off.tif|1|2";
    int w = 64, h = 64;
    const auto j = nlohmann::json::parse(data, data + size, nullptr, false);
    if (j.is_object()) {
        if (j.contains("leafon_key") && j["leafon_key"].is_string()) on.sourceKey = j["leafon_key"].get<std::string>();
        if (j.contains("leafoff_key") && j["leafoff_key"].is_string()) off.sourceKey = j["leafoff_key"].get<std::string>();
        if (j.contains("width") && j["width"].is_number_integer()) w = int(std::clamp<long long>(j["width"].get<long long>(), 1, 1 << 20));
        if (j.contains("height") && j["height"].is_number_integer()) h = int(std::clamp<long long>(j["height"].get<long long>(), 1, 1 << 20));
    }
    on.levels = {PyramidLevel{"on.tif", w, h}};
    off.levels = {PyramidLevel{"off.tif", w, h}};
    const auto cache = fuzz::workDir() / "cache";
    const auto file = pairHistogramsFile(on, off, cache);
    std::filesystem::create_directories(file.parent_path());
    std::filesystem::rename(fuzz::writeInput(data, size, "pairstats.json"), file);
    (void)cachedPairHistograms(on, off, cache);
    return 0;
}
