#pragma once
// A long job's progress callback (synth, prepare, pyramid and statistics builders; the CLI draws it as a bar).
#include <functional>

namespace seasonview {

/// Progress callback: fraction done in [0,1] and a short stage name.
using ProgressFn = std::function<void(double fraction, const char* stage)>;

} // namespace seasonview
