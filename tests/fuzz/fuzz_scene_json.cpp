// Scene manifests (scene.json): parsed, then its grid options read as `render` and `segment` read them.
#include "FuzzSupport.h"

#include "Scene.h"

using namespace seasonview;

SEASONVIEW_FUZZ_TARGET(scene_json) {
    auto s = parseManifest(fuzz::writeInput(data, size, "scene.json"));
    if (s) (void)parseGridOptions(*s);
    return 0;
}
