// City models end to end: `synth`'s buildings, `atlas build`/`atlas info`, `render --city atlas|original|flat`
// (golden images; the atlas close to the originals; roofs from the imagery), an OBJ in a national grid placed with
// `--city-crs`, the real Berlin and Tokyo models with their own photo textures, and bad input.
#include "BlockMap.h"
#include "TestUtil.h"

#include <glm/common.hpp>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

using namespace seasonview;
using namespace seasonview::test;

namespace {

/// Mean per-channel difference of two RGB images over the pixels where `mask` differs from `a` (the city).
struct RegionDiff {
    double psnr = 0.0;
    std::size_t pixels = 0;
};
RegionDiff diffWhere(const Image<std::uint8_t>& a, const Image<std::uint8_t>& b, const Image<std::uint8_t>& without) {
    double sq = 0.0;
    RegionDiff r;
    for (std::size_t i = 0; i < a.pixels.size(); i += 3) {
        int changed = 0;
        for (int c = 0; c < 3; ++c) changed += std::abs(int(a.pixels[i + std::size_t(c)]) - int(without.pixels[i + std::size_t(c)]));
        if (changed < 30) continue; // not a city pixel
        ++r.pixels;
        for (int c = 0; c < 3; ++c) {
            const double d = double(a.pixels[i + std::size_t(c)]) - double(b.pixels[i + std::size_t(c)]);
            sq += d * d;
        }
    }
    const double mse = r.pixels ? sq / double(r.pixels * 3) : 0.0;
    r.psnr = mse > 0.0 ? 10.0 * std::log10(255.0 * 255.0 / mse) : 99.0;
    return r;
}

// 512 m at 0.5 m: eight houses in the north-east corner (seed 1).
/// A one-line error naming `needle`, exit code 1.
void fails(const CliResult& r, const std::string& needle) {
    EXPECT_EQ(r.exitCode, 1) << r.out << r.err;
    EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
}

CliScene& scene() {
    static CliScene s("city-cli", {"--size-m", "512", "--gsd", "0.5", "--facade-size", "128"}, "400x250",
                      "195,140,+18,35,-18,60");
    return s;
}

} // namespace

// An atlas tree in the cache whose atlases rotted (a byte flipped every KiB of them; the index intact, so the tree
// opens) is never drawn: its atlases fail their checksums, the still is refused with one line naming the tree, the tree
// is removed, and the next run builds it again from the model and renders the same picture. (A tree cut short does
// not open, and is built again before anything is drawn.)
TEST(CityCliTest, DamagedCachedTreeIsRefusedThenBuiltAgain) {
    const CliScene s("city-cli-damaged", {"--size-m", "512", "--gsd", "0.5", "--facade-size", "128"}, "400x250",
                     "195,140,+18,35,-18,60");
    const CliResult first = s.render("first.png", {"--city", "atlas"});
    ASSERT_EQ(first.exitCode, 0) << first.err;
    std::vector<std::filesystem::path> trees;
    for (const auto& e : std::filesystem::directory_iterator(s.dir / "cache/atlas"))
        if (e.path().extension() == ".svat") trees.push_back(e.path());
    ASSERT_EQ(trees.size(), 1u);
    std::string bytes = readBytes(trees[0]);
    std::uint64_t indexOffset = 0;
    ASSERT_GT(bytes.size(), 32u);
    std::memcpy(&indexOffset, bytes.data() + 16, sizeof indexOffset); // the header: magic, version, CRC, offset
    ASSERT_LT(indexOffset, bytes.size());
    for (std::uint64_t i = 32 + 100; i < indexOffset; i += 1024) bytes[size_t(i)] = char(bytes[size_t(i)] ^ 0x20);
    std::ofstream(trees[0], std::ios::binary | std::ios::trunc) << bytes;
    const CliResult damaged = s.render("damaged.png", {"--city", "atlas"});
    fails(damaged, trees[0].filename().string());
    EXPECT_FALSE(std::filesystem::exists(s.dir / "damaged.png")) << "no still with a block missing";
    EXPECT_FALSE(std::filesystem::exists(trees[0])) << "the damaged tree is removed from the cache";
    EXPECT_NE(damaged.out.find("built again from the city model on the next run"), std::string::npos) << damaged.out;
    const CliResult again = s.render("again.png", {"--city", "atlas"});
    ASSERT_EQ(again.exitCode, 0) << again.err;
    EXPECT_NE(again.out.find("built the atlas tree"), std::string::npos) << again.out;
    EXPECT_EQ(s.image("again.png").pixels, s.image("first.png").pixels);
}

TEST(CityCliTest, SyntheticCityGoldensAndModes) {
    const CliScene& s = scene();
    ASSERT_EQ(s.render("none.png", {}).exitCode, 0);
    const CliResult atlas = s.render("city_synth_atlas.png", {"--city", "atlas"});
    ASSERT_EQ(atlas.exitCode, 0) << atlas.err;
    EXPECT_NE(atlas.out.find("built the atlas tree"), std::string::npos) << atlas.out; // implicit, into the cache
    const CliResult again = s.render("atlas2.png", {"--city", "atlas"});
    ASSERT_EQ(again.exitCode, 0);
    EXPECT_EQ(again.out.find("built the atlas tree"), std::string::npos) << "the cached tree is reused";
    ASSERT_EQ(s.render("city_synth_original.png", {"--city", "original"}).exitCode, 0);
    ASSERT_EQ(s.render("city_synth_flat.png", {"--city", "flat"}).exitCode, 0);
    const auto none = s.image("none.png"), a = s.image("city_synth_atlas.png"), o = s.image("city_synth_original.png"),
               f = s.image("city_synth_flat.png");
    // Rasterisation differs by a pixel along edges between llvmpipe builds (max); the mean catches a wrong city.
    compareWithGolden("city_synth_atlas", a.pixels, a.width, a.height, 255, 3.0);
    compareWithGolden("city_synth_flat", f.pixels, f.width, f.height, 255, 3.0);
    // The buildings are there (a few percent of the frame), the atlas shows what the originals show, flat does not.
    const RegionDiff ao = diffWhere(a, o, none);
    EXPECT_GT(ao.pixels, a.pixels.size() / 3 / 50) << "buildings should cover a few percent of the frame";
    EXPECT_GT(ao.psnr, 30.0) << "atlas vs original textures";
    EXPECT_LT(diffWhere(f, o, none).psnr, ao.psnr - 5.0) << "the dummy texture should look different";
}

// BC atlases uploaded as they are or decoded to RGB8 (what llvmpipe samples fastest): the same picture, and the pager
// counts what was uploaded (decoded atlases take six times the bytes, still under the capacity).
TEST(CityCliTest, AtlasUploadCompressedOrDecoded) {
    const CliScene& s = scene();
    ASSERT_EQ(s.render("up_none.png", {}).exitCode, 0);
    for (const char* u : {"compressed", "decoded", "auto"}) {
        const CliResult r = s.render(std::string("up_") + u + ".png", {"--city", "atlas", "--city-upload", u});
        ASSERT_EQ(r.exitCode, 0) << u << ": " << r.err;
    }
    const auto none = s.image("up_none.png"), c = s.image("up_compressed.png"), d = s.image("up_decoded.png"),
               a = s.image("up_auto.png");
    const RegionDiff cd = diffWhere(c, d, none);
    EXPECT_GT(cd.pixels, c.pixels.size() / 3 / 50);
    EXPECT_GT(cd.psnr, 40.0) << "our BC1 decoder vs the GL's";
    EXPECT_TRUE(a.pixels == c.pixels || a.pixels == d.pixels) << "auto is one of the two";

    // Two frames at the still's camera, each upload in turn.
    std::ofstream(s.dir / "still.json")
        << R"([{"time":0,"x":195,"y":140,"z":"+18","yaw":35,"pitch":-18,"fov":60},)"
        << R"({"time":1,"x":196,"y":141,"z":"+18","yaw":36,"pitch":-18,"fov":60}])";
    const CliResult b = runCli({"bench", (s.dir / "s/scene.json").string(), "--path", (s.dir / "still.json").string(),
                                "--frames", "3", "--warmup", "1", "--size", "200x125", "--coverage-every", "0",
                                "--compare", "city-upload=compressed,decoded", "--out", (s.dir / "upbench").string()});
    ASSERT_EQ(b.exitCode, 0) << b.err;
    std::ifstream sj(s.dir / "upbench/summary.json");
    const auto summary = nlohmann::json::parse(sj);
    const auto& cm = summary["modes"]["city-upload=compressed"]["city"];
    const auto& dm = summary["modes"]["city-upload=decoded"]["city"];
    ASSERT_TRUE(cm.is_object() && dm.is_object()) << summary.dump();
    EXPECT_EQ(dm["atlases_decoded"], true);
    const double cb = cm["resident_bytes"]["max"].get<double>(), db = dm["resident_bytes"]["max"].get<double>();
    EXPECT_GT(cb, 0.0);
    EXPECT_LE(db, dm["capacity_bytes"].get<double>());
    // A GL without S3TC decodes in both modes (llvmpipe and GPUs have it).
    if (cm["atlases_decoded"] == false) {
        EXPECT_GT(db, 3.5 * cb) << "RGB8 with mips is six times BC1 (RGBA8 four times BC3)";
    }
    EXPECT_GT(cm["cpu_ms"]["median"].get<double>(), 0.0) << "the city's own submission time is measured";
    std::ifstream csv(s.dir / "upbench/frames.csv");
    std::string header;
    std::getline(csv, header);
    EXPECT_NE(header.find(",city_cpu_ms"), std::string::npos) << header;

    const CliResult bad = s.render("x.png", {"--city", "atlas", "--city-upload", "sideways"});
    EXPECT_NE(bad.exitCode, 0);
    EXPECT_NE(bad.err.find("--city-upload"), std::string::npos) << bad.err;
}

