// The pair segmentation statistics prepared with the pyramids (foliage/PairStats.h): the histograms streamed from
// both level-0 files equal those of the two images held whole (so the GPU, which gets them from the pyramids, and
// the CPU `segment` use the same tables and threshold), the JSON cache is reused, a corrupt one rebuilt, and a
// damaged level file is one error naming it.
#include "ImagePyramid.h"
#include "PairStats.h"
#include "Segmentation.h"
#include "Stretch.h"
#include "SyntheticScene.h"
#include "TestUtil.h"

#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <functional>

using namespace seasonview;
using namespace seasonview::test;

namespace {

namespace fs = std::filesystem;

std::vector<ImagePyramid> preparedPair(const Scene& scene, const fs::path& cache) {
    std::vector<ImagePyramid> out;
    for (const ImageryLayer* layer : {&scene.leafon, &scene.leafoff}) {
        PrepareOptions o;
        o.cacheDir = cache;
        auto r = preparePyramid(*layer, o);
        EXPECT_TRUE(r.ok()) << r.message();
        if (r) out.push_back(r->pyramid);
    }
    return out;
}

/// The 8-bit RGB the segmentation sees: the source read whole with its display stretch applied.
Image<std::uint8_t> displayRgb(const ImageryLayer& layer) {
    auto rgba = readDisplayRgba(layer.info, layer.stretch);
    EXPECT_TRUE(rgba.ok()) << rgba.message();
    Image<std::uint8_t> rgb;
    if (!rgba) return rgb;
    rgb.width = rgba->width;
    rgb.height = rgba->height;
    rgb.channels = 3;
    rgb.pixels.resize(size_t(rgb.width) * size_t(rgb.height) * 3);
    for (size_t i = 0, n = size_t(rgb.width) * size_t(rgb.height); i < n; ++i)
        for (size_t c = 0; c < 3; ++c) rgb.pixels[i * 3 + c] = rgba->pixels[i * 4 + c];
    return rgb;
}

void expectSame(const SegmentationHistograms& a, const SegmentationHistograms& b) {
    EXPECT_EQ(a.on, b.on);
    EXPECT_EQ(a.off, b.off);
    EXPECT_EQ(a.drop, b.drop);
}

void expectPyramidsMatchImages(const Scene& scene, const fs::path& cache) {
    const std::vector<ImagePyramid> p = preparedPair(scene, cache);
    ASSERT_EQ(p.size(), 2u);
    auto fromPyramids = preparePairHistograms(p[0], p[1], cache);
    ASSERT_TRUE(fromPyramids.ok()) << fromPyramids.message();
    const SegmentationHistograms whole =
        pairHistograms(displayRgb(scene.leafon), displayRgb(scene.leafoff), true, true);
    expectSame(*fromPyramids, whole);
    std::uint64_t samples = 0;
    for (std::uint64_t n : whole.drop) samples += n;
    const std::uint64_t side = [](int v) { return std::uint64_t((v + 1) / 2); }(scene.leafon.info.width);
    EXPECT_EQ(samples, side * std::uint64_t((scene.leafon.info.height + 1) / 2));
    for (SegmentationMethod m : {SegmentationMethod::Equalized, SegmentationMethod::Default}) {
        const SegmentationStats a = statsFromHistograms(*fromPyramids, m), b = statsFromHistograms(whole, m);
        EXPECT_EQ(a.dropThreshold, b.dropThreshold);
        EXPECT_EQ(a.lutOn, b.lutOn);
        EXPECT_EQ(a.lutOff, b.lutOff);
    }
}

std::uint64_t sum(const std::array<std::uint64_t, kSegDropBins>& bins) {
    std::uint64_t s = 0;
    for (std::uint64_t v : bins) s += v;
    return s;
}

} // namespace

TEST(PairStatsTest, SyntheticSceneHistogramsFromThePyramidsEqualTheWholeImages) {
    TempDir dir("pairstats-synth");
    SynthOptions o;
    o.sizeM = 150.5; // 301 × 301 pixels: two tile rows and columns, the last ones partial, odd rows and columns
    o.gsd = 0.5;
    o.seed = 3;
    auto rep = generateSyntheticScene(o, dir / "scene");
    ASSERT_TRUE(rep.ok()) << rep.message();
    ASSERT_EQ(rep->width, 301);
    auto src = parseManifest(dir / "scene" / "scene.json");
    ASSERT_TRUE(src.ok()) << src.message();
    auto scene = loadScene(*src, dir / "cache");
    ASSERT_TRUE(scene.ok()) << scene.message();
    expectPyramidsMatchImages(*scene, dir / "cache");
    // A seasonal scene: its drop histogram is not one spike.
    auto p = preparedPair(*scene, dir / "cache");
    auto h = preparePairHistograms(p[0], p[1], dir / "cache");
    ASSERT_TRUE(h.ok());
    EXPECT_GT(dropThresholdFromHistogram(h->drop), kSegMinDrop);
}

