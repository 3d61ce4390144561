// Atlas-tree files (`atlas build` output, read by the renderer): the index, then every node's atlas decoded as
// the pager decodes it, and the traversal data the renderer walks.
#include "FuzzSupport.h"

#include "AtlasTree.h"

using namespace seasonview;

SEASONVIEW_FUZZ_TARGET(atlas_tree) {
    auto f = city::AtlasTreeFile::open(fuzz::writeInput(data, size, "city.atlas").string());
    if (!f) return 0;
    int decoded = 0;
    for (int t = 0; t < int(f->trees.size()); ++t)
        for (int n = 0; n < int(f->trees[size_t(t)].nodes.size()) && decoded < 64; ++n, ++decoded)
            (void)f->readAtlasRgba(t, n);
    return 0;
}
