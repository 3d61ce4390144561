#pragma once
// Programs built from the embedded shader files of shaders/. Variants are `#define` lines prepended to one source
// (filament/magnum style); `#include "file.glsl"` lines are expanded from the embedded set.
#include "Result.h"
#include "GlObjects.h"

#include <glm/mat2x2.hpp>
#include <glm/mat4x4.hpp>

#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace seasonview::gl {

/// The source of an embedded shader with includes expanded; empty when there is no such file.
std::string shaderSource(std::string_view name);

class ShaderProgram {
public:
    ShaderProgram() = default;
    /// Compiles and links `vertexName` + `fragmentName` (file names in shaders/) with the given defines
    /// ("NAME" or "NAME VALUE"). The error carries the compiler's log: a broken shader is a bug, tests catch it.
    static Result<ShaderProgram> build(std::string_view vertexName, std::string_view fragmentName,
                                       const std::vector<std::string>& defines = {});
    /// Compiles and links a compute program from `computeName` (a .comp file in shaders/).
    static Result<ShaderProgram> buildCompute(std::string_view computeName, const std::vector<std::string>& defines = {});
    /// The same from complete source text (`#version` line included; tests that run shader functions); errors name
    /// `label`.
    static Result<ShaderProgram> buildComputeSource(std::string_view label, const std::string& source);

    GLuint id() const { return m_program.id(); }
    void use() const { glUseProgram(m_program.id()); }
    /// Uniform location (cached; -1 when the uniform is absent or optimised out).
    GLint location(const char* name) const;

    void set(const char* name, int v) const { glProgramUniform1i(id(), location(name), v); }
    void set(const char* name, float v) const { glProgramUniform1f(id(), location(name), v); }
    void set(const char* name, const glm::vec2& v) const { glProgramUniform2f(id(), location(name), v.x, v.y); }
    void set(const char* name, const glm::vec3& v) const { glProgramUniform3f(id(), location(name), v.x, v.y, v.z); }
    void set(const char* name, const glm::vec4& v) const {
        glProgramUniform4f(id(), location(name), v.x, v.y, v.z, v.w);
    }
    void set(const char* name, const glm::mat2& m) const {
        glProgramUniformMatrix2fv(id(), location(name), 1, GL_FALSE, &m[0][0]);
    }
    void set(const char* name, const glm::mat4& m) const {
        glProgramUniformMatrix4fv(id(), location(name), 1, GL_FALSE, &m[0][0]);
    }

private:
    Program m_program;
    mutable std::unordered_map<std::string, GLint> m_locations;
};

} // namespace seasonview::gl
