#pragma once
// An offscreen colour (RGBA8) + depth (32F, for reversed Z) framebuffer every renderer draws into, headless or
// windowed; read back top row first, ready for an image file.
#include "GlObjects.h"

#include <cstdint>
#include <vector>

namespace seasonview::gl {

class RenderTarget {
public:
    RenderTarget(int width, int height);
    int width() const { return m_width; }
    int height() const { return m_height; }
    /// Binds for drawing, sets the viewport.
    void bind() const;
    /// RGBA8 pixels, row 0 = top of the image (GL's bottom-up rows flipped).
    std::vector<std::uint8_t> readRgba() const;
    /// Depth-buffer values (reversed Z: 0 = infinitely far / nothing drawn), row 0 = top.
    std::vector<float> readDepth() const;
    /// Copies the colour buffer to the default framebuffer of a window of the given size.
    void blitToDefault(int windowWidth, int windowHeight) const;
    GLuint framebuffer() const { return m_fbo.id(); }
    /// The depth buffer (DEPTH_COMPONENT32F), for passes that draw into other colour buffers with the same depth.
    GLuint depthRenderbuffer() const { return m_depth.id(); }

private:
    int m_width, m_height;
    Framebuffer m_fbo;
    Renderbuffer m_color, m_depth;
};

} // namespace seasonview::gl
