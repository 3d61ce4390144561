// The integer arithmetic the shaders do without integer division (llvmpipe divides vectors lane by lane): the
// float-quotient division by a uniform (shaders/common_intdiv.glsl), the clipmap layout's block, slot and toroidal
// texel as compile-time constants and as uniforms (common_clip_layout.glsl), and the three-component unpremultiply
// of the canopy derivation (foliage_rule.glsl). Each must equal C++'s integer arithmetic exactly.
#include "SegmentationRule.h"
#include "TestUtil.h"
#include "gl/GlDebug.h"
#include "gl/GlObjects.h"
#include "gl/ShaderProgram.h"

#include <gtest/gtest.h>

#include <functional>
#include <random>
#include <string>
#include <vector>

using namespace seasonview;

namespace {

// Runs `main` (a compute shader body over `ivec4 inputs[]` writing `ivec4 outputs[]`, one invocation per input, after
// `library` with `defines`) and returns the outputs.
std::vector<glm::ivec4> runCompute(const std::string& library, const std::vector<std::string>& defines,
                                   const std::string& mainBody, const std::vector<glm::ivec4>& inputs,
                                   const std::function<void(GLuint)>& setUniforms = {}) {
    std::string source = "#version 450 core\n";
    for (const std::string& d : defines) source += "#define " + d + "\n";
    source += gl::shaderSource(library);
    source += R"(
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer In { ivec4 inputs[]; };
layout(std430, binding = 1) writeonly buffer Out { ivec4 outputs[]; };
uniform int uCount;
void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= uCount) return;
    ivec4 v = inputs[i];
)" + mainBody + "\n}\n";
    auto built = gl::ShaderProgram::buildComputeSource("int math test", source);
    EXPECT_TRUE(built.ok()) << built.message();
    if (!built) return {};
    gl::ShaderProgram program = std::move(*built);
    gl::Buffer in = gl::Buffer::create(), out = gl::Buffer::create();
    glNamedBufferData(in.id(), GLsizeiptr(inputs.size() * 16), inputs.data(), GL_STATIC_DRAW);
    glNamedBufferData(out.id(), GLsizeiptr(inputs.size() * 16), nullptr, GL_STATIC_DRAW);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, in.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, out.id());
    glUseProgram(program.id());
    glUniform1i(glGetUniformLocation(program.id(), "uCount"), int(inputs.size()));
    if (setUniforms) setUniforms(program.id());
    glDispatchCompute(GLuint((inputs.size() + 63) / 64), 1, 1);
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    std::vector<glm::ivec4> result(inputs.size());
    glGetNamedBufferSubData(out.id(), 0, GLsizeiptr(result.size() * 16), result.data());
    glUseProgram(0);
    EXPECT_EQ(gl::drainErrors(), "");
    return result;
}

// Dividends 0 <= x < 2^24 for divisor d: around every multiple near 0, near 2^24 and at random.
std::vector<int> dividends(int d, std::mt19937& rng) {
    constexpr int kMax = (1 << 24) - 1;
    std::vector<int> x = {0, 1, 2, kMax, kMax - 1};
    for (int k = 1; k <= 40; ++k)
        for (int e : {-1, 0, 1}) {
            const long long lo = (long long)k * d + e, hi = (long long)(kMax / d - k) * d + e;
            for (long long v : {lo, hi})
                if (v >= 0 && v <= kMax) x.push_back(int(v));
        }
    for (int i = 0; i < 2000; ++i) x.push_back(int(rng() % std::uint32_t(kMax + 1)));
    return x;
}

} // namespace

