#include "RenderTarget.h"

#include <cassert>
#include <cstring>

namespace seasonview::gl {

RenderTarget::RenderTarget(int width, int height)
    : m_width(width), m_height(height), m_fbo(Framebuffer::create()), m_color(Renderbuffer::create()),
      m_depth(Renderbuffer::create()) {
    assert(width > 0 && height > 0 && "RenderTarget::RenderTarget(): empty size");
    glNamedRenderbufferStorage(m_color.id(), GL_RGBA8, width, height);
    glNamedRenderbufferStorage(m_depth.id(), GL_DEPTH_COMPONENT32F, width, height);
    glNamedFramebufferRenderbuffer(m_fbo.id(), GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, m_color.id());
    glNamedFramebufferRenderbuffer(m_fbo.id(), GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, m_depth.id());
    assert(glCheckNamedFramebufferStatus(m_fbo.id(), GL_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE &&
           "RenderTarget::RenderTarget(): incomplete framebuffer");
}

void RenderTarget::bind() const {
    glBindFramebuffer(GL_FRAMEBUFFER, m_fbo.id());
    glViewport(0, 0, m_width, m_height);
}

std::vector<std::uint8_t> RenderTarget::readRgba() const {
    const size_t row = size_t(m_width) * 4;
    std::vector<std::uint8_t> gl(row * size_t(m_height)), out(gl.size());
    glNamedFramebufferReadBuffer(m_fbo.id(), GL_COLOR_ATTACHMENT0);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, m_fbo.id());
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, m_width, m_height, GL_RGBA, GL_UNSIGNED_BYTE, gl.data());
    for (int y = 0; y < m_height; ++y)
        std::memcpy(&out[size_t(y) * row], &gl[size_t(m_height - 1 - y) * row], row);
    return out;
}

std::vector<float> RenderTarget::readDepth() const {
    const size_t row = size_t(m_width);
    std::vector<float> gl(row * size_t(m_height)), out(gl.size());
    glBindFramebuffer(GL_READ_FRAMEBUFFER, m_fbo.id());
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glReadPixels(0, 0, m_width, m_height, GL_DEPTH_COMPONENT, GL_FLOAT, gl.data());
    for (int y = 0; y < m_height; ++y)
        std::memcpy(&out[size_t(y) * row], &gl[size_t(m_height - 1 - y) * row], row * sizeof(float));
    return out;
}

void RenderTarget::blitToDefault(int windowWidth, int windowHeight) const {
    glBlitNamedFramebuffer(m_fbo.id(), 0, 0, 0, m_width, m_height, 0, 0, windowWidth, windowHeight,
                           GL_COLOR_BUFFER_BIT, GL_LINEAR);
}

} // namespace seasonview::gl