// `--compare city-flush=off,on` (the terrain handed to the GPU before the city's paging, or not) and `--stages
// finish`: each frame's stages (streaming, terrain, the city's paging and draws) issued and waited for one by one,
// their times within the frame's; the city's paging is a part of its CPU time.
TEST(CityCliTest, FlushFirstAndStagesAreMeasured) {
    const CliScene& s = scene();
    std::ofstream(s.dir / "flush.json")
        << R"([{"time":0,"x":195,"y":140,"z":"+18","yaw":35,"pitch":-18,"fov":60},)"
        << R"({"time":1,"x":190,"y":130,"z":"+25","yaw":40,"pitch":-20,"fov":60}])";
    const CliResult b = runCli({"bench", (s.dir / "s/scene.json").string(), "--path", (s.dir / "flush.json").string(),
                                "--frames", "3", "--warmup", "1", "--size", "200x125", "--coverage-every", "0",
                                "--compare", "city-flush=off,on", "--stages", "finish", "--out",
                                (s.dir / "flushbench").string()});
    ASSERT_EQ(b.exitCode, 0) << b.err;
    std::ifstream sj(s.dir / "flushbench/summary.json");
    const auto summary = nlohmann::json::parse(sj);
    for (const char* m : {"city-flush=off", "city-flush=on"}) {
        const auto& mode = summary["modes"][m];
        ASSERT_TRUE(mode["city"].is_object()) << m << ": " << summary.dump();
        EXPECT_EQ(mode["city"]["flush_first"], std::string(m) == "city-flush=on") << m;
        EXPECT_EQ(mode["city"]["mode"], "atlas") << m;
        std::set<std::string> names;
        for (const auto& st : mode["stages"]) names.insert(st["stage"].get<std::string>());
        for (const char* want : {"imagery_clipmap", "elevation_clipmap", "terrain", "city_paging", "city_draw"})
            EXPECT_TRUE(names.count(want)) << m << " lacks stage " << want << ": " << mode["stages"].dump();
    }
    // frames.csv: per frame, the frame time and the city's times.
    std::map<std::pair<std::string, int>, double> frameMs;
    {
        std::ifstream csv(s.dir / "flushbench/frames.csv");
        std::string header;
        std::getline(csv, header);
        std::vector<std::string> cols;
        std::stringstream h(header);
        for (std::string c; std::getline(h, c, ',');) cols.push_back(c);
        const auto col = [&](const std::string& n) {
            return std::size_t(std::find(cols.begin(), cols.end(), n) - cols.begin());
        };
        for (const char* c : {"city_update_ms", "city_upload_ms", "city_wait_ms", "city_uploaded_bytes", "stream_ms"})
            ASSERT_LT(col(c), cols.size()) << c << " missing from " << header;
        int rows = 0;
        for (std::string line; std::getline(csv, line); ++rows) {
            std::vector<std::string> cells;
            std::stringstream l(line);
            for (std::string c; std::getline(l, c, ',');) cells.push_back(c);
            ASSERT_EQ(cells.size(), cols.size()) << line;
            const double cpu = std::stod(cells[col("city_cpu_ms")]), update = std::stod(cells[col("city_update_ms")]),
                         upload = std::stod(cells[col("city_upload_ms")]);
            EXPECT_LE(update, cpu) << "the paging is part of the city's CPU time: " << line;
            EXPECT_LE(upload, update) << "the uploads are part of the paging: " << line;
            EXPECT_LE(std::stod(cells[col("stream_ms")]), std::stod(cells[col("cpu_ms")])) << line;
            frameMs[{cells[col("mode")], std::stoi(cells[col("frame")])}] = std::stod(cells[col("frame_ms")]);
        }
        EXPECT_EQ(rows, 6);
    }
    // stages.csv: every measured frame's stages, each issued then waited for within that frame.
    std::ifstream st(s.dir / "flushbench/stages.csv");
    std::string header;
    std::getline(st, header);
    EXPECT_EQ(header, "mode,frame,stage,cpu_ms,wait_ms");
    std::map<std::pair<std::string, int>, double> stageSum;
    for (std::string line; std::getline(st, line);) {
        std::vector<std::string> cells;
        std::stringstream l(line);
        for (std::string c; std::getline(l, c, ',');) cells.push_back(c);
        ASSERT_EQ(cells.size(), 5u) << line;
        const double cpu = std::stod(cells[3]), wait = std::stod(cells[4]);
        EXPECT_GE(cpu, 0.0) << line;
        EXPECT_GE(wait, 0.0) << line;
        stageSum[{cells[0], std::stoi(cells[1])}] += cpu + wait;
    }
    ASSERT_EQ(stageSum.size(), frameMs.size());
    for (const auto& [key, sum] : stageSum) {
        ASSERT_TRUE(frameMs.count(key)) << key.first << " frame " << key.second;
        EXPECT_LE(sum, frameMs[key]) << key.first << " frame " << key.second << ": stages within the frame";
        EXPECT_GT(sum, 0.0);
    }
    const CliResult bad = runCli({"bench", (s.dir / "s/scene.json").string(), "--stages", "sometimes", "--out",
                                  (s.dir / "badstages").string()});
    EXPECT_NE(bad.exitCode, 0);
    EXPECT_NE(bad.err.find("--stages"), std::string::npos) << bad.err;
}

// Occlusion culling (atlas mode): at street level in a block city the nodes behind the first buildings are skipped
// and the picture stays the same pixel for pixel; from above or at an angle nothing visible is lost either. In a walk
// down the street (bench) the hidden nodes stay skipped frame after frame.
TEST(CityCliTest, OcclusionCullingSkipsOnlyHiddenNodes) {
    static CliScene s("city-occl", {"--size-m", "512", "--gsd", "1", "--block-city", "160", "--facade-size", "64"},
                      "400x250", "-60,-110,+2,10,2");
    auto render = [&](const std::string& name, const std::string& camera, const char* occlusion) {
        const CliResult r = runCli({"render", (s.dir / "s/scene.json").string(), "--size", s.size, "--camera", camera,
                                    "--clip-size", "512", "--cache", (s.dir / "cache").string(), "--city", "atlas",
                                    "--city-occlusion", occlusion, "--stats", (s.dir / (name + ".json")).string(),
                                    "--out", (s.dir / (name + ".png")).string()});
        EXPECT_EQ(r.exitCode, 0) << r.err;
        std::ifstream f(s.dir / (name + ".json"));
        return f ? nlohmann::json::parse(f)["city"] : nlohmann::json::object();
    };
    for (const std::string camera : {"-60,-110,+2,10,2", "20,-200,+45,0,-15", "0,0,+400,0,-89", "-30,-5,+3,70,0"}) {
        const auto off = render("off", camera, "off"), on = render("on", camera, "on");
        ASSERT_TRUE(on.contains("atlas_nodes") && off.contains("atlas_nodes")) << camera;
        EXPECT_EQ(off["occlusion"], false);
        EXPECT_EQ(off["occlusion_queries"], 0);
        EXPECT_EQ(on["occlusion"], true);
        EXPECT_GT(on["occlusion_queries"].get<int>(), 0) << camera;
        EXPECT_LE(on["atlas_nodes"].get<int>(), off["atlas_nodes"].get<int>()) << camera;
        // Every atlas drawn is resident; a still waits for its blocks.
        EXPECT_GE(on["blocks_resident"].get<int>(), on["atlas_nodes"].get<int>()) << camera;
        EXPECT_GE(on["texture_binds"].get<int>(), 1) << camera;
        EXPECT_EQ(on["loader_queue"].get<int>(), 0) << camera;
        EXPECT_EQ(on["allocated_bytes"], on["resident_bytes"]) << camera; // the GL side holds what the pager counts
        EXPECT_GT(on["allocated_bytes"].get<std::int64_t>(), 0) << camera;
        const auto a = s.image("off.png"), b = s.image("on.png");
        EXPECT_TRUE(a.pixels == b.pixels) << camera << ": occlusion culling changed the picture";
        if (camera == "-60,-110,+2,10,2") {
            // Street level: most of the city is behind the first row.
            EXPECT_GT(on["occluded_nodes"].get<int>(), 0);
            EXPECT_LT(on["atlas_nodes"].get<int>(), off["atlas_nodes"].get<int>());
            EXPECT_LT(on["triangles"].get<int>(), off["triangles"].get<int>());
        }
    }

    std::ofstream(s.dir / "walk.json") << R"([{"time":0,"x":-60,"y":-110,"z":"+2","yaw":10,"pitch":2},)"
                                       << R"({"time":1,"x":-58,"y":-95,"z":"+2","yaw":0,"pitch":2}])";
    const CliResult b = runCli({"bench", (s.dir / "s/scene.json").string(), "--path", (s.dir / "walk.json").string(),
                                "--frames", "6", "--warmup", "1", "--size", "400x250", "--coverage-every", "0",
                                "--cache", (s.dir / "cache").string(), "--compare", "city-occlusion=off,on", "--out",
                                (s.dir / "walk").string()});
    ASSERT_EQ(b.exitCode, 0) << b.err;
    std::ifstream sj(s.dir / "walk/summary.json");
    const auto summary = nlohmann::json::parse(sj);
    const auto& on = summary["modes"]["city-occlusion=on"]["city"];
    const auto& off = summary["modes"]["city-occlusion=off"]["city"];
    ASSERT_TRUE(on.is_object() && off.is_object()) << summary.dump();
    EXPECT_EQ(on["occlusion"], true);
    EXPECT_EQ(off["occlusion"], false);
    EXPECT_EQ(off["occluded_nodes"]["max"].get<double>(), 0.0);
    EXPECT_GT(on["occluded_nodes"]["median"].get<double>(), 0.0) << "hidden nodes stay skipped while walking";
    EXPECT_LT(on["atlas_nodes"]["median"].get<double>(), off["atlas_nodes"]["median"].get<double>());
    std::ifstream csv(s.dir / "walk/frames.csv");
    std::string header;
    std::getline(csv, header);
    for (const char* col : {",city_occluded_nodes", ",city_occlusion_queries", ",city_occlusion_waits"})
        EXPECT_NE(header.find(col), std::string::npos) << header;
}