TEST(ShaderIntMathGLTest, DivisionByAUniformIsExact) {
    ASSERT_TRUE(test::headlessContext());
    std::mt19937 rng(5);
    std::vector<glm::ivec4> inputs;
    std::vector<int> divisors = {1, 2, 3, 5, 7, 8, 16, 63, 64, 65, 100, 255, 256, 1000, 1023, 1024, 1536, 4095, 4096,
                                 65535, 65536, (1 << 24) - 1};
    for (int i = 0; i < 20; ++i) divisors.push_back(1 + int(rng() % 100000));
    for (int d : divisors)
        for (int x : dividends(d, rng)) inputs.push_back({x, x / 3, d, 0}); // y: a second dividend in the same lane
    const auto out = runCompute("common_intdiv.glsl", {},
                                "outputs[i] = ivec4(svDiv(v.xy, v.z), svMod(v.xy, v.z));", inputs);
    ASSERT_EQ(out.size(), inputs.size());
    for (size_t i = 0; i < inputs.size(); ++i) {
        const glm::ivec4 v = inputs[i];
        const glm::ivec4 want(v.x / v.z, v.y / v.z, v.x % v.z, v.y % v.z);
        ASSERT_EQ(out[i], want) << "x " << v.x << ", " << v.y << " d " << v.z;
    }
}

TEST(ShaderIntMathGLTest, ClipLayoutAsConstantsAndAsUniformsAgree) {
    ASSERT_TRUE(test::headlessContext());
    // (block, slots, N): the default, a clip size that is not a power of two, a small one.
    for (const glm::ivec3 layout : {glm::ivec3(64, 32, 2048), glm::ivec3(64, 24, 1536), glm::ivec3(32, 8, 256)}) {
        std::mt19937 rng(9);
        std::vector<glm::ivec4> inputs;
        for (int i = 0; i < 4096; ++i) {
            const int q = i < 64 ? i * layout.x - 1 + i % 3 : int(rng() % (1u << 22));
            inputs.push_back({std::max(q, 0), int(rng() % (1u << 20)), 0, 0});
        }
        const std::string body = "outputs[i] = ivec4(clipBlockOf(v.xy).x, clipSlotOf(v.xy).x, clipTexelOf(v.xy));";
        const std::vector<std::string> constants = {"CLIP_BLOCK_SIZE " + std::to_string(layout.x),
                                                    "CLIP_SLOTS_PER_SIDE " + std::to_string(layout.y),
                                                    "CLIP_SIZE " + std::to_string(layout.z)};
        const auto viaConstants = runCompute("common_clip_layout.glsl", constants, body, inputs);
        const auto viaUniforms = runCompute("common_clip_layout.glsl", {}, body, inputs, [&](GLuint p) {
            glUniform1i(glGetUniformLocation(p, "uBlockSize"), layout.x);
            glUniform1i(glGetUniformLocation(p, "uSlotsPerSide"), layout.y);
            glUniform1f(glGetUniformLocation(p, "uClipSize"), float(layout.z));
        });
        ASSERT_EQ(viaConstants.size(), inputs.size());
        ASSERT_EQ(viaUniforms.size(), inputs.size());
        for (size_t i = 0; i < inputs.size(); ++i) {
            const glm::ivec4 v = inputs[i];
            const glm::ivec4 want(v.x / layout.x, v.x % layout.y, v.x % layout.z, v.y % layout.z);
            ASSERT_EQ(viaConstants[i], want) << "q " << v.x << ", " << v.y << " layout " << layout.x;
            ASSERT_EQ(viaUniforms[i], want) << "q " << v.x << ", " << v.y << " layout " << layout.x;
        }
    }
}

TEST(ShaderIntMathGLTest, UnpremultiplyOfThreeComponentsMatchesCpp) {
    ASSERT_TRUE(test::headlessContext());
    std::vector<glm::ivec4> inputs;
    for (int a = 0; a < 256; ++a)
        for (int c = 0; c < 256; c += 3) inputs.push_back({c, std::min(c + 1, 255), std::min(c + 2, 255), a});
    const auto out = runCompute("foliage_rule.glsl", {}, "outputs[i] = ivec4(svUnpremultiply3(v.rgb, v.a), 0);", inputs);
    ASSERT_EQ(out.size(), inputs.size());
    for (size_t i = 0; i < inputs.size(); ++i) {
        const glm::ivec4 v = inputs[i];
        const glm::ivec4 want(unpremultiply(v.x, v.w), unpremultiply(v.y, v.w), unpremultiply(v.z, v.w), 0);
        ASSERT_EQ(out[i], want) << "c " << v.x << " a " << v.w;
    }
}
