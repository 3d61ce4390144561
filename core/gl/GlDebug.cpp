#include "GlDebug.h"

#include <epoxy/gl.h>

#include <atomic>
#include <cstdio>

namespace seasonview::gl {

namespace {
std::atomic<int> g_errors{0};

void GLAPIENTRY onMessage(GLenum, GLenum type, GLuint, GLenum severity, GLsizei, const GLchar* message, const void*) {
    if (type == GL_DEBUG_TYPE_ERROR) ++g_errors;
    if (severity == GL_DEBUG_SEVERITY_NOTIFICATION) return;
    if (type != GL_DEBUG_TYPE_ERROR && severity == GL_DEBUG_SEVERITY_LOW) return;
    std::fprintf(stderr, "GL: %s\n", message);
}

const char* errorName(GLenum e) {
    switch (e) {
    case GL_INVALID_ENUM: return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE: return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION: return "GL_INVALID_OPERATION";
    case GL_INVALID_FRAMEBUFFER_OPERATION: return "GL_INVALID_FRAMEBUFFER_OPERATION";
    case GL_OUT_OF_MEMORY: return "GL_OUT_OF_MEMORY";
    default: return "GL_ERROR";
    }
}
} // namespace

void installDebugOutput() {
    if (!epoxy_has_gl_extension("GL_KHR_debug") && epoxy_gl_version() < 43) return;
    glEnable(GL_DEBUG_OUTPUT);
    glEnable(GL_DEBUG_OUTPUT_SYNCHRONOUS);
    glDebugMessageCallback(onMessage, nullptr);
    glDebugMessageControl(GL_DONT_CARE, GL_DONT_CARE, GL_DONT_CARE, 0, nullptr, GL_TRUE);
}

int debugErrorCount() { return g_errors.load(); }

std::string drainErrors() {
    std::string s;
    for (int i = 0; i < 16; ++i) {
        GLenum e = glGetError();
        if (e == GL_NO_ERROR) break;
        if (!s.empty()) s += ' ';
        s += errorName(e);
    }
    return s;
}

} // namespace seasonview::gl