// `--terrain off`: the city drawn alone (as Buchholz & Döllner timed the facades): the same city pixels as over
// the terrain, nothing else drawn, and in a bench every draw call and triangle is the city's.
TEST(CityCliTest, TerrainOffDrawsTheCityAlone) {
    const CliScene& s = scene();
    const auto stats = [&](const std::string& name) {
        std::ifstream f(s.dir / name);
        return f ? nlohmann::json::parse(f) : nlohmann::json::object();
    };
    ASSERT_EQ(s.render("alone.png", {"--city", "flat", "--terrain", "off", "--stats", (s.dir / "alone.json").string()})
                  .exitCode,
              0);
    ASSERT_EQ(s.render("over.png", {"--city", "flat", "--stats", (s.dir / "over.json").string()}).exitCode, 0);
    const auto alone = stats("alone.json"), over = stats("over.json");
    ASSERT_TRUE(alone.contains("city") && over.contains("city")) << alone.dump();
    EXPECT_GT(alone["city"]["triangles"].get<std::int64_t>(), 0);
    EXPECT_EQ(alone["triangles"], alone["city"]["triangles"]) << "only the city's triangles are drawn";
    EXPECT_GT(over["triangles"].get<std::int64_t>(), over["city"]["triangles"].get<std::int64_t>());
    const auto a = s.image("alone.png"), o = s.image("over.png");
    ASSERT_EQ(a.pixels.size(), o.pixels.size());
    // The background is the clear colour (the view's top-left corner is sky); the city's pixels are as drawn over
    // the terrain, except where the ground hides them (wall feet, a house behind the rise: 11 % here).
    const std::uint8_t* bg = a.pixels.data();
    std::size_t city = 0, same = 0, background = 0;
    for (std::size_t i = 0; i < a.pixels.size(); i += 3) {
        const bool isBg = a.pixels[i] == bg[0] && a.pixels[i + 1] == bg[1] && a.pixels[i + 2] == bg[2];
        if (isBg) {
            ++background;
            continue;
        }
        ++city;
        int d = 0;
        for (std::size_t c = 0; c < 3; ++c) d = std::max(d, std::abs(int(a.pixels[i + c]) - int(o.pixels[i + c])));
        if (d <= 2) ++same;
    }
    EXPECT_GT(city, a.pixels.size() / 3 / 100) << "the houses are in view";
    EXPECT_GT(background, a.pixels.size() / 3 / 2) << "no terrain";
    EXPECT_GT(double(same), 0.8 * double(city));

    // bench: every draw call and triangle is the city's; terrain=on,off compares both in one run.
    std::ofstream(s.dir / "alone_path.json")
        << R"([{"time":0,"x":195,"y":140,"z":"+18","yaw":35,"pitch":-18,"fov":60},)"
        << R"({"time":1,"x":196,"y":141,"z":"+18","yaw":36,"pitch":-18,"fov":60}])";
    const auto bench = [&](const std::string& out, std::vector<std::string> extra) {
        std::vector<std::string> args = {"bench", (s.dir / "s/scene.json").string(), "--path",
                                         (s.dir / "alone_path.json").string(), "--frames", "3", "--warmup", "1",
                                         "--size", "200x125", "--coverage-every", "0", "--out", (s.dir / out).string()};
        args.insert(args.end(), extra.begin(), extra.end());
        return runCli(args);
    };
    const CliResult b = bench("alone_bench", {"--terrain", "off", "--compare", "city=atlas,flat"});
    ASSERT_EQ(b.exitCode, 0) << b.err;
    std::ifstream csv(s.dir / "alone_bench/frames.csv");
    std::string line;
    std::getline(csv, line);
    std::vector<std::string> header;
    for (std::stringstream h(line); std::getline(h, line, ',');) header.push_back(line);
    const auto col = [&](const std::string& name) {
        return std::size_t(std::find(header.begin(), header.end(), name) - header.begin());
    };
    const std::size_t dc = col("draw_calls"), cdc = col("city_draw_calls"), tri = col("triangles"),
                      ctri = col("city_triangles");
    ASSERT_LT(std::max({dc, cdc, tri, ctri}), header.size());
    int rows = 0;
    while (std::getline(csv, line)) {
        std::vector<std::string> f;
        for (std::stringstream r(line); std::getline(r, line, ',');) f.push_back(line);
        ASSERT_EQ(f.size(), header.size());
        EXPECT_EQ(f[dc], f[cdc]) << f[0];
        EXPECT_EQ(f[tri], f[ctri]) << f[0];
        EXPECT_NE(f[ctri], "0") << f[0];
        ++rows;
    }
    EXPECT_EQ(rows, 6);
    std::ifstream sj(s.dir / "alone_bench/summary.json");
    EXPECT_EQ(nlohmann::json::parse(sj)["settings"]["terrain"], "off");

    const CliResult both = bench("terrain_bench", {"--city", "flat", "--compare", "terrain=on,off"});
    ASSERT_EQ(both.exitCode, 0) << both.err;
    std::ifstream sj2(s.dir / "terrain_bench/summary.json");
    const auto modes = nlohmann::json::parse(sj2)["modes"];
    ASSERT_TRUE(modes.contains("terrain=on") && modes.contains("terrain=off")) << modes.dump();
    EXPECT_GT(modes["terrain=on"]["totals"]["triangles_per_frame"].get<std::int64_t>(),
              modes["terrain=off"]["totals"]["triangles_per_frame"].get<std::int64_t>());

    fails(s.render("x.png", {"--terrain", "off"}), "--city");
    fails(s.render("x.png", {"--terrain", "off", "--city", "flat", "--view", "canopy"}), "canopy");
    fails(bench("x_bench", {"--terrain", "off"}), "--city");
    fails(bench("x_bench", {"--terrain", "off", "--compare", "city=flat,off"}), "city=off");
    EXPECT_FALSE(std::filesystem::exists(s.dir / "x.png"));
}

