// OBJ city models with their material library: the input is split at the first "\n#MTL\n" into the .obj and
// its .mtl (both in the corpus), loaded in the scene's local frame and with a CRS.
#include "FuzzSupport.h"

#include "CityModel.h"

#include <string_view>

using namespace seasonview;

SEASONVIEW_FUZZ_TARGET(obj) {
    const std::string_view all(reinterpret_cast<const char*>(data), size);
    const std::size_t cut = all.find("\n#MTL\n");
    const std::string_view obj = all.substr(0, cut);
    const std::string_view mtl = cut == std::string_view::npos ? std::string_view() : all.substr(cut + 6);
    fuzz::writeInput(reinterpret_cast<const std::uint8_t*>(mtl.data()), mtl.size(), "model.mtl");
    const auto path = fuzz::writeInput(reinterpret_cast<const std::uint8_t*>(obj.data()), obj.size(), "model.obj");
    city::CityLoadOptions local;
    local.localFrame = true;
    (void)city::loadCityModel(path.string(), local);
    city::CityLoadOptions utm;
    utm.crs = Crs::utm(32, true);
    utm.objUp = 'z';
    (void)city::loadCityModel(path.string(), utm);
    return 0;
}
