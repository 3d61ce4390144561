#include "ShaderProgram.h"

#include "EmbeddedShaders.h"

#include <sstream>

namespace seasonview::gl {

namespace {

std::string_view rawSource(std::string_view name) {
    for (const auto& s : seasonview::embeddedShaders())
        if (s.name == name) return s.source;
    return {};
}

std::string expandIncludes(std::string_view source, int depth) {
    std::ostringstream out;
    std::istringstream in{std::string(source)};
    std::string line;
    while (std::getline(in, line)) {
        if (depth < 8 && line.rfind("#include \"", 0) == 0) {
            const size_t end = line.find('"', 10);
            std::string_view inc = rawSource(std::string_view(line).substr(10, end - 10));
            if (!inc.empty()) {
                out << expandIncludes(inc, depth + 1) << '\n';
                continue;
            }
        }
        out << line << '\n';
    }
    return out.str();
}

// Compiles the complete source `text`; the error names `label` and carries the compiler's log on one line.
Result<Shader> compileText(GLenum type, std::string_view label, const std::string& text) {
    Shader s = Shader::create(type);
    const char* src = text.c_str();
    glShaderSource(s.id(), 1, &src, nullptr);
    glCompileShader(s.id());
    GLint ok = 0;
    glGetShaderiv(s.id(), GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[4096] = {};
        glGetShaderInfoLog(s.id(), sizeof log, nullptr, log);
        std::string l = log;
        for (char& c : l)
            if (c == '\n') c = ' ';
        return Error{"shader " + std::string(label) + ": " + l};
    }
    return s;
}

// The embedded shader `name` with its includes expanded, after the version line and `defines`.
Result<std::string> composeSource(std::string_view name, const std::vector<std::string>& defines) {
    std::string body = shaderSource(name);
    if (body.empty()) return Error{"shader " + std::string(name) + ": not embedded"};
    std::string text = "#version 450 core\n";
    for (const auto& d : defines) text += "#define " + d + "\n";
    return text + "#line 1\n" + body;
}

Result<Shader> compile(GLenum type, std::string_view name, const std::vector<std::string>& defines) {
    auto text = composeSource(name, defines);
    if (!text) return text.error();
    return compileText(type, name, *text);
}

} // namespace

std::string shaderSource(std::string_view name) {
    std::string_view raw = rawSource(name);
    return raw.empty() ? std::string() : expandIncludes(raw, 0);
}

namespace {
// Links the compiled shaders into `program`; the error names `what` and carries the linker's log.
Status linkProgram(GLuint program, const std::vector<const Shader*>& shaders, const std::string& what) {
    for (const Shader* s : shaders) glAttachShader(program, s->id());
    glLinkProgram(program);
    GLint ok = 0;
    glGetProgramiv(program, GL_LINK_STATUS, &ok);
    for (const Shader* s : shaders) glDetachShader(program, s->id());
    if (!ok) {
        char log[4096] = {};
        glGetProgramInfoLog(program, sizeof log, nullptr, log);
        return Error{"program " + what + ": " + log};
    }
    return Ok{};
}
} // namespace

Result<ShaderProgram> ShaderProgram::build(std::string_view vertexName, std::string_view fragmentName,
                                           const std::vector<std::string>& defines) {
    auto vs = compile(GL_VERTEX_SHADER, vertexName, defines);
    if (!vs) return vs.error();
    auto fs = compile(GL_FRAGMENT_SHADER, fragmentName, defines);
    if (!fs) return fs.error();
    ShaderProgram p;
    p.m_program = Program::create();
    if (auto st = linkProgram(p.id(), {&*vs, &*fs}, std::string(vertexName) + "+" + std::string(fragmentName)); !st)
        return st.error();
    return p;
}

Result<ShaderProgram> ShaderProgram::buildCompute(std::string_view computeName, const std::vector<std::string>& defines) {
    auto text = composeSource(computeName, defines);
    if (!text) return text.error();
    return buildComputeSource(computeName, *text);
}

Result<ShaderProgram> ShaderProgram::buildComputeSource(std::string_view label, const std::string& source) {
    auto cs = compileText(GL_COMPUTE_SHADER, label, source);
    if (!cs) return cs.error();
    ShaderProgram p;
    p.m_program = Program::create();
    if (auto st = linkProgram(p.id(), {&*cs}, std::string(label)); !st) return st.error();
    return p;
}

GLint ShaderProgram::location(const char* name) const {
    auto it = m_locations.find(name);
    if (it != m_locations.end()) return it->second;
    GLint loc = glGetUniformLocation(id(), name);
    m_locations.emplace(name, loc);
    return loc;
}

} // namespace seasonview::gl
