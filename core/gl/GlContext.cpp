#include "GlContext.h"

#include "GlDebug.h"

#include <epoxy/egl.h>
#include <epoxy/gl.h>
#include <GLFW/glfw3.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <vector>

namespace seasonview::gl {

bool isSoftwareRenderer(const std::string& glRenderer) {
    for (const char* name : {"llvmpipe", "softpipe", "SwiftShader"})
        if (glRenderer.find(name) != std::string::npos) return true;
    return false;
}

bool currentIsSoftwareRenderer() {
    const auto* name = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
    return name && isSoftwareRenderer(name);
}

void GlContext::fillInfo(const char* platform) {
    auto str = [](GLenum e) {
        const GLubyte* s = glGetString(e);
        return s ? std::string(reinterpret_cast<const char*>(s)) : std::string("?");
    };
    m_info.platform = platform;
    m_info.vendor = str(GL_VENDOR);
    m_info.renderer = str(GL_RENDERER);
    m_info.version = str(GL_VERSION);
    GLint renderbuffer = 0, viewport[2] = {0, 0};
    glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &renderbuffer);
    glGetIntegerv(GL_MAX_VIEWPORT_DIMS, viewport);
    m_info.maxFramebufferSide = std::min({renderbuffer, viewport[0], viewport[1]});
}

Status checkFramebufferSize(const ContextInfo& info, int width, int height, const std::string& what) {
    if (width <= info.maxFramebufferSide && height <= info.maxFramebufferSide) return Ok{};
    return Error{what + " " + std::to_string(width) + "x" + std::to_string(height) + ": larger than " + info.renderer +
                 " allows (at most " + std::to_string(info.maxFramebufferSide) +
                 " pixels a side: GL_MAX_RENDERBUFFER_SIZE, GL_MAX_VIEWPORT_DIMS)"};
}