TEST(CityCliTest, RoofsComeFromTheImageryOfTheSeason) {
    const CliScene& s = scene();
    ASSERT_EQ(s.render("on.png", {"--city", "flat", "--view", "leafon"}).exitCode, 0);
    ASSERT_EQ(s.render("off.png", {"--city", "flat", "--view", "leafoff"}).exitCode, 0);
    ASSERT_EQ(s.render("plain_on.png", {"--view", "leafon"}).exitCode, 0);
    // The city's pixels (where it changed the plain leaf-on terrain) follow the season on the roofs: the flat
    // mode's walls are one grey dummy texture in both seasons, so only roofs textured from the season's imagery
    // can make the leaf-on and leaf-off renders differ there (about a third of the city's pixels here; none if the
    // roofs read a fixed season).
    const auto on = s.image("on.png"), off = s.image("off.png"), plain = s.image("plain_on.png");
    ASSERT_EQ(on.pixels.size(), off.pixels.size());
    ASSERT_EQ(on.pixels.size(), plain.pixels.size());
    std::size_t city = 0, differ = 0;
    for (std::size_t i = 0; i < on.pixels.size(); i += 3) {
        int changed = 0;
        for (std::size_t c = 0; c < 3; ++c) changed += std::abs(int(on.pixels[i + c]) - int(plain.pixels[i + c]));
        if (changed < 30) continue; // not the city's
        ++city;
        if (std::abs(int(on.pixels[i]) - int(off.pixels[i])) > 12) ++differ;
    }
    EXPECT_GT(city, on.pixels.size() / 3 / 100);
    EXPECT_GT(differ, city / 10) << differ << " of " << city << " city pixels differ between the seasons";

    // The roofs follow the blend and swipe views as the terrain does: halfway between the seasons, and leaf-on left
    // of the swipe line, leaf-off right of it.
    ASSERT_EQ(s.render("blend.png", {"--city", "flat", "--view", "blend", "--blend", "0.5"}).exitCode, 0);
    ASSERT_EQ(s.render("swipe.png", {"--city", "flat", "--view", "swipe", "--swipe", "0.4"}).exitCode, 0);
    const auto blend = s.image("blend.png"), swipe = s.image("swipe.png");
    ASSERT_EQ(blend.pixels.size(), on.pixels.size());
    ASSERT_EQ(swipe.pixels.size(), on.pixels.size());
    const int line = int(0.4 * on.width);
    std::size_t roofs = 0, blendOff = 0, left = 0, right = 0, swipeOff = 0;
    for (int y = 0; y < on.height; ++y)
        for (int x = 0; x < on.width; ++x) {
            const std::size_t i = (std::size_t(y) * std::size_t(on.width) + std::size_t(x)) * 3;
            int seasons = 0, changed = 0;
            for (std::size_t c = 0; c < 3; ++c) {
                seasons += std::abs(int(on.pixels[i + c]) - int(off.pixels[i + c]));
                changed += std::abs(int(on.pixels[i + c]) - int(plain.pixels[i + c]));
            }
            if (changed < 30 || seasons < 36) continue; // a roof pixel whose seasons differ
            ++roofs;
            for (std::size_t c = 0; c < 3; ++c)
                if (std::abs(2 * int(blend.pixels[i + c]) - int(on.pixels[i + c]) - int(off.pixels[i + c])) > 6) {
                    ++blendOff;
                    break;
                }
            if (std::abs(x - line) <= 2) continue;
            const auto& want = x < line ? on : off;
            ++(x < line ? left : right);
            for (std::size_t c = 0; c < 3; ++c)
                if (std::abs(int(swipe.pixels[i + c]) - int(want.pixels[i + c])) > 2) {
                    ++swipeOff;
                    break;
                }
        }
    EXPECT_GT(roofs, city / 20);
    EXPECT_GT(left, 0u);
    EXPECT_GT(right, 0u);
    EXPECT_LE(blendOff, roofs / 50) << blendOff << " of " << roofs << " roof pixels are not halfway between the seasons";
    EXPECT_LE(swipeOff, (left + right) / 50) << swipeOff << " of " << left + right << " roof pixels are not their side's season";
}

// `synth --facades DIR`: every building's facade is cut from one of the folder's photos and made unique by its
// label (thesis §4.7.1); a folder without photos is one clear error.
TEST(CityCliTest, SynthFacadesFromAPhotoFolder) {
    TempDir dir("city-photos");
    std::filesystem::create_directories(dir / "photos");
    const std::uint8_t colours[3][3] = {{210, 40, 40}, {40, 210, 40}, {40, 40, 210}};
    for (int p = 0; p < 3; ++p) {
        const int w = 80, h = 60;
        std::vector<std::uint8_t> px(std::size_t(w * h * 3));
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                for (int c = 0; c < 3; ++c) // the photo's colour with darker window rows
                    px[std::size_t((y * w + x) * 3 + c)] = std::uint8_t(colours[p][c] * ((y / 6) % 3 == 0 ? 0.8 : 1.0));
        ASSERT_TRUE(writeImageAtomic(dir / "photos" / ("p" + std::to_string(p) + ".png"), px.data(), w, h, 3).ok());
    }
    const CliResult r = runCli({"synth", "--out", (dir / "s").string(), "--size-m", "512", "--gsd", "1",
                                "--facade-size", "64", "--facades", (dir / "photos").string()});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    std::vector<std::filesystem::path> facades;
    for (const auto& e : std::filesystem::directory_iterator(dir / "s/city/facades")) facades.push_back(e.path());
    ASSERT_GE(facades.size(), 4u);
    std::ifstream mtl(dir / "s/city/city.mtl");
    std::size_t materials = 0;
    for (std::string line; std::getline(mtl, line);)
        if (line.rfind("map_Kd", 0) == 0) ++materials;
    EXPECT_EQ(materials, facades.size()) << "one facade texture per textured material";
    std::set<std::string> contents;
    int used[3] = {0, 0, 0};
    for (const auto& f : facades) {
        auto img = readImageU8(f, 3);
        ASSERT_TRUE(img.ok()) << img.message();
        double mean[3] = {0, 0, 0};
        for (std::size_t i = 0; i < img->pixels.size(); i += 3)
            for (std::size_t c = 0; c < 3; ++c) mean[c] += img->pixels[i + c];
        const std::size_t dominant = std::size_t(std::max_element(mean, mean + 3) - mean);
        for (std::size_t c = 0; c < 3; ++c)
            if (c != dominant) {
                EXPECT_GT(mean[dominant], 2.0 * mean[c]) << f << ": not one of the photos";
            }
        ++used[dominant];
        std::ifstream in(f, std::ios::binary);
        contents.insert(std::string(std::istreambuf_iterator<char>(in), {}));
    }
    EXPECT_EQ(contents.size(), facades.size()) << "every building's facade differs (its label), even on one photo";
    EXPECT_GE(int(used[0] > 0) + int(used[1] > 0) + int(used[2] > 0), 2) << "buildings draw from the whole pool";

    std::filesystem::create_directories(dir / "empty");
    const CliResult bad = runCli({"synth", "--out", (dir / "s2").string(), "--size-m", "256", "--gsd", "1",
                                  "--facades", (dir / "empty").string()});
    EXPECT_EQ(bad.exitCode, 1);
    EXPECT_NE(bad.err.find("no JPEG or PNG photos"), std::string::npos) << bad.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "s2/scene.json"));
}

// Original textures over twice an atlas's bytes are paged in bands of rows (thesis §4.6): with 64² atlases the
// 128² facades go in six parts, with 128² atlases whole; drawn with their originals the two look the same, still
// and while the threaded loader brings the parts in over several frames.
TEST(CityCliTest, LargeOriginalsArePagedInParts) {
    const CliScene& s = scene();
    for (const char* size : {"64", "128"}) {
        const auto tree = (s.dir / (std::string("parts") + size + ".svat")).string();
        ASSERT_EQ(runCli({"atlas", "build", (s.dir / "s/city/city.obj").string(), "--obj-local", "--out", tree,
                          "--atlas-size", size})
                      .exitCode,
                  0);
        const CliResult r = s.render(std::string("parts") + size + ".png", {"--city", "original", "--city-tree", tree});
        ASSERT_EQ(r.exitCode, 0) << r.err;
        const CliResult b = runCli({"bench", (s.dir / "s/scene.json").string(), "--path", "orbit", "--frames", "4",
                                    "--warmup", "0", "--size", "160x100", "--coverage-every", "0", "--cache",
                                    (s.dir / "cache").string(), "--city", "original", "--city-tree", tree,
                                    "--city-capacity", "1", "--out", (s.dir / (std::string("partsbench") + size)).string()});
        ASSERT_EQ(b.exitCode, 0) << b.err;
    }
    ASSERT_EQ(s.render("parts_none.png", {}).exitCode, 0);
    const auto split = s.image("parts64.png"), whole = s.image("parts128.png"), none = s.image("parts_none.png");
    const RegionDiff d = diffWhere(split, whole, none);
    EXPECT_GT(d.pixels, split.pixels.size() / 3 / 100) << "the houses are in view";
    EXPECT_GT(d.psnr, 40.0) << "the split facades are the whole ones";
}

