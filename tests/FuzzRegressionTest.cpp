// The fuzz targets (tests/fuzz/fuzz_*.cpp, compiled into this program) run on every input that once broke them
// (tests/fuzz/regressions/TARGET/), and on a few degenerate inputs each: they must return without an exception, and,
// under the sanitizer build (.ci/run), without a sanitizer report. The loaders' answers to the findings are checked
// by name below.
#include "FuzzSupport.h"
#include "TestUtil.h"

#include "AtlasTree.h"
#include "Commands.h"
#include "ImagePyramid.h"

#include <gtest/gtest.h>

using namespace seasonview;
using namespace seasonview::test;

namespace fs = std::filesystem;

TEST(FuzzRegressionTest, EveryLoaderHasATarget) {
    for (const char* t : {"raster", "scene_json", "camera_path", "trees_csv", "pair_stats", "pyramid_index",
                          "pyramid_tile", "citygml", "obj", "atlas_tree", "blockmap", "preset", "viewer_script"})
        EXPECT_EQ(fuzz::targets().count(t), 1u) << t;
}

TEST(FuzzRegressionTest, FindingsAndDegenerateInputsRunClean) {
    const fs::path root = fs::path(SEASONVIEW_SOURCE_DIR) / "tests/fuzz/regressions";
    int findings = 0;
    for (const auto& [name, fn] : fuzz::targets()) {
        SCOPED_TRACE(name);
        for (const std::string& input : {std::string(), std::string("{}"), std::string("[[[[[["),
                                         std::string("II*\0\x08\0\0\0", 8), std::string(1000, '\xff')})
            EXPECT_NO_THROW(fn(reinterpret_cast<const std::uint8_t*>(input.data()), input.size()));
        if (!fs::exists(root / name)) continue;
        for (const auto& e : fs::directory_iterator(root / name)) {
            SCOPED_TRACE(e.path().filename().string());
            const std::string bytes = readBytes(e.path());
            EXPECT_NO_THROW(fn(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()));
            ++findings;
        }
    }
    EXPECT_GE(findings, 2);
}

// fuzz_preset: an integer key holding a number far out of int's range was converted with undefined behaviour.
TEST(FuzzRegressionTest, PresetIntegersOutOfRangeAreErrors) {
    TempDir dir("fuzz-preset");
    for (const std::string& text : {std::string(R"({"facade_size": 5e80})"), std::string(R"({"block_city": -1e300})"),
                                    std::string(R"({"seed": 1.5})"), std::string(R"({"seed": "one"})")}) {
        SCOPED_TRACE(text);
        std::ofstream(dir / "p.json") << text;
        auto r = app::loadSynthPreset(dir / "p.json");
        ASSERT_FALSE(r.ok());
        EXPECT_NE(r.message().find("p.json: preset keys"), std::string::npos) << r.message();
    }
}

// fuzz_pyramid_tile: a level file with tiles larger than the tile cache made OpenImageIO abort; such a file is now
// refused by the header check every pyramid's levels pass before a tile is read.
TEST(FuzzRegressionTest, LevelFileWithForeignTilesIsRefusedByItsHeader) {
    const fs::path file = fs::path(SEASONVIEW_SOURCE_DIR) / "tests/fuzz/regressions/pyramid_tile/oiio-abort-tile-over-cache.tif";
    const std::string why = checkLevelFile(file, fs::file_size(file), 64530, 18707, 256, TexelFormat::Rgba8);
    EXPECT_NE(why, "");
}

// fuzz_atlas_tree: a node whose atlas byte count wrapped the index's bounds check around 2^64 passed it, and reading
// its blob threw std::length_error; an empty vector in the index was copied from a null pointer.
TEST(FuzzRegressionTest, AtlasTreeIndexWithImpossibleExtentsIsCorrupt) {
    const fs::path dir = fs::path(SEASONVIEW_SOURCE_DIR) / "tests/fuzz/regressions/atlas_tree";
    auto wrapped = city::AtlasTreeFile::open((dir / "length-error-huge-blob.atlas").string());
    ASSERT_FALSE(wrapped.ok());
    EXPECT_NE(wrapped.message().find("corrupt atlas tree index"), std::string::npos) << wrapped.message();
    auto empty = city::AtlasTreeFile::open((dir / "ubsan-memcpy-of-empty-vector.atlas").string());
    EXPECT_TRUE(empty.ok()) << empty.message(); // a valid tree with an empty table
}
