#pragma once
// Move-only RAII wrappers for every GL object type seasonview uses (magnum GL/Buffer.h style): copy deleted, a
// move leaves the source with id 0, the destructor does nothing for id 0. Objects are created with the DSA
// glCreate* functions (GL 4.5) and must be destroyed while their context is current.
#include <epoxy/gl.h>

#include <utility>

namespace seasonview::gl {

template <typename Traits> class Object {
public:
    Object() = default;
    /// Takes ownership of an existing name.
    explicit Object(GLuint id) : m_id(id) {}
    ~Object() { reset(); }
    Object(const Object&) = delete;
    Object& operator=(const Object&) = delete;
    Object(Object&& o) noexcept : m_id(std::exchange(o.m_id, 0u)) {}
    Object& operator=(Object&& o) noexcept {
        if (this != &o) {
            reset();
            m_id = std::exchange(o.m_id, 0u);
        }
        return *this;
    }

    /// Creates a new GL object (arguments as the traits' create, e.g. a texture target or shader type).
    template <typename... Args> static Object create(Args... args) { return Object(Traits::create(args...)); }

    GLuint id() const { return m_id; }
    explicit operator bool() const { return m_id != 0; }
    /// Deletes the GL object now (no-op for id 0).
    void reset() {
        if (m_id) Traits::destroy(m_id);
        m_id = 0;
    }
    /// Gives up ownership without deleting.
    GLuint release() { return std::exchange(m_id, 0u); }

private:
    GLuint m_id = 0;
};

namespace detail {
struct BufferTraits {
    static GLuint create() { GLuint id = 0; glCreateBuffers(1, &id); return id; }
    static void destroy(GLuint id) { glDeleteBuffers(1, &id); }
};
struct VertexArrayTraits {
    static GLuint create() { GLuint id = 0; glCreateVertexArrays(1, &id); return id; }
    static void destroy(GLuint id) { glDeleteVertexArrays(1, &id); }
};
struct TextureTraits {
    static GLuint create(GLenum target) { GLuint id = 0; glCreateTextures(target, 1, &id); return id; }
    static void destroy(GLuint id) { glDeleteTextures(1, &id); }
};
struct SamplerTraits {
    static GLuint create() { GLuint id = 0; glCreateSamplers(1, &id); return id; }
    static void destroy(GLuint id) { glDeleteSamplers(1, &id); }
};
struct FramebufferTraits {
    static GLuint create() { GLuint id = 0; glCreateFramebuffers(1, &id); return id; }
    static void destroy(GLuint id) { glDeleteFramebuffers(1, &id); }
};
struct RenderbufferTraits {
    static GLuint create() { GLuint id = 0; glCreateRenderbuffers(1, &id); return id; }
    static void destroy(GLuint id) { glDeleteRenderbuffers(1, &id); }
};
struct QueryTraits {
    static GLuint create(GLenum target) { GLuint id = 0; glCreateQueries(target, 1, &id); return id; }
    static void destroy(GLuint id) { glDeleteQueries(1, &id); }
};
struct ShaderTraits {
    static GLuint create(GLenum type) { return glCreateShader(type); }
    static void destroy(GLuint id) { glDeleteShader(id); }
};
struct ProgramTraits {
    static GLuint create() { return glCreateProgram(); }
    static void destroy(GLuint id) { glDeleteProgram(id); }
};
} // namespace detail

using Buffer = Object<detail::BufferTraits>;
using VertexArray = Object<detail::VertexArrayTraits>;
using Texture = Object<detail::TextureTraits>;
using Sampler = Object<detail::SamplerTraits>;
using Framebuffer = Object<detail::FramebufferTraits>;
using Renderbuffer = Object<detail::RenderbufferTraits>;
using Query = Object<detail::QueryTraits>;
using Shader = Object<detail::ShaderTraits>;
using Program = Object<detail::ProgramTraits>;

} // namespace seasonview::gl