TEST(PairStatsTest, SixteenBitLevelZeroIsTheStretchedImage) {
    TempDir dir("pairstats-16");
    auto scene = writeTestPair(dir.path(), 260, 517, 1.0, true); // taller than two tile rows, odd height
    ASSERT_TRUE(scene.ok()) << scene.message();
    ASSERT_FALSE(scene->leafon.stretch.identity);
    expectPyramidsMatchImages(*scene, dir / "cache");
}

TEST(PairStatsTest, CacheIsReusedAndACorruptOneRebuilt) {
    TempDir dir("pairstats-cache");
    auto scene = writeTestPair(dir.path(), 300, 200, 1.0);
    ASSERT_TRUE(scene.ok()) << scene.message();
    const fs::path cache = dir / "cache";
    const std::vector<ImagePyramid> p = preparedPair(*scene, cache);
    ASSERT_EQ(p.size(), 2u);
    EXPECT_FALSE(cachedPairHistograms(p[0], p[1], cache).has_value());

    PairHistogramsReport first;
    auto a = preparePairHistograms(p[0], p[1], cache, {}, &first);
    ASSERT_TRUE(a.ok()) << a.message();
    EXPECT_TRUE(first.built);
    EXPECT_EQ(first.reason, "not prepared yet");
    EXPECT_EQ(first.file, pairHistogramsFile(p[0], p[1], cache));
    EXPECT_EQ(first.file.parent_path(), cache / "pairstats");
    ASSERT_TRUE(fs::is_regular_file(first.file));
    EXPECT_LT(fs::file_size(first.file), 64u * 1024u); // a small file
    const auto written = fs::last_write_time(first.file);
    const auto cached = cachedPairHistograms(p[0], p[1], cache);
    ASSERT_TRUE(cached.has_value());
    expectSame(*cached, *a);

    PairHistogramsReport second;
    auto b = preparePairHistograms(p[0], p[1], cache, {}, &second);
    ASSERT_TRUE(b.ok()) << b.message();
    EXPECT_FALSE(second.built);
    EXPECT_EQ(fs::last_write_time(first.file), written) << "an up-to-date file is not rewritten";
    expectSame(*b, *a);

    const std::string good = readBytes(first.file);
    struct Damage {
        const char* name;
        std::string text;
        const char* reason;
    };
    std::string edited = good;
    const size_t at = edited.find("\"drop\":[") + 8; // the first drop bin: 0 for this pair, made 7
    ASSERT_NE(at, std::string::npos + 8);
    edited.insert(at, "7");
    const std::vector<Damage> damages = {
        {"garbage", "{not json", "unreadable"},
        {"cut in half", good.substr(0, good.size() / 2), "unreadable"},
        {"empty", "", "unreadable"},
        {"a bin changed", edited, "does not hold"},
        {"histograms missing", "{\"key\": 1}", "unreadable"},
    };
    for (const Damage& d : damages) {
        SCOPED_TRACE(d.name);
        std::ofstream(first.file, std::ios::binary | std::ios::trunc) << d.text;
        EXPECT_FALSE(cachedPairHistograms(p[0], p[1], cache).has_value());
        PairHistogramsReport r;
        auto c = preparePairHistograms(p[0], p[1], cache, {}, &r);
        ASSERT_TRUE(c.ok()) << c.message();
        EXPECT_TRUE(r.built);
        EXPECT_EQ(r.reason.rfind("cache corrupt: ", 0), 0u) << r.reason;
        EXPECT_NE(r.reason.find(d.reason), std::string::npos) << r.reason;
        expectSame(*c, *a);
        EXPECT_EQ(readBytes(first.file), good);
    }
    for (const auto& e : fs::directory_iterator(cache / "pairstats"))
        EXPECT_EQ(e.path().filename().string().find(".partial"), std::string::npos) << e.path();
}

