#pragma once
// Shader sources of shaders/, embedded into the binary by shaders/embed.cmake.
#include <string_view>
#include <vector>

namespace seasonview {

struct EmbeddedShader {
    std::string_view name;   // file name, e.g. "terrain_reference.vert"
    std::string_view source; // file contents, without a #version line
};

/// Every shader file of shaders/, in no particular order. Lives for the whole program.
const std::vector<EmbeddedShader>& embeddedShaders();

} // namespace seasonview
