#pragma once
// KHR_debug plumbing: GL errors and warnings reach stderr and are counted, so tests can fail on them.
#include <string>

namespace seasonview::gl {

/// Installs the debug-message callback on the current context (synchronous output). Errors and high/medium
/// severity messages are printed to stderr as "GL: ..."; notifications are dropped.
void installDebugOutput();

/// Number of GL_DEBUG_TYPE_ERROR messages received since start (all contexts of this process).
int debugErrorCount();

/// glGetError() drained: returns "" when clean, else the error names joined with spaces.
std::string drainErrors();

} // namespace seasonview::gl
