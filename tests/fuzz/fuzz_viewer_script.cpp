// Viewer scripts (`view --script`), played frame by frame as the viewer plays them, and `--screenshot-at T:FILE`.
#include "FuzzSupport.h"

#include "ViewerScript.h"

#include <string>

using namespace seasonview;

SEASONVIEW_FUZZ_TARGET(viewer_script) {
    if (auto events = app::loadViewerScript(fuzz::writeInput(data, size, "script.json"))) {
        const double end = std::min(app::scriptEnd(*events), 1000.0);
        double t0 = -1.0;
        for (int i = 0; i < 64; ++i) {
            const double t1 = end * (i + 1) / 64.0;
            (void)app::scriptFrame(*events, t0, t1);
            t0 = t1;
        }
    }
    (void)app::parseTimedScreenshot(std::string(reinterpret_cast<const char*>(data), size));
    return 0;
}