TEST(CityCliTest, AtlasBuildAndInfo) {
    const CliScene& s = scene();
    const auto tree = (s.dir / "t.svat").string();
    const CliResult b = runCli({"atlas", "build", (s.dir / "s/city/city.obj").string(), "--obj-local", "--out", tree,
                                "--atlas-size", "256", "--report", (s.dir / "t.json").string()});
    ASSERT_EQ(b.exitCode, 0) << b.err;
    EXPECT_NE(b.out.find("nodes"), std::string::npos) << b.out;
    std::ifstream j(s.dir / "t.json");
    const std::string json((std::istreambuf_iterator<char>(j)), {});
    for (const char* key : {"\"nodes\"", "\"seconds\"", "\"peak_rss_gb\"", "\"file_bytes\"", "\"mean_leaf_fill\"", "\"dmin_m\""})
        EXPECT_NE(json.find(key), std::string::npos) << key;
    const CliResult info = runCli({"atlas", "info", tree, "--atlas-png", "0:" + (s.dir / "root.png").string()});
    ASSERT_EQ(info.exitCode, 0) << info.err;
    EXPECT_NE(info.out.find("RGB tree"), std::string::npos) << info.out;
    auto root = readImageU8(s.dir / "root.png", 3);
    ASSERT_TRUE(root.ok());
    EXPECT_EQ(root->width, 256);
    // And it renders as given.
    ASSERT_EQ(s.render("given.png", {"--city", "atlas", "--city-tree", tree}).exitCode, 0);
    // Sized for 2 pixels per texel with a 16-texel border: the same automatic dmin; the file and report say so.
    const auto coarse = (s.dir / "t2.svat").string();
    const CliResult b2 = runCli({"atlas", "build", (s.dir / "s/city/city.obj").string(), "--obj-local", "--out", coarse,
                                 "--atlas-size", "256", "--dmin", "auto", "--tpp", "2", "--border", "16", "--report",
                                 (s.dir / "t2.json").string()});
    ASSERT_EQ(b2.exitCode, 0) << b2.err;
    const auto r1 = nlohmann::json::parse(json), r2 = nlohmann::json::parse(std::ifstream(s.dir / "t2.json"));
    EXPECT_DOUBLE_EQ(r2["dmin_initial_m"].get<double>(), r1["dmin_initial_m"].get<double>());
    EXPECT_EQ(r2["tpp"].get<double>(), 2.0);
    EXPECT_EQ(r2["border"].get<int>(), 16);
    EXPECT_EQ(r1["border"].get<int>(), 8);
    const CliResult info2 = runCli({"atlas", "info", coarse});
    ASSERT_EQ(info2.exitCode, 0) << info2.err;
    EXPECT_NE(info2.out.find("border 16"), std::string::npos) << info2.out;
    EXPECT_NE(info2.out.find("(τ 2.00)"), std::string::npos) << info2.out;
    EXPECT_NE(info.out.find("border 8"), std::string::npos) << info.out;
    fails(runCli({"atlas", "build", (s.dir / "s/city/city.obj").string(), "--obj-local", "--out",
                  (s.dir / "x.svat").string(), "--border", "0"}),
          "--border");
    // compare: a tree against itself is exact; against the tree of another structure, one line naming it.
    const CliResult same = runCli({"atlas", "compare", tree, tree});
    ASSERT_EQ(same.exitCode, 0) << same.err;
    EXPECT_NE(same.out.find("B/A size 1.000; PSNR of B against A 99.00 dB"), std::string::npos) << same.out;
    fails(runCli({"atlas", "compare", tree, coarse}), coarse);
}

// `atlas blockmaps`: the city's BlockMaps over a quadtree of its footprint, written whole; every map's buildings
// within the model's footprint; bad input one line and no file.
TEST(CityCliTest, AtlasBlockMapsBuildsTheCitysQuadtree) {
    const CliScene& s = scene();
    const auto out = s.dir / "city.svbm";
    const CliResult b = runCli({"atlas", "blockmaps", (s.dir / "s/city/city.obj").string(), "--obj-local", "--out",
                                out.string(), "--size", "32", "--wall-texels", "16", "--report", (s.dir / "bm.json").string()});
    ASSERT_EQ(b.exitCode, 0) << b.err;
    EXPECT_NE(b.out.find("BlockMaps of 32² texels"), std::string::npos) << b.out;
    auto maps = city::readBlockMaps(out);
    ASSERT_TRUE(maps) << maps.message();
    const auto report = nlohmann::json::parse(std::ifstream(s.dir / "bm.json"));
    EXPECT_EQ(report["maps"].get<std::size_t>(), maps->size());
    for (const char* key : {"seconds", "peak_rss_gb", "file_bytes", "columns", "depth"}) EXPECT_TRUE(report.contains(key)) << key;
    auto model = city::loadCityModel((s.dir / "s/city/city.obj").string(), [] {
        city::CityLoadOptions o;
        o.localFrame = true;
        return o;
    }());
    ASSERT_TRUE(model) << model.message();
    const glm::dvec3 lo = model->boundsMin(), hi = model->boundsMax();
    // The root covers the whole model; the finest maps are 32 m (32 texels of 1 m); every map holds buildings.
    ASSERT_FALSE(maps->empty());
    const city::BlockMap& root = maps->front();
    EXPECT_LE(root.origin.x, lo.x);
    EXPECT_GE(root.origin.x + root.size * root.texel, hi.x);
    EXPECT_GE(root.origin.y + root.size * root.texel, hi.y);
    double finest = 1e300;
    std::size_t columns = 0;
    for (const city::BlockMap& m : *maps) {
        finest = std::min(finest, m.texel);
        columns += std::size_t(m.columns());
        EXPECT_GT(std::count_if(m.height.begin(), m.height.end(), [](std::uint16_t h) { return h > 0; }), 0);
        EXPECT_GE(m.zBase, lo.z - 1e-6);
        EXPECT_LE(m.zTop, hi.z + 1.0);
    }
    EXPECT_DOUBLE_EQ(finest, 1.0);
    EXPECT_EQ(report["columns"].get<std::size_t>(), columns);
    // Bad input: one line, exit 1, no file.
    const auto missing = s.dir / "none.obj", badOut = s.dir / "bad.svbm";
    fails(runCli({"atlas", "blockmaps", missing.string(), "--obj-local", "--out", badOut.string()}), missing.string());
    EXPECT_FALSE(std::filesystem::exists(badOut));
    fails(runCli({"atlas", "blockmaps", (s.dir / "s/city/city.obj").string(), "--obj-local", "--out", badOut.string(),
                  "--leaf-texel", "0"}),
          "leaf texel");
    EXPECT_FALSE(std::filesystem::exists(badOut));
}

// `--city blockmap`: render and bench draw the atlas tree near and BlockMaps far (built from the tree into the
// cache on first use, found there the second time); bench's summary counts the maps; a BlockMap file that is
// missing or damaged, and an error bound that is not positive, are refused with one line.
TEST(CityCliTest, BlockmapModeRendersAndBenches) {
    const CliScene& s = scene();
    const CliResult first = s.render("bm.png", {"--city", "blockmap"});
    ASSERT_EQ(first.exitCode, 0) << first.err;
    EXPECT_NE(first.out.find("BlockMaps of"), std::string::npos) << first.out;
    const CliResult again = s.render("bm2.png", {"--city", "blockmap"});
    ASSERT_EQ(again.exitCode, 0) << again.err;
    EXPECT_EQ(again.out.find("BlockMaps of"), std::string::npos) << "found in the cache: " << again.out;
    EXPECT_TRUE(s.image("bm.png").pixels == s.image("bm2.png").pixels);
    ASSERT_EQ(s.render("bm_none.png", {}).exitCode, 0);
    ASSERT_EQ(s.render("bm_atlas.png", {"--city", "atlas"}).exitCode, 0);
    const RegionDiff d = diffWhere(s.image("bm_atlas.png"), s.image("bm.png"), s.image("bm_none.png"));
    EXPECT_GT(d.pixels, 100u) << "the city is in the still";
    EXPECT_GT(d.psnr, 30.0);

    const CliResult b = runCli({"bench", (s.dir / "s/scene.json").string(), "--path", "orbit", "--frames", "3",
                                "--warmup", "1", "--size", "200x125", "--coverage-every", "0", "--compare",
                                "city=atlas,blockmap", "--out", (s.dir / "bmbench").string()});
    ASSERT_EQ(b.exitCode, 0) << b.err;
    std::ifstream sj(s.dir / "bmbench/summary.json");
    const auto summary = nlohmann::json::parse(sj);
    const auto& bm = summary["modes"]["city=blockmap"]["city"];
    const auto& at = summary["modes"]["city=atlas"]["city"];
    ASSERT_TRUE(bm.is_object() && at.is_object()) << summary.dump();
    EXPECT_EQ(bm["mode"], "blockmap");
    EXPECT_EQ(at["block_maps"]["max"].get<double>(), 0.0);
    EXPECT_TRUE(bm["block_maps"].is_object());
    EXPECT_LE(bm["resident_bytes"]["max"].get<double>(), bm["capacity_bytes"].get<double>());
    std::ifstream csv(s.dir / "bmbench/frames.csv");
    std::string header;
    std::getline(csv, header);
    EXPECT_NE(header.find(",city_blockmaps,city_blockmaps_not_resident,city_blockmap_pool_bytes,"
                          "city_blockmap_moved_bytes"),
              std::string::npos)
        << header;
    // The maps' pool: none in atlas mode, allocated once maps were drawn.
    EXPECT_EQ(at["block_map_pool_bytes"]["max"].get<double>(), 0.0);
    ASSERT_GT(bm["block_maps"]["max"].get<double>(), 0.0) << "the orbit sees the houses as maps";
    EXPECT_GT(bm["block_map_pool_bytes"]["max"].get<double>(), 0.0);
    EXPECT_TRUE(bm["block_map_moved_bytes"].is_object());

    // A cached file whose maps rot (every map's checksum flipped; the headers intact, so it opens): the still stops
    // at the first map paged in, with one line naming the file, and the cached file is removed to be built again.
    std::filesystem::path cached;
    for (const auto& e : std::filesystem::directory_iterator(s.dir / "cache/atlas"))
        if (e.path().extension() == ".svbm") cached = e.path();
    ASSERT_FALSE(cached.empty());
    {
        auto f = city::BlockMapFile::open(cached);
        ASSERT_TRUE(f) << f.message();
        for (const auto& r : f->records()) flipByte(cached, r.offset + r.bytes - 1);
    }
    // From the south-west, 400 m away: the houses are a map.
    auto far = [&](const std::string& out) {
        return runCli({"render", (s.dir / "s/scene.json").string(), "--size", s.size, "--camera=-200,-200,+120,40,-15",
                       "--clip-size", "512", "--cache", (s.dir / "cache").string(), "--city", "blockmap", "--stats",
                       (s.dir / (out + ".json")).string(), "--out", (s.dir / out).string()});
    };
    fails(far("rot.png"), cached.filename().string());
    EXPECT_FALSE(std::filesystem::exists(cached)) << "removed, to be built again";
    const CliResult rebuilt = far("bm3.png");
    ASSERT_EQ(rebuilt.exitCode, 0) << rebuilt.err;
    EXPECT_NE(rebuilt.out.find("BlockMaps of"), std::string::npos) << rebuilt.out;
    std::ifstream stats(s.dir / "bm3.png.json");
    const auto st = nlohmann::json::parse(stats);
    EXPECT_GE(st["city"]["block_maps"].get<int>(), 1) << st.dump();

    fails(s.render("x.png", {"--city", "blockmap", "--city-blockmaps", (s.dir / "none.svbm").string()}), "none.svbm");
    std::ofstream(s.dir / "cut.svbm") << "SVBLOCKM\x01";
    fails(s.render("x.png", {"--city", "blockmap", "--city-blockmaps", (s.dir / "cut.svbm").string()}), "cut.svbm");
    fails(s.render("x.png", {"--city", "blockmap", "--city-blockmap-error", "0"}), "--city-blockmap-error");
}

