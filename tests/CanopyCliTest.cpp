// `render --view canopy` end to end: the derived canopy layer, the leaf-off ground under it and the stacked layers
// (golden images), `--canopy-layers off`, and the flags' errors.
#include "TestUtil.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <tuple>

using namespace seasonview;
using namespace seasonview::test;

namespace {

CliScene& scene() {
    static CliScene s("canopy-cli", {"--size-m", "256", "--gsd", "0.25", "--seed", "7"}, "320x240", "-40,40,+60,150,-45");
    return s;
}

} // namespace

TEST(CanopyCliTest, CanopyViewGoldens) {
    const CliScene& s = scene();
    for (auto [layers, trunks, golden] : {std::tuple{"16", "on", "canopy_layers16"}, std::tuple{"16", "off", "canopy_layers16_no_trunks"},
                                          std::tuple{"off", "on", "canopy_ground"}}) {
        const CliResult r = s.render(std::string(golden) + ".png", {"--view", "canopy", "--canopy-layers", layers, "--trunks", trunks});
        ASSERT_EQ(r.exitCode, 0) << r.err;
        const Image<std::uint8_t> img = s.image(std::string(golden) + ".png");
        // Layer edges move by a pixel between rasteriser builds (max); the mean catches a wrong canopy.
        compareWithGolden(golden, img.pixels, img.width, img.height, 255, 3.0);
    }
}

// The ground alone differs from plain leaf-on exactly where the canopy is (leaf-off there), and the layers change
// the picture again (crowns standing up, hiding ground behind them).
TEST(CanopyCliTest, GroundUnderTheCanopyIsLeafOffAndLayersStandUp) {
    const CliScene& s = scene();
    ASSERT_EQ(s.render("on.png", {"--view", "leafon"}).exitCode, 0);
    ASSERT_EQ(s.render("ground.png", {"--view", "canopy", "--canopy-layers", "off"}).exitCode, 0);
    ASSERT_EQ(s.render("layers.png", {"--view", "canopy"}).exitCode, 0);
    const auto on = s.image("on.png"), ground = s.image("ground.png"), layers = s.image("layers.png");
    ASSERT_EQ(on.pixels.size(), ground.pixels.size());
    ASSERT_EQ(on.pixels.size(), layers.pixels.size());
    auto changed = [](const Image<std::uint8_t>& a, const Image<std::uint8_t>& b) {
        std::int64_t n = 0;
        for (size_t i = 0; i < a.pixels.size(); i += 3)
            n += std::abs(int(a.pixels[i]) - int(b.pixels[i])) + std::abs(int(a.pixels[i + 1]) - int(b.pixels[i + 1])) +
                             std::abs(int(a.pixels[i + 2]) - int(b.pixels[i + 2])) >
                         40
                     ? 1
                     : 0;
        return double(n) / double(a.pixels.size() / 3);
    };
    const double groundChange = changed(on, ground), layerChange = changed(ground, layers);
    EXPECT_GT(groundChange, 0.01) << "the ground under the crowns should switch to leaf-off";
    EXPECT_LT(groundChange, 0.9);
    EXPECT_GT(layerChange, 0.05) << "the stacked layers should cover the leaf-off ground";
}

// Both ground seasons are flags: leaf-on everywhere is the leaf-on view, leaf-off everywhere the leaf-off view.
TEST(CanopyCliTest, GroundSeasonsAreConfigurable) {
    const CliScene& s = scene();
    for (const char* season : {"leafon", "leafoff"}) {
        ASSERT_EQ(s.render(std::string(season) + "_view.png", {"--view", season}).exitCode, 0);
        const CliResult r = s.render(std::string(season) + "_ground.png",
                                     {"--view", "canopy", "--canopy-layers", "off", "--ground-under-canopy", season,
                                      "--ground-elsewhere", season});
        ASSERT_EQ(r.exitCode, 0) << r.err;
        const auto view = s.image(std::string(season) + "_view.png"), ground = s.image(std::string(season) + "_ground.png");
        EXPECT_EQ(view.pixels, ground.pixels) << season;
    }
    // The default (leaf-off under the crowns) differs from both.
    ASSERT_EQ(s.render("default_ground.png", {"--view", "canopy", "--canopy-layers", "off"}).exitCode, 0);
    EXPECT_NE(s.image("default_ground.png").pixels, s.image("leafon_view.png").pixels);
}

