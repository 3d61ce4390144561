// Synthetic-scene presets (`synth --preset FILE`).
#include "FuzzSupport.h"

#include "Commands.h"

using namespace seasonview;

SEASONVIEW_FUZZ_TARGET(preset) {
    (void)app::loadSynthPreset(fuzz::writeInput(data, size, "preset.json"));
    return 0;
}
