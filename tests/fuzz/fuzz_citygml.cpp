// CityGML city models (`--city`, `atlas build`), loaded as the commands load them: CRS from the file.
#include "FuzzSupport.h"

#include "CityModel.h"

using namespace seasonview;

SEASONVIEW_FUZZ_TARGET(citygml) {
    city::CityLoadOptions o;
    o.crs = Crs::utm(32, true);
    (void)city::loadCityModel(fuzz::writeInput(data, size, "model.gml").string(), o);
    return 0;
}
