// The GPU copy of the segmentation rule (shaders/foliage_rule.glsl) against the CPU one (foliage/SegmentationRule.h):
// a compute shader runs every GLSL rule function on many inputs, including the edge cases of each test, and every
// answer must equal the C++ answer exactly (both use the same integer, and exact double, arithmetic).
#include "SegmentationRule.h"
#include "TestUtil.h"
#include "gl/GlDebug.h"
#include "gl/GlObjects.h"
#include "gl/ShaderProgram.h"

#include <gtest/gtest.h>

#include <random>

using namespace seasonview;

namespace {

const char* kMain = R"(
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer On { ivec4 on[]; };    // rgb, drop threshold t
layout(std430, binding = 1) readonly buffer Off { ivec4 off[]; };  // rgb, vote count
layout(std430, binding = 2) readonly buffer Tex { double tex[]; }; // n, sum, sumSq per case
layout(std430, binding = 3) readonly buffer K { int ks[]; };
layout(std430, binding = 4) writeonly buffer Out { int answers[]; };
uniform int uCount;
void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= uCount) return;
    ivec3 a = on[i].rgb, b = off[i].rgb;
    bool drop = svDropAtLeast(a, b, on[i].w);
    bool textured = svTextured(tex[3 * i], tex[3 * i + 1], tex[3 * i + 2]);
    answers[i] = int(svGreenIsMax(a)) | int(svGreenIsMax(b)) << 1 | int(drop) << 2 |
                 int(svIsMajority(off[i].w, ks[i])) << 3 | int(textured) << 4 |
                 int(svDefaultTexel(drop, textured)) << 5;
}
)";

} // namespace

TEST(FoliageRuleGLTest, GlslRuleAgreesWithCpp) {
    gl::GlContext* ctx = test::headlessContext();
    ASSERT_TRUE(ctx);
    const std::string source = "#version 450 core\n" + gl::shaderSource("foliage_rule.glsl") + kMain;
    auto built = gl::ShaderProgram::buildComputeSource("foliage_rule test", source);
    ASSERT_TRUE(built.ok()) << built.message();
    gl::ShaderProgram program = std::move(*built);

    // Random colours, thresholds, votes; texture windows of random smoothed brightness, half of them scaled so that
    // the coefficient of variation lies right at the 0.03 threshold.
    constexpr int n = 1 << 16;
    std::mt19937 rng(11);
    std::vector<std::int32_t> on(4 * n), off(4 * n), ks(n);
    std::vector<double> tex(3 * n);
    for (int i = 0; i < n; ++i) {
        for (int c = 0; c < 3; ++c) {
            on[size_t(4 * i + c)] = int(rng() % 256);
            off[size_t(4 * i + c)] = i % 7 == 0 ? on[size_t(4 * i + c)] : int(rng() % 256); // some ties and equal pairs
        }
        on[size_t(4 * i + 3)] = int(rng() % 511) - 255;
        ks[size_t(i)] = 1 + 2 * int(rng() % 8);
        off[size_t(4 * i + 3)] = int(rng() % std::uint32_t(ks[size_t(i)] * ks[size_t(i)] + 1));
        double sum = 0, sumSq = 0;
        const double base = 100.0 + double(rng() % 6700);
        const double spread = i % 2 ? base * 0.03 * (0.97 + 0.06 * double(rng() % 1000) / 1000.0) : double(rng() % 800);
        for (int j = 0; j < 25; ++j) {
            const double v = std::round(base + (j % 2 ? spread : -spread) * (j == 24 ? 0 : 1));
            sum += v;
            sumSq += v * v;
        }
        tex[size_t(3 * i)] = 25;
        tex[size_t(3 * i + 1)] = sum;
        tex[size_t(3 * i + 2)] = sumSq;
    }
    gl::Buffer buffers[5];
    const std::pair<const void*, size_t> data[] = {{on.data(), on.size() * 4},
                                                   {off.data(), off.size() * 4},
                                                   {tex.data(), tex.size() * 8},
                                                   {ks.data(), ks.size() * 4},
                                                   {nullptr, size_t(n) * 4}};
    for (GLuint b = 0; b < 5; ++b) {
        buffers[b] = gl::Buffer::create();
        glNamedBufferData(buffers[b].id(), GLsizeiptr(data[b].second), data[b].first, GL_STATIC_DRAW);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, b, buffers[b].id());
    }
    glUseProgram(program.id());
    glUniform1i(glGetUniformLocation(program.id(), "uCount"), n);
    glDispatchCompute((n + 63) / 64, 1, 1);
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    std::vector<std::int32_t> answers(n);
    glGetNamedBufferSubData(buffers[4].id(), 0, GLsizeiptr(n * 4), answers.data());
    EXPECT_EQ(gl::drainErrors(), "");

    int textured = 0, dropped = 0;
    for (int i = 0; i < n; ++i) {
        const std::int32_t* a = &on[size_t(4 * i)];
        const std::int32_t* b = &off[size_t(4 * i)];
        const bool drop = dropAtLeast(a[0], a[1], a[2], b[0], b[1], b[2], a[3]);
        const bool tx = seasonview::textured(tex[size_t(3 * i)], tex[size_t(3 * i + 1)], tex[size_t(3 * i + 2)]);
        const int expected = int(greenIsMax(a[0], a[1], a[2])) | int(greenIsMax(b[0], b[1], b[2])) << 1 |
                             int(drop) << 2 | int(isMajority(b[3], ks[size_t(i)])) << 3 | int(tx) << 4 |
                             int(defaultTexel(drop, tx)) << 5;
        ASSERT_EQ(answers[size_t(i)], expected) << "case " << i;
        textured += tx;
        dropped += drop;
    }
    // Both outcomes of each test occur (the cases probe the thresholds, not one side of them).
    EXPECT_GT(textured, n / 10);
    EXPECT_LT(textured, n - n / 10);
    EXPECT_GT(dropped, n / 10);
    EXPECT_LT(dropped, n - n / 10);
}
