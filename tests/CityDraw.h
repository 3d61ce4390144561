#pragma once
// Drawing a city alone for the city GL tests (CityPagingGLTest, CityBlockMapGLTest): cleared to one colour and to the
// far depth, then drawn, read back.
#include "CityRendererGL.h"
#include "gl/RenderTarget.h"

#include <epoxy/gl.h>

#include <cstdint>
#include <vector>

namespace seasonview::test {

/// The city alone at `cam` over a clear colour of (0.2, 0.3, 0.4); its frame's counters in `st`; RGBA, row 0 at top.
inline std::vector<std::uint8_t> drawCity(city::CityRendererGL& city, const Camera& cam, const gl::RenderTarget& target,
                                          city::CityFrameStats& st) {
    target.bind();
    glClearColor(0.2f, 0.3f, 0.4f, 1.0f);
    glClearDepth(0.0); // reversed Z
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    st = city.draw(cam, nullptr, target);
    return target.readRgba();
}

} // namespace seasonview::test