// An OBJ in real coordinates of a national grid (Swiss LV95, EPSG:2056) over a UTM 32N scene near Bern, given by
// `render --buildings X.obj --city-crs EPSG:2056`: seen straight down, the house is drawn where its corners project, to
// a pixel, and exactly where the same house written in the scene's local frame (an OBJ without --city-crs) is drawn.
TEST(CityCliTest, ObjInANationalGridIsDrawnWhereItBelongs) {
    TempDir dir("city-crs");
    const Crs utm = Crs::utm(32, true), lv95 = *Crs::fromEpsg(2056);
    const glm::dvec2 centre = glm::round(convert(Crs::geographic(), utm, {7.44, 46.95}));
    // 128 m × 128 m at 0.5 m around `centre`: the scene's local frame is UTM translated there (x east, y north).
    writeTestImage(dir / "on.tif", 256, 256, testGeoref(0.5, centre.x - 64.0, centre.y + 64.0), false, 1);
    writeTestImage(dir / "off.tif", 256, 256, testGeoref(0.5, centre.x - 64.0, centre.y + 64.0), false, 2);
    // A 20 m × 12 m house, 3 m high, south-east of the centre: local x 20..40, y -30..-18. Its footprint
    // counter-clockwise seen from above; OBJ is y up: (x, y, z) = (east, height, -north).
    const glm::dvec2 foot[4] = {{20.0, -30.0}, {40.0, -30.0}, {40.0, -18.0}, {20.0, -18.0}};
    const double top = 3.0;
    // The walls textured (a tree needs textured triangles), the roof plain.
    std::vector<std::uint8_t> wall(8 * 8 * 3, 170);
    ASSERT_TRUE(writeImageAtomic(dir / "wall.png", wall.data(), 8, 8, 3).ok());
    std::ofstream(dir / "house.mtl") << "newmtl wall\nmap_Kd wall.png\n";
    auto obj = [&](auto place) {
        std::string text = "mtllib house.mtl\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\no house\n";
        for (double z : {0.0, top})
            for (const glm::dvec2& f : foot) {
                const glm::dvec2 p = place(f);
                text += "v " + std::to_string(p.x) + " " + std::to_string(z) + " " + std::to_string(-p.y) + "\n";
            }
        text += "usemtl wall\n";
        for (int i = 0; i < 4; ++i) { // walls facing out, then the roof facing up
            const int j = (i + 1) % 4;
            text += "f " + std::to_string(i + 1) + "/1 " + std::to_string(j + 1) + "/2 " + std::to_string(j + 5) +
                    "/3 " + std::to_string(i + 5) + "/4\n";
        }
        return text + "f 5 6 7 8\n";
    };
    std::ofstream(dir / "house_lv95.obj") << obj([&](glm::dvec2 f) { return convert(utm, lv95, centre + f); });
    std::ofstream(dir / "house_local.obj") << obj([](glm::dvec2 f) { return f; });

    // Straight down from `height`, 256 px wide: 128 m on the ground, 0.5 m per pixel, north up.
    const double tanHalfFov = std::tan(30.0 * 3.14159265358979 / 180.0), height = 64.0 / tanHalfFov;
    const std::string camera = "0,0," + std::to_string(height) + ",0,-90,60";
    auto render = [&](const std::string& out, const std::string& model, std::vector<std::string> extra) {
        std::vector<std::string> a = {"render", "--leafon", (dir / "on.tif").string(), "--leafoff",
                                      (dir / "off.tif").string(), "--buildings", (dir / model).string()};
        a.insert(a.end(), {"--city", "flat", "--terrain", "off", "--camera", camera, "--size", "256x256"});
        a.insert(a.end(), {"--clip-size", "256", "--cache", (dir / "cache").string(), "--out", (dir / out).string()});
        a.insert(a.end(), extra.begin(), extra.end());
        const CliResult r = runCli(a);
        EXPECT_EQ(r.exitCode, 0) << out << ": " << r.err;
        auto img = readImageU8(dir / out, 3);
        EXPECT_TRUE(img.ok()) << img.message();
        // The city's pixels: all but the clear colour (the top-left corner, far from the house).
        std::vector<bool> city(256 * 256, false);
        if (!img || img->width != 256 || img->height != 256)
            return city;
        for (int y = 0; y < 256; ++y)
            for (int x = 0; x < 256; ++x)
                for (int c = 0; c < 3; ++c)
                    if (img->at(x, y, c) != img->at(0, 0, c))
                        city[size_t(y) * 256 + size_t(x)] = true;
        return city;
    };
    const std::vector<bool> national = render("lv95.png", "house_lv95.obj", {"--city-crs", "EPSG:2056"});
    const std::vector<bool> local = render("local.png", "house_local.obj", {});
    ASSERT_FALSE(HasFailure());

    // Where the 8 corners project (pixel edges: 0 at the left and top of the image), and the drawn pixels' box.
    glm::dvec2 lo(1e9), hi(-1e9);
    for (double z : {0.0, top})
        for (const glm::dvec2& f : foot) {
            const double perMetre = 128.0 / ((height - z) * tanHalfFov);
            const glm::dvec2 px(128.0 + f.x * perMetre, 128.0 - f.y * perMetre);
            lo = glm::min(lo, px);
            hi = glm::max(hi, px);
        }
    int x0 = 256, y0 = 256, x1 = -1, y1 = -1, drawn = 0, differ = 0;
    for (int y = 0; y < 256; ++y)
        for (int x = 0; x < 256; ++x) {
            const size_t i = size_t(y) * 256 + size_t(x);
            differ += national[i] != local[i];
            if (!national[i])
                continue;
            ++drawn;
            x0 = std::min(x0, x);
            y0 = std::min(y0, y);
            x1 = std::max(x1, x + 1);
            y1 = std::max(y1, y + 1);
        }
    std::printf("house: pixels %d..%d x %d..%d, expected %.1f..%.1f x %.1f..%.1f; %d drawn, %d differ from local\n", x0,
                x1, y0, y1, lo.x, hi.x, lo.y, hi.y, drawn, differ);
    // A pixel is drawn when its centre is inside: the box's edges within a pixel of the projected corners' (and a
    // half for rasterisation rules).
    EXPECT_NEAR(x0, lo.x, 1.5);
    EXPECT_NEAR(x1, hi.x, 1.5);
    EXPECT_NEAR(y0, lo.y, 1.5);
    EXPECT_NEAR(y1, hi.y, 1.5);
    // Seen from above the house is its roof and the two walls facing the centre: nearly its whole box.
    const double box = (hi.x - lo.x) * (hi.y - lo.y);
    EXPECT_GT(drawn, 0.85 * box);
    EXPECT_LT(drawn, 1.1 * box);
    // Through PROJ and back the corners move by micrometres: only rasterisation ties at the edges may differ.
    EXPECT_LE(differ, 20);
}

