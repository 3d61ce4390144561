// `seasonview bench`: headless frame benchmark along a camera path (see Bench.h).
#include "Bench.h"
#include "CameraPath.h"
#include "ClipmapCenters.h"
#include "Commands.h"
#include "RenderJob.h"

#include <cstdio>
#include <memory>

namespace seasonview::app {

Runner addBenchCommand(CLI::App& app) {
    struct Args {
        SceneArgs scene;
        BenchSettings b;
        std::string size = "1920x1080", out;
    };
    auto a = std::make_shared<Args>();
    CLI::App* cmd = app.add_subcommand("bench", "Headless frame benchmark along a camera path (frames.csv, summary.json, "
                                                "compare.json, plot.png)");
    a->scene.addTo(*cmd);
    cmd->add_option("--path", a->b.path, "Camera path: " + CameraPath::namedPaths() + " or a keyframe JSON file")
        ->capture_default_str();
    cmd->add_option("--frames", a->b.frames, "Frames measured")->capture_default_str()->check(CLI::Range(2, 10000000));
    cmd->add_option("--warmup", a->b.warmup, "Frames run at the path's start before measuring")->capture_default_str();
    cmd->add_option("--size", a->size, "Frame size WxH")->capture_default_str();
    cmd->add_option("--out", a->out, "Output folder")->required();
    cmd->add_option("--compare", a->b.compare,
                    "Modes run interleaved over the same path: \"centers=" + placementNames() +
                        "\" (comma-separated), \"renderer=clipmap,reference\", \"aniso=1,8,...\", \"canopy=off,16\" "
                        "(no canopy vs the canopy view with N layers), \"canopy-draw=layers,march\" (the layers "
                        "rasterised each vs intersected per pixel), \"segmentation=upload,perframe\" (canopy "
                        "layer derived when blocks arrive vs re-derived every frame), \"scene=terrain,full\" (the "
                        "relief alone vs both seasons, canopy layers and trunks), \"city=atlas,original,flat,off\", "
                        "\"city-upload=compressed,decoded\", \"city-occlusion=off,on\", \"terrain=on,off\" "
                        "(with a city: the city over the terrain vs alone) or \"terrain-shading=forward,deferred\" "
                        "(the terrain's fragments shaded as rasterised vs once per pixel from a G-buffer)");
    cmd->add_option("--canopy-layers", a->b.canopyLayers, "canopy view: stacked layers 1..32 or off")
        ->capture_default_str();
    cmd->add_option("--method", a->b.method, "canopy view: pixel|neighborhood|equalized|default")->capture_default_str();
    cmd->add_option("--trunks", a->b.trunks, "canopy view: trunks under the crowns, on|off")->capture_default_str();
    cmd->add_option("--canopy-draw", a->b.canopyDraw, "canopy view: how the stacked layers are drawn, layers|march")
        ->capture_default_str();
    cmd->add_option("--ground-under-canopy", a->b.groundUnder, "canopy view: ground season under the crowns, leafon|leafoff")
        ->capture_default_str();
    cmd->add_option("--ground-elsewhere", a->b.groundElsewhere, "canopy view: ground season elsewhere, leafon|leafoff")
        ->capture_default_str();
    cmd->add_option("--k", a->b.k, "canopy view: the ground layer's neighbourhood size (odd, 1..15)")
        ->capture_default_str();
    cmd->add_option("--aniso", a->b.anisotropy, "Maximum anisotropy 1..16 (1 = isotropic)")->capture_default_str();
    cmd->add_option("--clip-levels", a->b.clipLevels, "Toroidal clipmap levels allocated at least (0 = as needed)")
        ->check(CLI::Range(0, 16))
        ->capture_default_str();
    cmd->add_option("--grid-size", a->b.gridSize, "Geometry clipmap n = 2^k - 1 (31..1023)")->capture_default_str();
    cmd->add_option("--renderer", a->b.renderer, "clipmap|reference")->capture_default_str();
    cmd->add_option("--centers", a->b.centers, "Clipmap level centres: " + placementNames())->capture_default_str();
    cmd->add_option("--view", a->b.view, "leafon|leafoff|blend|swipe|lod|wireframe|levels|relief|canopy")->capture_default_str();
    cmd->add_option("--clip-size", a->b.clipSize, "Clipmap level size N (256..4096)")->capture_default_str();
    cmd->add_option("--upload-budget", a->b.uploadBudget, "Clipmap texels uploaded per frame and layer")
        ->capture_default_str();
    cmd->add_option("--coverage-every", a->b.coverageEvery, "Measure coverage every K frames (0: never)")
        ->capture_default_str();
    cmd->add_option("--seed", a->b.seed, "Seed of the random path")->capture_default_str();
    cmd->add_option("--city", a->b.city, "City model: atlas|original|flat|off (the scene's buildings)")
        ->check(CLI::IsMember({"atlas", "original", "flat", "off"}))
        ->capture_default_str();
    cmd->add_option("--city-tree", a->b.cityTree, "Atlas tree file (default: built from the scene's buildings into the cache)");
    cmd->add_option("--city-capacity", a->b.cityCapacityMb, "City: resident atlases and textures, MB")->capture_default_str();
    cmd->add_option("--city-tpp", a->b.cityTpp, "City: pixels per texel allowed")->capture_default_str();
    cmd->add_option("--city-upload", a->b.cityUpload,
                    "City: BC atlases uploaded compressed, decoded (RGB8), or auto (decoded on software rasterisers)")
        ->check(CLI::IsMember({"auto", "compressed", "decoded"}))
        ->capture_default_str();
    cmd->add_option("--city-occlusion", a->b.cityOcclusion,
                    "City, atlas mode: skip nodes hidden behind what is drawn (occlusion queries on node boxes)")
        ->check(CLI::IsMember({"on", "off"}))
        ->capture_default_str();
    cmd->add_option("--terrain-shading", a->b.terrainShading,
                    "How the terrain's fragments are shaded: deferred (a geometry pass, then each pixel once) or "
                    "forward (as rasterised); the same pixels")
        ->check(CLI::IsMember({"forward", "deferred"}))
        ->capture_default_str();
    cmd->add_option("--terrain", a->b.terrain,
                    "on: the terrain drawn; off: only the city (its facades and roofs), as the atlas-tree paper timed it")
        ->check(CLI::IsMember({"on", "off"}))
        ->capture_default_str();
    return [a]() -> int {
        auto fail = [](const std::string& m) {
            std::fprintf(stderr, "seasonview bench: %s\n", m.c_str());
            return 1;
        };
        auto size = parseSize(a->size);
        if (!size) return fail(size.message());
        a->b.width = size->first;
        a->b.height = size->second;
        a->b.cacheDir = a->scene.cache;
        auto scene = a->scene.load();
        if (!scene) return fail(scene.message());
        printSceneNotes(*scene);
        auto r = runBench(*scene, a->b, a->out);
        if (!r && rebuildingDamaged(r.message(), a->scene.cacheDir())) r = runBench(*scene, a->b, a->out);
        if (!r) return fail(r.message());
        std::printf("%s", r->table.c_str());
        std::printf("wrote %s/{frames.csv,summary.json%s,plot.png}: %d frames x %zu modes at %dx%d on %s in %.1f s\n",
                    a->out.c_str(), r->modes.size() > 1 ? ",compare.json" : "", a->b.frames, r->modes.size(),
                    a->b.width, a->b.height, r->device.c_str(), r->seconds);
        return 0;
    };
}

} // namespace seasonview::app
