#pragma once
// OpenGL 4.5 core contexts: headless through EGL, windowed through GLFW. Renderers draw into their own
// framebuffer objects either way, so the same code path serves both.
#include "Result.h"

#include <memory>
#include <string>

namespace seasonview::gl {

struct ContextInfo {
    std::string platform;   // "EGL device", "EGL surfaceless", "GLFW window"
    std::string vendor, renderer, version;
    int maxFramebufferSide = 0; // the largest render target side: min(GL_MAX_RENDERBUFFER_SIZE, GL_MAX_VIEWPORT_DIMS)
};

/// Whether a GL_RENDERER string names a software rasteriser (llvmpipe, softpipe, SwiftShader).
bool isSoftwareRenderer(const std::string& glRenderer);
/// Whether the current context's renderer is a software rasteriser (isSoftwareRenderer of its GL_RENDERER).
bool currentIsSoftwareRenderer();

/// Whether a width×height render target fits what this context allows (`what` names the option, e.g. "--size");
/// the error names the limit and the renderer.
Status checkFramebufferSize(const ContextInfo& info, int width, int height, const std::string& what);

class GlContext {
public:
    virtual ~GlContext() = default;
    /// Makes the context current on the calling thread.
    virtual void makeCurrent() = 0;
    /// Presents the window's back buffer (no-op headless).
    virtual void swapBuffers() {}
    /// Polls window events and says whether the user asked to close (always false headless).
    virtual bool shouldClose() { return false; }
    /// Size in pixels of the window's default framebuffer (0,0 headless).
    virtual void framebufferSize(int& width, int& height) const { width = height = 0; }
    /// The GLFWwindow* of a windowed context (nullptr headless).
    virtual void* nativeWindow() const { return nullptr; }
    const ContextInfo& info() const { return m_info; }

protected:
    ContextInfo m_info;
    void fillInfo(const char* platform); // call with the context current
};

/// Headless context. Platform choice: EGL device platform when an NVIDIA device is enumerated, Mesa surfaceless
/// otherwise; SEASONVIEW_EGL_PLATFORM=device|surfaceless forces one. Debug output installed when `debug`.
Result<std::unique_ptr<GlContext>> createHeadlessContext(bool debug = true);

/// A GLFW window with an OpenGL 4.5 core context (needs a display; works under Xvfb). `visible` false gives a
/// hidden window, for rendering through the windowed path without showing anything.
Result<std::unique_ptr<GlContext>> createWindowContext(int width, int height, const std::string& title, bool visible,
                                                       bool debug = true);

} // namespace seasonview::gl
