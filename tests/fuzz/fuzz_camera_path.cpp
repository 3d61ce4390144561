// Camera paths (keyframe JSON for `bench --path` and `render --path`), evaluated along their length, and the same
// bytes as a camera string ("X,Y,Z,YAW,PITCH[,FOV]", --camera and bookmarks).
#include "FuzzSupport.h"

#include "Camera.h"
#include "CameraPath.h"

#include <string>

using namespace seasonview;

SEASONVIEW_FUZZ_TARGET(camera_path) {
    if (auto path = CameraPath::fromJson(fuzz::writeInput(data, size, "path.json")))
        for (int i = 0; i <= 16; ++i) (void)path->at(i / 16.0, [](double, double) { return 10.0; });
    if (auto spec = parseCamera(std::string(reinterpret_cast<const char*>(data), size)))
        (void)spec->resolve([](double, double) { return 10.0; });
    return 0;
}