// Trunks stand under the crowns, which are lifted to their base: on and off differ, and the trunks' bark colour
// (brown, red above green and blue) appears only with them.
TEST(CanopyCliTest, TrunksStandUnderTheCrowns) {
    const CliScene& s = scene();
    // Leaf-on ground under the crowns here, so that the lifted crowns uncover no brown leaf-off ground.
    ASSERT_EQ(s.render("trunks_on.png", {"--view", "canopy", "--trunks", "on", "--ground-under-canopy", "leafon"}).exitCode, 0);
    ASSERT_EQ(s.render("trunks_off.png", {"--view", "canopy", "--trunks", "off", "--ground-under-canopy", "leafon"}).exitCode, 0);
    const auto on = s.image("trunks_on.png"), off = s.image("trunks_off.png");
    ASSERT_EQ(on.pixels.size(), off.pixels.size());
    auto bark = [](const Image<std::uint8_t>& img) {
        int n = 0;
        for (size_t i = 0; i < img.pixels.size(); i += 3) {
            const int r = img.pixels[i], g = img.pixels[i + 1], b = img.pixels[i + 2];
            n += r > g + 12 && g > b + 8 && r < 140 && r > 40 ? 1 : 0;
        }
        return n;
    };
    EXPECT_NE(on.pixels, off.pixels);
    std::printf("bark-coloured pixels: %d with trunks, %d without\n", bark(on), bark(off));
    EXPECT_GT(bark(on), bark(off) + 20) << "no trunks drawn";
}

TEST(CanopyCliTest, BadCanopyFlagsFailWithOneLine) {
    const CliScene& s = scene();
    for (auto [args, needle] : {std::pair{std::vector<std::string>{"--view", "canopy", "--canopy-layers", "0"}, "--canopy-layers"},
                                std::pair{std::vector<std::string>{"--view", "canopy", "--canopy-layers", "x"}, "--canopy-layers"},
                                std::pair{std::vector<std::string>{"--view", "canopy", "--method", "magic"}, "--method"},
                                std::pair{std::vector<std::string>{"--view", "canopy", "--k", "4"}, "--k"},
                                std::pair{std::vector<std::string>{"--view", "canopy", "--ground-under-canopy", "winter"}, "--ground-under-canopy"},
                                std::pair{std::vector<std::string>{"--view", "canopy", "--ground-elsewhere", "x"}, "--ground-elsewhere"},
                                std::pair{std::vector<std::string>{"--view", "canopy", "--trunks", "yes"}, "--trunks"},
                                std::pair{std::vector<std::string>{"--view", "canopy", "--canopy-draw", "rays"}, "--canopy-draw"},
                                std::pair{std::vector<std::string>{"--view", "canopy", "--canopy-derive", "fpga"}, "--canopy-derive"},
                                std::pair{std::vector<std::string>{"--view", "canopy", "--canopy-levels", "some"}, "--canopy-levels"}}) {
        const CliResult r = s.render("bad.png", args);
        EXPECT_EQ(r.exitCode, 1);
        EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
        EXPECT_FALSE(std::filesystem::exists(s.dir / "bad.png"));
    }
}

// The two ways of drawing the stacked layers show the same canopy: every layer rasterised (§4.2 as written) and the
// top layer rasterised with each pixel's ray intersected with the layers below. They differ at crown edges, where
// the rasterised layers are thinned to one per pixel of stack and the march takes every layer, and by the march's
// planar-terrain intersection on slopes; a march that missed layers or put them at the wrong height would change
// whole crowns.
// The march runs in the deferred terrain resolve (one full-screen pass for crowns and ground) or, with forward
// terrain shading, in its own full-screen pass before the terrain (CanopyRendererGL::marchForward): the same pixels.
TEST(CanopyCliTest, MarchedLayersTheSameWithForwardAndDeferredTerrain) {
    const CliScene& s = scene();
    for (const char* trunks : {"on", "off"}) {
        ASSERT_EQ(s.render("deferred.png", {"--view", "canopy", "--trunks", trunks}).exitCode, 0);
        ASSERT_EQ(s.render("forward.png", {"--view", "canopy", "--trunks", trunks, "--terrain-shading", "forward"}).exitCode, 0);
        ASSERT_EQ(s.render("ground.png", {"--view", "canopy", "--canopy-layers", "off", "--trunks", trunks}).exitCode, 0);
        const auto deferred = s.image("deferred.png"), forward = s.image("forward.png"), ground = s.image("ground.png");
        ASSERT_EQ(deferred.pixels.size(), forward.pixels.size());
        int worst = 0;
        size_t crowns = 0;
        for (size_t i = 0; i < deferred.pixels.size(); ++i) {
            worst = std::max(worst, std::abs(int(deferred.pixels[i]) - int(forward.pixels[i])));
            crowns += deferred.pixels[i] != ground.pixels[i];
        }
        EXPECT_EQ(worst, 0) << trunks;
        EXPECT_GT(crowns, deferred.pixels.size() / 50) << trunks; // the crowns are drawn at all
    }
}

// The canopy layer derived on the CPU (the default) and by the compute shader: the same canopy. The GPU leaves the
// clip windows' outer ring of blocks underived (it waits for neighbours never resident), which lookups take from the
// next coarser level, so a few pixels where that ring is seen may differ; whole crowns may not.
TEST(CanopyCliTest, CpuAndGpuDerivedCanopyDrawsTheSame) {
    const CliScene& s = scene();
    ASSERT_EQ(s.render("cpu.png", {"--view", "canopy", "--canopy-derive", "cpu"}).exitCode, 0);
    ASSERT_EQ(s.render("gpu.png", {"--view", "canopy", "--canopy-derive", "gpu"}).exitCode, 0);
    ASSERT_EQ(s.render("ground.png", {"--view", "canopy", "--canopy-layers", "off"}).exitCode, 0);
    const auto cpu = s.image("cpu.png"), gpu = s.image("gpu.png"), ground = s.image("ground.png");
    ASSERT_EQ(cpu.pixels.size(), gpu.pixels.size());
    size_t differing = 0, crowns = 0;
    for (size_t i = 0; i < cpu.pixels.size(); ++i) {
        differing += cpu.pixels[i] != gpu.pixels[i];
        crowns += cpu.pixels[i] != ground.pixels[i];
    }
    EXPECT_GT(crowns, cpu.pixels.size() / 50); // the crowns are drawn at all
    EXPECT_LT(differing, cpu.pixels.size() / 200) << differing << " of " << cpu.pixels.size() << " samples differ";
}

