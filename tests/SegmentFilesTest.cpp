// segmentScene (foliage/SegmentFiles.h) on files: the pair held in memory (each input decoded once), streamed twice
// (a first pass for the histograms) and given its histograms (the pair statistics cache) gives the same mask and
// overlay, byte for byte, equal to the in-memory segmentation of the same pixels.
#include "PairStats.h"
#include "SegmentFiles.h"
#include "Segmentation.h"
#include "TestUtil.h"

#include <gtest/gtest.h>

using namespace seasonview;
using namespace seasonview::test;

namespace {

namespace fs = std::filesystem;

struct SegmentRun {
    SegmentReport report;
    std::vector<std::uint8_t> mask, overlay;
};

enum class Mode { Held, Streamed, Given };

SegmentRun segment(const Scene& scene, const TreePair& pair, const fs::path& dir, SegmentationParams params,
                   int bandRows, Mode mode) {
    SegmentJob job;
    job.params = params;
    job.mask = dir / "mask.png";
    job.overlay = dir / "overlay.png";
    job.truth = dir / "truth.png";
    job.bandRows = bandRows;
    if (mode == Mode::Streamed) job.memoryBudget = 0;
    if (mode == Mode::Given) job.histograms = pairHistograms(pair.on, pair.off, true, true);
    SegmentRun run;
    auto r = segmentScene(scene, job);
    EXPECT_TRUE(r.ok()) << r.message();
    if (!r) return run;
    run.report = *r;
    auto mask = readImageU8(job.mask, 1);
    auto overlay = readImageU8(job.overlay, 3);
    EXPECT_TRUE(mask.ok() && overlay.ok());
    if (mask) run.mask = mask->pixels;
    if (overlay) run.overlay = overlay->pixels;
    return run;
}

} // namespace

TEST(SegmentFilesTest, HeldStreamedAndGivenStatisticsGiveTheSameMask) {
    TempDir dir("segment-files");
    const int w = 203, h = 150; // tiles of 64: partial tiles at the right and the bottom
    const TreePair pair = makeTreePair(w, h, 6);
    GeoTiffWriteOptions o;
    o.tileSize = 64;
    for (const auto& [name, img] : {std::pair{"on.tif", &pair.on}, std::pair{"off.tif", &pair.off}})
        ASSERT_TRUE(writeGeoTiff(dir / name, img->pixels.data(), SampleType::U8, w, h, 3, testGeoref(0.5), o).ok());
    ASSERT_TRUE(writeImageAtomic(dir / "truth.png", pair.truth.pixels.data(), w, h, 1).ok());
    SceneSources src;
    src.leafon = dir / "on.tif";
    src.leafoff = dir / "off.tif";
    auto scene = loadScene(src, dir / "cache");
    ASSERT_TRUE(scene.ok()) << scene.message();

    for (SegmentationMethod m : {SegmentationMethod::Default, SegmentationMethod::Equalized,
                                 SegmentationMethod::Neighborhood})
        for (int k : {3, 5})
            for (int bandRows : {7, 64, 256}) {
                const SegmentationParams params{m, k};
                SCOPED_TRACE(std::string(segmentationMethodName(m)) + " k " + std::to_string(k) + ", bands of " +
                             std::to_string(bandRows));
                const std::vector<std::uint8_t> expected = segmentImage(pair.on, pair.off, params).pixels;
                const SegmentRun held = segment(*scene, pair, dir.path(), params, bandRows, Mode::Held);
                const SegmentRun streamed = segment(*scene, pair, dir.path(), params, bandRows, Mode::Streamed);
                const SegmentRun given = segment(*scene, pair, dir.path(), params, bandRows, Mode::Given);
                ASSERT_TRUE(held.mask == expected);
                ASSERT_TRUE(streamed.mask == expected);
                ASSERT_TRUE(given.mask == expected);
                EXPECT_TRUE(held.overlay == streamed.overlay);
                EXPECT_TRUE(given.overlay == streamed.overlay);
                EXPECT_EQ(held.report.confusion->tp, streamed.report.confusion->tp);
                if (needsHistograms(m)) {
                    EXPECT_EQ(held.report.statsSource, StatsSource::HeldPair);
                    EXPECT_TRUE(held.report.heldInMemory);
                    EXPECT_EQ(held.report.inputPasses, 1);
                    EXPECT_EQ(streamed.report.statsSource, StatsSource::HistogramPass);
                    EXPECT_FALSE(streamed.report.heldInMemory);
                    EXPECT_EQ(streamed.report.inputPasses, 2);
                    EXPECT_EQ(given.report.statsSource, StatsSource::Given);
                    EXPECT_FALSE(given.report.heldInMemory);
                    EXPECT_EQ(given.report.inputPasses, 1);
                    EXPECT_EQ(held.report.stats.dropThreshold, streamed.report.stats.dropThreshold);
                    EXPECT_EQ(held.report.stats.lutOn, streamed.report.stats.lutOn);
                } else {
                    // Nothing to hold for: streamed once whatever the budget.
                    EXPECT_EQ(held.report.statsSource, StatsSource::None);
                    EXPECT_FALSE(held.report.heldInMemory);
                    EXPECT_EQ(held.report.inputPasses, 1);
                }
            }
    // The default method finds the crowns on this pair (a comparison of empty masks would prove nothing).
    const SegmentRun run = segment(*scene, pair, dir.path(), {SegmentationMethod::Default, 5}, 64, Mode::Held);
    EXPECT_GT(std::count(run.mask.begin(), run.mask.end(), 255), 500);
}

TEST(SegmentFilesTest, StatisticsFromThePyramidsAreThoseOfTheHeldPair) {
    // What `segment` takes from the pair statistics cache equals what it computes itself.
    TempDir dir("segment-files-cache");
    const int w = 300, h = 270;
    const TreePair pair = makeTreePair(w, h, 8);
    ASSERT_TRUE(writeGeoTiff(dir / "on.tif", pair.on.pixels.data(), SampleType::U8, w, h, 3, testGeoref(0.5)).ok());
    ASSERT_TRUE(writeGeoTiff(dir / "off.tif", pair.off.pixels.data(), SampleType::U8, w, h, 3, testGeoref(0.5)).ok());
    SceneSources src;
    src.leafon = dir / "on.tif";
    src.leafoff = dir / "off.tif";
    auto scene = loadScene(src, dir / "cache");
    ASSERT_TRUE(scene.ok()) << scene.message();
    std::vector<ImagePyramid> p;
    for (const ImageryLayer* layer : {&scene->leafon, &scene->leafoff}) {
        PrepareOptions o;
        o.cacheDir = dir / "cache";
        auto r = preparePyramid(*layer, o);
        ASSERT_TRUE(r.ok()) << r.message();
        p.push_back(r->pyramid);
    }
    auto h1 = preparePairHistograms(p[0], p[1], dir / "cache");
    ASSERT_TRUE(h1.ok()) << h1.message();
    SegmentJob job;
    job.params = {SegmentationMethod::Default, 5};
    job.mask = dir / "held.png";
    auto held = segmentScene(*scene, job);
    ASSERT_TRUE(held.ok()) << held.message();
    job.mask = dir / "given.png";
    job.histograms = *h1;
    auto given = segmentScene(*scene, job);
    ASSERT_TRUE(given.ok()) << given.message();
    EXPECT_EQ(held->stats.dropThreshold, given->stats.dropThreshold);
    auto a = readImageU8(dir / "held.png", 1), b = readImageU8(dir / "given.png", 1);
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_TRUE(a->pixels == b->pixels);
}
