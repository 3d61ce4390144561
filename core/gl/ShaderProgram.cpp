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

Result<Shader> compile(GLenum type, std::string_view name, const std::vector<std::string>& defines) {
    std::string body = shaderSource(name);
    if (body.empty()) return Error{"shader " + std::string(name) + ": not embedded"};
    std::string text = "#version 450 core\n";
    for (const auto& d : defines) text += "#define " + d + "\n";
    text += "#line 1\n" + body;
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
        return Error{"shader " + std::string(name) + ": " + l};
    }
    return s;
}

} // namespace

std::string shaderSource(std::string_view name) {
    std::string_view raw = rawSource(name);
    return raw.empty() ? std::string() : expandIncludes(raw, 0);
}

Result<ShaderProgram> ShaderProgram::build(std::string_view vertexName, std::string_view fragmentName,
                                           const std::vector<std::string>& defines) {
    auto vs = compile(GL_VERTEX_SHADER, vertexName, defines);
    if (!vs) return vs.error();
    auto fs = compile(GL_FRAGMENT_SHADER, fragmentName, defines);
    if (!fs) return fs.error();
    ShaderProgram p;
    p.m_program = Program::create();
    glAttachShader(p.id(), vs->id());
    glAttachShader(p.id(), fs->id());
    glLinkProgram(p.id());
    GLint ok = 0;
    glGetProgramiv(p.id(), GL_LINK_STATUS, &ok);
    if (!ok) {
        char log[4096] = {};
        glGetProgramInfoLog(p.id(), sizeof log, nullptr, log);
        return Error{"program " + std::string(vertexName) + "+" + std::string(fragmentName) + ": " + log};
    }
    glDetachShader(p.id(), vs->id());
    glDetachShader(p.id(), fs->id());
    return p;
}

Result<ShaderProgram> ShaderProgram::buildCompute(std::string_view computeName, const std::vector<std::string>& defines) {
    auto cs = compile(GL_COMPUTE_SHADER, computeName, defines);
    if (!cs) return cs.error();
    ShaderProgram p;
    p.m_program = Program::create();
    glAttachShader(p.id(), cs->id());
    glLinkProgram(p.id());
    GLint ok = 0;
    glGetProgramiv(p.id(), GL_LINK_STATUS, &ok);
    if (!ok) {
        char log[4096] = {};
        glGetProgramInfoLog(p.id(), sizeof log, nullptr, log);
        return Error{"program " + std::string(computeName) + ": " + log};
    }
    glDetachShader(p.id(), cs->id());
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