TEST(CityCliTest, BadInput) {
    const CliScene& s = scene();
    fails(runCli({"atlas", "build", (s.dir / "nope.gml").string(), "--out", (s.dir / "x.svat").string()}), "nope.gml");
    fails(runCli({"atlas", "build", (s.dir / "s/city/city.obj").string(), "--out", (s.dir / "x.svat").string()}), "no CRS");
    fails(runCli({"atlas", "build", (s.dir / "s/city/city.obj").string(), "--obj-local", "--out",
                  (s.dir / "x.svat").string(), "--atlas-size", "100"}),
          "power of two");
    {
        std::ofstream(s.dir / "bad.svat") << "SVATLAS garbage";
        fails(runCli({"atlas", "info", (s.dir / "bad.svat").string()}), "bad.svat");
    }
    fails(s.render("x.png", {"--city", "atlas", "--city-tree", (s.dir / "bad.svat").string()}), "bad.svat");
    fails(s.render("x.png", {"--city", "sideways"}), "--city");
    {
        // A material library cut before its materials: every face untextured, nothing to build a tree from. One
        // line, the load's first warning given as the cause.
        std::filesystem::create_directories(s.dir / "cut-mtl");
        std::filesystem::copy_file(s.dir / "s/city/city.obj", s.dir / "cut-mtl/city.obj",
                                   std::filesystem::copy_options::overwrite_existing);
        std::ofstream(s.dir / "cut-mtl/city.mtl") << "# Blender MTL File\nnewm";
        fails(runCli({"atlas", "build", (s.dir / "cut-mtl/city.obj").string(), "--obj-local", "--out",
                      (s.dir / "x.svat").string()}),
              "no textured triangles to build a tree from (after ");
        const CliResult r = runCli({"atlas", "build", (s.dir / "cut-mtl/city.obj").string(), "--obj-local", "--out",
                                    (s.dir / "x.svat").string()});
        EXPECT_NE(r.err.find("not found in .mtl"), std::string::npos) << r.err;
    }
    {
        // A capacity below the root atlas would leave the city undrawn: refused, naming the tree and the size.
        const auto big = (s.dir / "big.svat").string();
        ASSERT_EQ(runCli({"atlas", "build", (s.dir / "s/city/city.obj").string(), "--obj-local", "--out", big,
                          "--atlas-size", "1024"})
                      .exitCode,
                  0);
        fails(s.render("x.png", {"--city", "atlas", "--city-tree", big, "--city-capacity", "1", "--city-upload", "decoded"}),
              "big.svat (RGB tree): the city capacity (1.0 MB for this tree) cannot hold its root atlas (4.2 MB, decoded): raise --city-capacity to at least 5 MB");
    }
    EXPECT_FALSE(std::filesystem::exists(s.dir / "x.png"));
    EXPECT_FALSE(std::filesystem::exists(s.dir / "x.svat"));
}

TEST(CityCliTest, RealBerlinAndTokyoModelsWithTheirPhotoTextures) {
    const auto data = realDataDir();
    if (!data || !std::filesystem::exists(*data / "city/berlin_lod2/berlin_lod2.gml"))
        GTEST_SKIP() << "real data not found (../shared/data or SEASONVIEW_DATA): city/";
    TempDir dir("city-cli-real");
    struct Case {
        const char* name;
        std::string model, centre, camera;
    };
    const Case cases[] = {
        {"city_berlin", (*data / "city/berlin_lod2/berlin_lod2.gml").string(), "13.384,52.510", "110,175,+45,35,-28,60"},
        {"city_tokyo", (*data / "city/plateau_ota/53392642_bldg_6697_op2.gml").string(), "139.7777,35.5385",
         "-60,-80,+90,25,-22,60"}};
    for (const Case& c : cases) {
        // A synthetic landscape under the model (its own UTM zone), the model's own roof photos.
        const auto sceneDir = dir / (std::string(c.name) + "_scene");
        ASSERT_EQ(runCli({"synth", "--out", sceneDir.string(), "--size-m", "1024", "--gsd", "1", "--no-city",
                          "--centre", c.centre})
                      .exitCode,
                  0);
        const auto tree = (dir / (std::string(c.name) + ".svat")).string();
        const CliResult b = runCli({"atlas", "build", c.model, "--out", tree, "--roofs", "model"});
        ASSERT_EQ(b.exitCode, 0) << b.err;
        for (const char* mode : {"atlas", "original"}) {
            const auto out = dir / (std::string(c.name) + "_" + mode + ".png");
            const CliResult r = runCli({"render", (sceneDir / "scene.json").string(), "--size", "400x250", "--camera",
                                        c.camera, "--clip-size", "512", "--cache", (dir / "cache").string(), "--city",
                                        mode, "--city-tree", tree, "--out", out.string()});
            ASSERT_EQ(r.exitCode, 0) << r.err;
        }
        const CliResult none = runCli({"render", (sceneDir / "scene.json").string(), "--size", "400x250", "--camera",
                                       c.camera, "--clip-size", "512", "--cache", (dir / "cache").string(), "--out",
                                       (dir / (std::string(c.name) + "_none.png")).string()});
        ASSERT_EQ(none.exitCode, 0);
        auto a = readImageU8(dir / (std::string(c.name) + "_atlas.png"), 3);
        auto o = readImageU8(dir / (std::string(c.name) + "_original.png"), 3);
        auto n = readImageU8(dir / (std::string(c.name) + "_none.png"), 3);
        ASSERT_TRUE(a.ok() && o.ok() && n.ok());
        compareWithGolden(c.name, a->pixels, a->width, a->height, 255, 3.0);
        const RegionDiff d = diffWhere(*a, *o, *n);
        EXPECT_GT(d.pixels, std::size_t(400 * 250 / 50)) << c.name;
        // Both drawn through 2×2 box mips (the driver's non-power-of-two mips gave 33.3 dB for Berlin), the capped
        // originals copied texel for texel into 8-aligned areas (36.8 dB for Tokyo; 33.6 dB before).
        EXPECT_GT(d.psnr, 34.5) << c.name << ": atlas vs original photo textures (Berlin 35.1, Tokyo 36.8 dB measured)";
        std::cout << "  " << c.name << ": atlas vs original PSNR " << d.psnr << " dB over " << d.pixels << " city pixels\n";
    }
}

TEST(CityCliTest, ViewerDrawsTheCityAndKeyBHidesIt) {
    const CliScene& s = scene();
    {
        std::ofstream f(s.dir / "city_script.json");
        f << R"([{"t": 0.5, "key": "B"}, {"t": 0.9, "set": "city", "value": true}])";
    }
    auto png = [&](const char* name) { return (s.dir / name).string(); };
    const auto r = runCliWithDisplay({"view", (s.dir / "s/scene.json").string(), "--size", "320x200", "--cache",
                                      (s.dir / "cache").string(), "--camera", "195,140,+18,35,-18,60", "--city", "atlas",
                                      "--no-panel", "--script", png("city_script.json"), "--screenshot-at",
                                      std::string("0.3:") + png("v_city.png"), "--screenshot-at",
                                      std::string("0.7:") + png("v_nocity.png"), "--screenshot-at",
                                      std::string("1.1:") + png("v_city_again.png"), "--quit-at", "1.2"});
    if (!r) GTEST_SKIP() << "no DISPLAY and no xvfb-run: the viewer needs a window";
    ASSERT_EQ(r->exitCode, 0) << r->err;
    auto city = readImageU8(s.dir / "v_city.png", 3), none = readImageU8(s.dir / "v_nocity.png", 3),
         again = readImageU8(s.dir / "v_city_again.png", 3);
    ASSERT_TRUE(city.ok() && none.ok() && again.ok());
    std::size_t differ = 0;
    for (std::size_t i = 0; i < city->pixels.size(); i += 3)
        differ += std::abs(int(city->pixels[i]) - int(none->pixels[i])) > 30 ? 1 : 0;
    EXPECT_GT(differ, city->pixels.size() / 3 / 50) << "the buildings should show, and B hide them";
    EXPECT_EQ(city->pixels, again->pixels) << "`set city true` shows the same city again";
}

// The viewer with `--city blockmap`: in the levels view the houses, at a coarse error bound, are a BlockMap (lavender:
// a coarse level's purple), G switches the maps off (the atlas tree draws them, white), `set city_blockmaps true` on
// again (the same picture).
TEST(CityCliTest, ViewerKeyGSwitchesTheFarBlockMaps) {
    const CliScene& s = scene();
    {
        std::ofstream f(s.dir / "bm_script.json");
        f << R"([{"t": 0.1, "set": "view", "value": "levels"}, {"t": 0.5, "key": "G"},)"
          << R"( {"t": 0.9, "set": "city_blockmaps", "value": true}])";
    }
    auto png = [&](const char* name) { return (s.dir / name).string(); };
    const auto r = runCliWithDisplay({"view", (s.dir / "s/scene.json").string(), "--size", "320x200", "--cache",
                                      (s.dir / "cache").string(), "--camera=40,-20,+40,40,-6,12", "--city", "blockmap",
                                      "--city-blockmap-error", "8", "--no-panel", "--script", png("bm_script.json"),
                                      "--screenshot-at", std::string("0.3:") + png("g_on.png"), "--screenshot-at",
                                      std::string("0.7:") + png("g_off.png"), "--screenshot-at",
                                      std::string("1.1:") + png("g_again.png"), "--quit-at", "1.2"});
    if (!r) GTEST_SKIP() << "no DISPLAY and no xvfb-run: the viewer needs a window";
    ASSERT_EQ(r->exitCode, 0) << r->err;
    auto on = readImageU8(s.dir / "g_on.png", 3), off = readImageU8(s.dir / "g_off.png", 3),
         again = readImageU8(s.dir / "g_again.png", 3);
    ASSERT_TRUE(on.ok() && off.ok() && again.ok());
    // Lavender maps against white polygons: green lower than red and blue where the maps are.
    std::size_t mapPixels = 0, offMapPixels = 0;
    auto lavender = [](const Image<std::uint8_t>& img, std::size_t i) {
        return img.pixels[i] > img.pixels[i + 1] + 12 && img.pixels[i + 2] > img.pixels[i + 1] + 12 && img.pixels[i] > 120;
    };
    for (std::size_t i = 0; i < on->pixels.size(); i += 3) {
        mapPixels += lavender(*on, i) ? 1 : 0;
        offMapPixels += lavender(*off, i) ? 1 : 0;
    }
    EXPECT_GT(mapPixels, 200u) << "the houses are a BlockMap";
    EXPECT_LT(offMapPixels, mapPixels / 20) << "G: the atlas tree draws them";
    EXPECT_EQ(on->pixels, again->pixels) << "`set city_blockmaps true` shows the maps again";
}