namespace {

std::string eglErrorText() {
    char buf[32];
    std::snprintf(buf, sizeof buf, "EGL error 0x%04x", eglGetError());
    return buf;
}

class EglContext final : public GlContext {
public:
    EglContext(EGLDisplay display, EGLContext context, const char* platform) : m_display(display), m_context(context) {
        makeCurrent();
        fillInfo(platform);
    }
    ~EglContext() override {
        eglMakeCurrent(m_display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        eglDestroyContext(m_display, m_context);
        eglTerminate(m_display);
    }
    void makeCurrent() override { eglMakeCurrent(m_display, EGL_NO_SURFACE, EGL_NO_SURFACE, m_context); }

private:
    EGLDisplay m_display;
    EGLContext m_context;
};

EGLContext createEglGlContext(EGLDisplay display, bool debug) {
    if (!eglBindAPI(EGL_OPENGL_API)) return EGL_NO_CONTEXT;
    const EGLint configAttribs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLConfig config = nullptr;
    EGLint count = 0;
    EGLConfig chosen = EGL_NO_CONFIG_KHR;
    if (eglChooseConfig(display, configAttribs, &config, 1, &count) && count > 0) chosen = config;
    const EGLint contextAttribs[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5,
                                     EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                     EGL_CONTEXT_OPENGL_DEBUG, debug ? EGL_TRUE : EGL_FALSE, EGL_NONE};
    return eglCreateContext(display, chosen, EGL_NO_CONTEXT, contextAttribs);
}

// Tries the device platform; returns an initialised NVIDIA display or EGL_NO_DISPLAY.
EGLDisplay findDeviceDisplay(bool requireNvidia) {
    if (!epoxy_has_egl_extension(EGL_NO_DISPLAY, "EGL_EXT_device_enumeration") &&
        !epoxy_has_egl_extension(EGL_NO_DISPLAY, "EGL_EXT_device_base"))
        return EGL_NO_DISPLAY;
    EGLDeviceEXT devices[16];
    EGLint n = 0;
    if (!eglQueryDevicesEXT(16, devices, &n)) return EGL_NO_DISPLAY;
    for (EGLint i = 0; i < n; ++i) {
        EGLDisplay d = eglGetPlatformDisplayEXT(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr);
        if (d == EGL_NO_DISPLAY) continue;
        EGLint major = 0, minor = 0;
        if (!eglInitialize(d, &major, &minor)) continue;
        const char* vendor = eglQueryString(d, EGL_VENDOR);
        if (!requireNvidia || (vendor && std::strstr(vendor, "NVIDIA"))) return d;
        eglTerminate(d);
    }
    return EGL_NO_DISPLAY;
}

} // namespace

Result<std::unique_ptr<GlContext>> createHeadlessContext(bool debug) {
    const char* force = std::getenv("SEASONVIEW_EGL_PLATFORM");
    const std::string forced = force ? force : "";
    if (forced != "surfaceless") {
        EGLDisplay d = findDeviceDisplay(forced != "device");
        if (d != EGL_NO_DISPLAY) {
            EGLContext c = createEglGlContext(d, debug);
            if (c != EGL_NO_CONTEXT) {
                auto ctx = std::make_unique<EglContext>(d, c, "EGL device");
                if (debug) installDebugOutput();
                return std::unique_ptr<GlContext>(std::move(ctx));
            }
            eglTerminate(d);
        }
        if (forced == "device") return Error{"EGL: no usable device-platform display (" + eglErrorText() + ")"};
    }
    EGLDisplay d = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    if (d == EGL_NO_DISPLAY) return Error{"EGL: no surfaceless display (" + eglErrorText() + "); is libegl-mesa0 installed?"};
    EGLint major = 0, minor = 0;
    if (!eglInitialize(d, &major, &minor)) return Error{"EGL: eglInitialize failed (" + eglErrorText() + ")"};
    EGLContext c = createEglGlContext(d, debug);
    if (c == EGL_NO_CONTEXT) {
        std::string e = eglErrorText();
        eglTerminate(d);
        return Error{"EGL: cannot create an OpenGL 4.5 core context (" + e + ")"};
    }
    auto ctx = std::make_unique<EglContext>(d, c, "EGL surfaceless");
    if (debug) installDebugOutput();
    return std::unique_ptr<GlContext>(std::move(ctx));
}

namespace {

class GlfwContext final : public GlContext {
public:
    explicit GlfwContext(GLFWwindow* window) : m_window(window) {
        makeCurrent();
        fillInfo("GLFW window");
    }
    ~GlfwContext() override {
        glfwDestroyWindow(m_window);
        glfwTerminate();
    }
    void makeCurrent() override { glfwMakeContextCurrent(m_window); }
    void swapBuffers() override { glfwSwapBuffers(m_window); }
    bool shouldClose() override {
        glfwPollEvents();
        return glfwWindowShouldClose(m_window);
    }
    void framebufferSize(int& width, int& height) const override { glfwGetFramebufferSize(m_window, &width, &height); }
    void* nativeWindow() const override { return m_window; }

private:
    GLFWwindow* m_window;
};

} // namespace

Result<std::unique_ptr<GlContext>> createWindowContext(int width, int height, const std::string& title, bool visible,
                                                       bool debug) {
    glfwSetErrorCallback(nullptr);
    if (!glfwInit()) {
        const char* desc = nullptr;
        glfwGetError(&desc);
        return Error{std::string("GLFW: cannot initialise (") + (desc ? desc : "no display?") +
                     "); use headless rendering or run under xvfb-run"};
    }
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_OPENGL_DEBUG_CONTEXT, debug ? GLFW_TRUE : GLFW_FALSE);
    glfwWindowHint(GLFW_VISIBLE, visible ? GLFW_TRUE : GLFW_FALSE);
    GLFWwindow* w = glfwCreateWindow(width, height, title.c_str(), nullptr, nullptr);
    if (!w) {
        const char* desc = nullptr;
        glfwGetError(&desc);
        glfwTerminate();
        return Error{std::string("GLFW: cannot create an OpenGL 4.5 window (") + (desc ? desc : "?") + ")"};
    }
    auto ctx = std::make_unique<GlfwContext>(w);
    if (debug) installDebugOutput();
    return std::unique_ptr<GlContext>(std::move(ctx));
}

} // namespace seasonview::gl