TEST(PairStatsTest, ChangedSourceGetsNewStatisticsAndTheOldFileGoes) {
    TempDir dir("pairstats-changed");
    auto scene = writeTestPair(dir.path(), 120, 90, 1.0);
    ASSERT_TRUE(scene.ok()) << scene.message();
    const fs::path cache = dir / "cache";
    std::vector<ImagePyramid> p = preparedPair(*scene, cache);
    ASSERT_EQ(p.size(), 2u);
    ASSERT_TRUE(preparePairHistograms(p[0], p[1], cache).ok());
    const fs::path old = pairHistogramsFile(p[0], p[1], cache);

    // Leaf-off rewritten with other pixels (a later modification time): new pyramid, new key, new statistics.
    writeTestImage(dir / "off.tif", 120, 90, testGeoref(1.0), false, 9);
    fs::last_write_time(dir / "off.tif", fs::last_write_time(dir / "off.tif") + std::chrono::seconds(5));
    SceneSources s;
    s.leafon = dir / "on.tif";
    s.leafoff = dir / "off.tif";
    auto changed = loadScene(s, cache);
    ASSERT_TRUE(changed.ok()) << changed.message();
    p = preparedPair(*changed, cache);
    PairHistogramsReport r;
    auto h = preparePairHistograms(p[0], p[1], cache, {}, &r);
    ASSERT_TRUE(h.ok()) << h.message();
    EXPECT_TRUE(r.built);
    EXPECT_NE(r.file, old);
    EXPECT_FALSE(fs::exists(old)) << "statistics of the replaced source are removed";
    expectSame(*h, pairHistograms(displayRgb(changed->leafon), displayRgb(changed->leafoff), true, true));
}

TEST(PairStatsTest, DamagedLevelZeroIsOneLineNamingTheFile) {
    TempDir dir("pairstats-damaged");
    auto scene = writeTestPair(dir.path(), 600, 520, 1.0);
    ASSERT_TRUE(scene.ok()) << scene.message();
    const fs::path cache = dir / "cache";
    const std::vector<ImagePyramid> p = preparedPair(*scene, cache);
    ASSERT_EQ(p.size(), 2u);
    const fs::path level0 = p[1].levels.at(0).file;
    const std::string bytes = readBytes(level0);
    ASSERT_GT(bytes.size(), 1000u);

    struct Damage {
        const char* name;
        std::function<void()> apply;
    };
    const std::vector<Damage> damages = {
        {"truncated", [&] { fs::resize_file(level0, bytes.size() / 2); }},
        {"tiles overwritten",
         [&] { // the directory intact, the compressed tiles in the middle of the file replaced by garbage
             std::string b = bytes;
             for (size_t i = b.size() / 4; i < b.size() / 2; ++i) b[i] = char(i * 7);
             std::ofstream(level0, std::ios::binary | std::ios::trunc) << b;
         }},
        {"deleted", [&] { fs::remove(level0); }},
    };
    for (const Damage& d : damages) {
        SCOPED_TRACE(d.name);
        std::ofstream(level0, std::ios::binary | std::ios::trunc) << bytes;
        d.apply();
        auto h = preparePairHistograms(p[0], p[1], cache);
        ASSERT_FALSE(h.ok());
        EXPECT_EQ(h.message().rfind(level0.string() + ": ", 0), 0u) << h.message();
        EXPECT_EQ(h.message().find('\n'), std::string::npos) << h.message();
        EXPECT_FALSE(fs::exists(pairHistogramsFile(p[0], p[1], cache))) << "no statistics from a damaged level";
    }
}

TEST(PairStatsTest, EverySampleCountedOnceInEachHistogram) {
    // 33 × 17 pixels: 17 sampled columns of 9 sampled rows, in each of the seven histograms.
    TempDir dir("pairstats-counts");
    auto scene = writeTestPair(dir.path(), 33, 17, 1.0);
    ASSERT_TRUE(scene.ok()) << scene.message();
    const std::vector<ImagePyramid> p = preparedPair(*scene, dir / "cache");
    auto h = preparePairHistograms(p[0], p[1], dir / "cache");
    ASSERT_TRUE(h.ok()) << h.message();
    const std::uint64_t samples = 17u * 9u;
    EXPECT_EQ(sum(h->drop), samples);
    for (size_t c = 0; c < 3; ++c) {
        std::uint64_t a = 0, b = 0;
        for (size_t v = 0; v < 256; ++v) {
            a += h->on[c][v];
            b += h->off[c][v];
        }
        EXPECT_EQ(a, samples);
        EXPECT_EQ(b, samples);
    }
}
