#include "TestUtil.h"
#include "gl/GlContext.h"
#include "gl/GlDebug.h"
#include "gl/GlObjects.h"
#include "gl/RenderTarget.h"
#include "gl/ShaderProgram.h"

#include <gtest/gtest.h>

using namespace seasonview;

namespace {
gl::GlContext* context() { return test::headlessContext(); }
} // namespace

TEST(GlObjectsGLTest, HeadlessContextIsGl45Core) {
    ASSERT_TRUE(context());
    context()->makeCurrent();
    const auto& info = context()->info();
    EXPECT_EQ(info.platform.rfind("EGL", 0), 0u) << info.platform;
    EXPECT_GE(epoxy_gl_version(), 45) << info.version;
    GLint mask = 0;
    glGetIntegerv(GL_CONTEXT_PROFILE_MASK, &mask);
    EXPECT_TRUE(mask & GL_CONTEXT_CORE_PROFILE_BIT);
    EXPECT_EQ(gl::drainErrors(), "");
}

// Software rasterisers are told from GPUs by their GL_RENDERER: what the auto settings follow (the terrain's shading
// path, the city's BC upload).
TEST(GlObjectsGLTest, SoftwareRenderersAreTold) {
    EXPECT_TRUE(gl::isSoftwareRenderer("llvmpipe (LLVM 15.0.6, 256 bits)"));
    EXPECT_TRUE(gl::isSoftwareRenderer("softpipe"));
    EXPECT_TRUE(gl::isSoftwareRenderer("ANGLE (Google, Vulkan 1.3.0 (SwiftShader Device (Subzero)), SwiftShader driver)"));
    EXPECT_FALSE(gl::isSoftwareRenderer("NVIDIA H200/PCIe/SSE2"));
    EXPECT_FALSE(gl::isSoftwareRenderer("AMD Radeon RX 7900 XTX (radeonsi, navi31, LLVM 15.0.6, DRM 3.54)"));
    EXPECT_FALSE(gl::isSoftwareRenderer(""));
    ASSERT_TRUE(context());
    context()->makeCurrent();
    EXPECT_EQ(gl::currentIsSoftwareRenderer(), gl::isSoftwareRenderer(context()->info().renderer));
}

TEST(GlObjectsGLTest, MoveOnlyRaiiDeletesExactlyOnce) {
    ASSERT_TRUE(context());
    context()->makeCurrent();
    static_assert(!std::is_copy_constructible_v<gl::Buffer>);
    static_assert(!std::is_copy_assignable_v<gl::Texture>);
    static_assert(std::is_nothrow_move_constructible_v<gl::Framebuffer>);
    GLuint id = 0;
    {
        gl::Buffer a = gl::Buffer::create();
        id = a.id();
        EXPECT_NE(id, 0u);
        EXPECT_TRUE(glIsBuffer(id));
        gl::Buffer b = std::move(a);
        EXPECT_EQ(a.id(), 0u); // NOLINT(bugprone-use-after-move): the moved-from state is the contract
        EXPECT_EQ(b.id(), id);
        gl::Buffer c;
        c = std::move(b);
        EXPECT_EQ(b.id(), 0u); // NOLINT(bugprone-use-after-move)
        EXPECT_TRUE(glIsBuffer(id));
    }
    EXPECT_FALSE(glIsBuffer(id)) << "destroyed when the last owner died";
    {
        gl::Texture t = gl::Texture::create(GL_TEXTURE_2D_ARRAY);
        gl::Texture u = gl::Texture::create(GL_TEXTURE_2D);
        const GLuint tid = t.id();
        t = std::move(u); // assigning over a live object deletes the old one
        EXPECT_FALSE(glIsTexture(tid));
        gl::Query q = gl::Query::create(GL_TIME_ELAPSED);
        gl::Sampler s = gl::Sampler::create();
        gl::VertexArray v = gl::VertexArray::create();
        gl::Renderbuffer r = gl::Renderbuffer::create();
        EXPECT_TRUE(q && s && v && r);
        gl::Program empty; // id 0: destructor does nothing
    }
    EXPECT_EQ(gl::drainErrors(), "");
}

TEST(GlObjectsGLTest, ShaderVariantsAndErrors) {
    ASSERT_TRUE(context());
    context()->makeCurrent();
    auto p = gl::ShaderProgram::build("terrain_reference.vert", "terrain_reference.frag", {"SEASONVIEW_TEST_VARIANT 1"});
    ASSERT_TRUE(p.ok()) << p.message();
    EXPECT_GE(p->location("uViewProj"), 0);
    EXPECT_EQ(p->location("uNoSuchUniform"), -1);
    auto missing = gl::ShaderProgram::build("no_such.vert", "terrain_reference.frag");
    ASSERT_FALSE(missing.ok());
    EXPECT_NE(missing.message().find("not embedded"), std::string::npos);
    EXPECT_NE(gl::shaderSource("terrain_reference.frag").find("vec4 sampleTiledImage"), std::string::npos)
        << "#include is expanded";
    EXPECT_EQ(gl::drainErrors(), "");
}

TEST(GlObjectsGLTest, DebugOutputCountsErrors) {
    ASSERT_TRUE(context());
    context()->makeCurrent();
    const int before = gl::debugErrorCount();
    glBindBuffer(0x1234, 0); // invalid enum on purpose
    EXPECT_EQ(gl::debugErrorCount(), before + 1);
    EXPECT_EQ(gl::drainErrors(), "GL_INVALID_ENUM");
}

TEST(GlObjectsGLTest, ReadbackIsTopRowFirst) {
    ASSERT_TRUE(context());
    context()->makeCurrent();
    gl::RenderTarget t(4, 2);
    t.bind();
    glClearColor(0, 0, 1, 1);
    glClear(GL_COLOR_BUFFER_BIT);
    glEnable(GL_SCISSOR_TEST);
    glScissor(0, 1, 4, 1); // GL row 1 = the top row of the image
    glClearColor(1, 0, 0, 1);
    glClear(GL_COLOR_BUFFER_BIT);
    glDisable(GL_SCISSOR_TEST);
    const auto px = t.readRgba();
    EXPECT_EQ(px[0], 255); // top-left red
    EXPECT_EQ(px[2], 0);
    EXPECT_EQ(px[4 * 4 + 2], 255); // bottom-left blue
    EXPECT_EQ(gl::drainErrors(), "");
}
