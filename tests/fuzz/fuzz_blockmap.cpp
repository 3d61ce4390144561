// BlockMap files (`atlas blockmaps` and the blockmap mode's cache, read by the renderer's pager): the headers, the
// quadtree recovered from the maps' squares, every map read as the loader thread reads it, and rays cast against
// each (the traversal indexes the maps' textures by what the file says).
#include "FuzzSupport.h"

#include "BlockMap.h"

using namespace seasonview;

SEASONVIEW_FUZZ_TARGET(blockmap) {
    auto f = city::BlockMapFile::open(fuzz::writeInput(data, size, "city.svbm"));
    if (!f) return 0;
    (void)city::BlockMapQuadtree::of(*f);
    for (std::size_t k = 0; k < f->records().size() && k < 16; ++k) {
        auto m = f->read(k);
        if (!m) continue;
        const double side = double(m->size) * m->texel;
        const glm::dvec3 centre(m->origin + 0.5 * side, 0.5 * (m->zBase + m->zTop));
        for (const glm::dvec3 eye : {centre + glm::dvec3(-side, -0.3 * side, side), centre + glm::dvec3(0.1, 0.2, 2.0 * side)})
            (void)city::traceBlockMap(*m, eye, centre - eye);
    }
    return 0;
}
