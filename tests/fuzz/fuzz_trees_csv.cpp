// True tree lists (trees.csv, columns x, y, radius_m[, type]) read by `segment --true-trees`.
#include "FuzzSupport.h"

#include "SegmentFiles.h"

using namespace seasonview;

SEASONVIEW_FUZZ_TARGET(trees_csv) {
    (void)readTrueTrees(fuzz::writeInput(data, size, "trees.csv"));
    return 0;
}