// `atlas blockmaps` of an atlas tree: the walls' colours read through the tree's atlases (what `--city blockmap`
// draws next to the atlases), not the original textures. The facades repainted magenta after the tree was built:
// maps of the model show magenta walls, the coarse maps of its tree the facades the atlases hold.
TEST(CityCliTest, AtlasBlockMapsOfATreeReadItsAtlases) {
    TempDir dir("city-cli-bm-atlas");
    ASSERT_EQ(runCli({"synth", "--out", (dir / "s").string(), "--size-m", "256", "--gsd", "1", "--block-city", "40",
                      "--facade-size", "64"})
                  .exitCode,
              0);
    const auto tree = dir / "t.svat";
    ASSERT_EQ(runCli({"atlas", "build", (dir / "s/city/city.obj").string(), "--obj-local", "--out", tree.string(),
                      "--atlas-size", "128"})
                  .exitCode,
              0);
    std::vector<std::uint8_t> magenta(64 * 64 * 3);
    for (std::size_t i = 0; i < magenta.size(); i += 3) magenta[i] = magenta[i + 2] = 255;
    int repainted = 0;
    for (const auto& e : std::filesystem::directory_iterator(dir / "s/city/facades")) {
        ASSERT_TRUE(writeImageAtomic(e.path(), magenta.data(), 64, 64, 3).ok());
        ++repainted;
    }
    ASSERT_GT(repainted, 0);
    const auto ofTree = dir / "tree.svbm", ofModel = dir / "model.svbm";
    const CliResult bt = runCli({"atlas", "blockmaps", tree.string(), "--out", ofTree.string(), "--report",
                                 (dir / "bt.json").string()});
    ASSERT_EQ(bt.exitCode, 0) << bt.err;
    EXPECT_GT(nlohmann::json::parse(std::ifstream(dir / "bt.json"))["atlas_reads"].get<int>(), 0);
    const CliResult bo = runCli({"atlas", "blockmaps", (dir / "s/city/city.obj").string(), "--obj-local", "--out",
                                 ofModel.string()});
    ASSERT_EQ(bo.exitCode, 0) << bo.err;
    // The root maps' mean wall colour (texels whose rays met walls).
    auto rootWalls = [](const std::filesystem::path& p) {
        auto maps = city::readBlockMaps(p);
        EXPECT_TRUE(maps) << maps.message();
        glm::dvec3 sum(0.0);
        double n = 0.0;
        if (!maps || maps->empty()) return sum;
        const auto& w = maps->front().wallRgba;
        for (std::size_t i = 0; i + 3 < w.size(); i += 4)
            if (w[i + 3] > 128) {
                sum += glm::dvec3(w[i], w[i + 1], w[i + 2]);
                n += 1.0;
            }
        EXPECT_GT(n, 100.0) << p;
        return n > 0.0 ? sum / n : sum;
    };
    const glm::dvec3 m = rootWalls(ofModel), t = rootWalls(ofTree);
    EXPECT_GT(m.r, 200.0);
    EXPECT_LT(m.g, 40.0) << "the model's maps: the repainted facades";
    EXPECT_GT(t.g, 60.0) << "the tree's maps: its atlases' facades (" << t.r << ", " << t.g << ", " << t.b << ")";
    // A damaged tree is refused with one line naming it, and no file.
    const auto cut = dir / "cut.svat", bad = dir / "bad.svbm";
    std::string bytes = readBytes(tree);
    bytes.resize(bytes.size() / 2);
    { std::ofstream(cut, std::ios::binary) << bytes; }
    fails(runCli({"atlas", "blockmaps", cut.string(), "--out", bad.string()}), cut.string());
    EXPECT_FALSE(std::filesystem::exists(bad));
}

// `--city blockmap` against `--city atlas` through `render --city-accuracy --city-accuracy-against atlas`, at an
// overview of a 400-building block city where buildings are 4-6 px wide and the maps' texels up to a pixel, roofs from
// the terrain's imagery as users see them (CityBlockMapGLTest draws them plain): the maps' roofs filter the imagery
// over the pixel's footprint on the roof's plane, not over the hits' own derivatives, which jump at a roof's edge
// (26.2 dB that way). With `--supersample 4` (4 × 4 samples a pixel, the maps and atlases those of the output's
// pixels) the comparison leaves out the aliasing both modes share, and the picture is exactly the box filter of the
// same still rendered 4× larger with the error bounds 4× larger.
TEST(CityCliTest, BlockmapOverviewAgainstTheAtlasModeWithRoofsFromTheImagery) {
    static CliScene s("city-bm-overview", {"--size-m", "512", "--gsd", "1", "--block-city", "400", "--facade-size", "64"},
                      "320x240", "0,-350,+450,0,-50");
    auto accuracy = [&](const std::string& out, const std::vector<std::string>& extra) {
        std::vector<std::string> a = {"--terrain", "off", "--city", "blockmap", "--city-accuracy",
                                      (s.dir / (out + ".json")).string(), "--city-accuracy-against", "atlas"};
        a.insert(a.end(), extra.begin(), extra.end());
        const CliResult r = s.render(out, a);
        EXPECT_EQ(r.exitCode, 0) << r.err;
        std::ifstream f(s.dir / (out + ".json"));
        return nlohmann::json::parse(f, nullptr, false);
    };
    const auto one = accuracy("one.png", {});
    ASSERT_FALSE(one.is_discarded());
    EXPECT_EQ(one["against"], "atlas");
    EXPECT_EQ(one["supersample"], 1);
    EXPECT_GT(one["block_maps"].get<int>(), 0) << one.dump();
    EXPECT_GT(one["city_pixels"].get<int>(), 320 * 240 / 20) << one.dump();
    const double psnr1 = one["psnr_db"].get<double>();
    EXPECT_GE(psnr1, 29.0) << one.dump();
    const auto four = accuracy("four.png", {"--supersample", "4"});
    ASSERT_FALSE(four.is_discarded());
    EXPECT_EQ(four["supersample"], 4);
    EXPECT_EQ(four["size"], nlohmann::json::array({320, 240}));
    EXPECT_GE(four["psnr_db"].get<double>(), 32.5) << four.dump();
    std::printf("blockmap against atlas, roofs from the imagery: %.2f dB, 4x4 samples %.2f dB\n", psnr1,
                four["psnr_db"].get<double>());

    // The supersampled still is the 4x4 box filter of the still 4x larger with the bounds 4x larger.
    const CliResult big = runCli({"render", (s.dir / "s/scene.json").string(), "--size", "1280x960", "--camera", s.camera,
                                  "--clip-size", "512", "--cache", (s.dir / "cache").string(), "--terrain", "off",
                                  "--city", "blockmap", "--city-tpp", "4", "--city-blockmap-error", "4", "--out",
                                  (s.dir / "big.png").string()});
    ASSERT_EQ(big.exitCode, 0) << big.err;
    const Image<std::uint8_t> b = s.image("big.png"), f = s.image("four.png");
    ASSERT_EQ(b.width, 1280);
    ASSERT_EQ(f.width, 320);
    ASSERT_EQ(f.height, 240);
    int worst = 0;
    for (int y = 0; y < 240; ++y)
        for (int x = 0; x < 320; ++x)
            for (int c = 0; c < 3; ++c) {
                int sum = 0;
                for (int j = 0; j < 4; ++j)
                    for (int i = 0; i < 4; ++i) sum += b.at(x * 4 + i, y * 4 + j, c);
                worst = std::max(worst, std::abs((sum + 8) / 16 - int(f.at(x, y, c))));
            }
    EXPECT_EQ(worst, 0);

    fails(s.render("x.png", {"--supersample", "0"}), "--supersample");
    fails(s.render("x.png", {"--city", "blockmap", "--city-accuracy", (s.dir / "x.json").string(),
                             "--city-accuracy-against", "flat"}),
          "--city-accuracy-against");
}