TEST(CanopyCliTest, MarchedLayersMatchRasterisedLayers) {
    const CliScene& s = scene();
    for (const char* trunks : {"on", "off"}) {
        ASSERT_EQ(s.render("layers.png", {"--view", "canopy", "--canopy-draw", "layers", "--trunks", trunks}).exitCode, 0);
        ASSERT_EQ(s.render("march.png", {"--view", "canopy", "--canopy-draw", "march", "--trunks", trunks}).exitCode, 0);
        ASSERT_EQ(s.render("ground.png", {"--view", "canopy", "--canopy-layers", "off", "--trunks", trunks}).exitCode, 0);
        const auto layers = s.image("layers.png"), march = s.image("march.png"), ground = s.image("ground.png");
        ASSERT_EQ(layers.pixels.size(), march.pixels.size());
        double diff = 0.0, canopy = 0.0; // mean absolute difference per channel: the two modes, the layers' effect
        for (size_t i = 0; i < layers.pixels.size(); ++i) {
            diff += std::abs(int(layers.pixels[i]) - int(march.pixels[i]));
            canopy += std::abs(int(layers.pixels[i]) - int(ground.pixels[i]));
        }
        diff /= double(layers.pixels.size());
        canopy /= double(layers.pixels.size());
        // Measured: 0.69 (trunks on) and 0.86 (off) between the modes, against 17.6 and 21.2 for what the layers
        // change.
        EXPECT_LT(diff, 3.0) << trunks;
        EXPECT_GT(canopy, 4.0 * diff) << trunks;
    }
}

// The march's record is drawn at half the frame's resolution (CanopyRendererGL::kEntryScale), its texels spanning
// two pixels each way, past the frame's edge for an odd size: at 321×241 the marched crowns still match the
// rasterised layers, over the whole frame and in its last two columns and rows, which only the record's last texels
// cover.
TEST(CanopyCliTest, MarchedLayersAtAnOddSizeMatchToTheFramesEdge) {
    const CliScene& s = scene();
    auto render = [&](const std::string& out, const std::vector<std::string>& extra) {
        std::vector<std::string> a = {"render", (s.dir / "s/scene.json").string(), "--size", "321x241", "--camera",
                                      s.camera, "--clip-size", "512", "--cache", (s.dir / "cache").string(),
                                      "--out", (s.dir / out).string(), "--view", "canopy", "--trunks", "off"};
        a.insert(a.end(), extra.begin(), extra.end());
        return runCli(a).exitCode;
    };
    ASSERT_EQ(render("odd_layers.png", {"--canopy-draw", "layers"}), 0);
    ASSERT_EQ(render("odd_march.png", {"--canopy-draw", "march"}), 0);
    ASSERT_EQ(render("odd_ground.png", {"--canopy-layers", "off"}), 0);
    const auto layers = s.image("odd_layers.png"), march = s.image("odd_march.png"), ground = s.image("odd_ground.png");
    ASSERT_EQ(layers.width, 321);
    ASSERT_EQ(layers.height, 241);
    ASSERT_EQ(march.pixels.size(), layers.pixels.size());
    auto meanOver = [&](const auto& a, const auto& b, bool edgeOnly) {
        double sum = 0.0;
        size_t n = 0;
        for (int y = 0; y < layers.height; ++y)
            for (int x = 0; x < layers.width; ++x) {
                if (edgeOnly && x < layers.width - 2 && y < layers.height - 2) continue;
                for (int c = 0; c < 3; ++c) {
                    const size_t i = (size_t(y) * size_t(layers.width) + size_t(x)) * 3 + size_t(c);
                    sum += std::abs(int(a.pixels[i]) - int(b.pixels[i]));
                    ++n;
                }
            }
        return sum / double(n);
    };
    const double diff = meanOver(layers, march, false), canopy = meanOver(layers, ground, false);
    const double edgeDiff = meanOver(layers, march, true), edgeCanopy = meanOver(layers, ground, true);
    std::printf("odd size: march vs layers %.2f (the layers' effect %.2f); last two columns and rows %.2f (%.2f)\n",
                diff, canopy, edgeDiff, edgeCanopy);
    EXPECT_LT(diff, 3.0);
    EXPECT_GT(canopy, 4.0 * diff);
    EXPECT_LT(edgeDiff, 3.0);
    EXPECT_GT(edgeCanopy, 4.0 * edgeDiff);
}
