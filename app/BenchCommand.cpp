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
        FrameArgs frame;
        BenchSettings b;
        std::string out;
    };
    auto a = std::make_shared<Args>();
    a->frame.size = "1920x1080";
    CLI::App* cmd = app.add_subcommand("bench", "Headless frame benchmark along a camera path (frames.csv, summary.json, "
                                                "compare.json, plot.png)");
    a->scene.addTo(*cmd);
    a->frame.addTo(*cmd, "Frame", {.camera = false, .window = false});
    cmd->add_option("--out", a->out, "Output folder")->required()->group(kFrameGroup);
    const char* benchGroup = "Benchmark";
    cmd->add_option("--path", a->b.path, "Camera path: " + CameraPath::namedPaths() + " or a keyframe JSON file")
        ->capture_default_str()
        ->group(benchGroup);
    cmd->add_option("--frames", a->b.frames, "Frames measured")
        ->capture_default_str()
        ->check(CLI::Range(2, 10000000))
        ->group(benchGroup);
    cmd->add_option("--warmup", a->b.warmup, "Frames run at the path's start before measuring (with a city, one more once the view is loaded, "
                    "so the first measured frame compiles no program)")
        ->capture_default_str()
        ->group(benchGroup);
    cmd->add_option("--compare", a->b.compare,
                    "Modes run interleaved over the same path: \"centers=" + placementNames() +
                        "\" (comma-separated), \"renderer=clipmap,reference\", \"aniso=1,8,...\", \"canopy=off,16\" "
                        "(no canopy vs the canopy view with N layers), \"canopy-draw=layers,march\" (the layers "
                        "rasterised each vs intersected per pixel), \"segmentation=upload,perframe\" (canopy "
                        "layer derived when blocks arrive vs re-derived every frame), \"canopy-levels=all,read\" (every "
                        "arriving block of the canopy layer derived vs only those the view reads), \"canopy-derive=gpu,cpu\" "
                        "(the canopy layer's blocks derived by a compute shader vs on the block loader's workers), "
                        "\"canopy-pyramid=off,on\" (the canopy layer derived while flying vs read from the layer "
                        "`prepare` makes, built first when missing), "
                        "\"scene=terrain,full\" (the "
                        "relief alone vs both seasons, canopy layers and trunks), \"city=atlas,original,flat,off\", "
                        "\"city-upload=compressed,decoded\", \"city-occlusion=off,on\", \"city-flush=off,on\" "
                        "(the city's paging with the terrain handed to the GPU first or not), "
                        "\"city-map-occlusion=conditional,readback\" (blockmap mode: the maps tested for occlusion "
                        "drawn under conditional rendering vs after reading the answers), \"terrain=on,off\" "
                        "(with a city: the city over the terrain vs alone), \"terrain-shading=forward,deferred\" "
                        "(the terrain's fragments shaded as rasterised vs once per pixel from a G-buffer) or "
                        "\"source=prepared,stream\" (seasons from tile services prepared whole vs streamed, --stream)")
        ->group(benchGroup);
    cmd->add_option("--upload-budget", a->b.uploadBudget, "Clipmap texels uploaded per frame and layer")
        ->capture_default_str()
        ->group(benchGroup);
    cmd->add_option("--stages", a->b.stages,
                    "Time each frame's stages: finish (each stage's CPU issuing, then a wait for the GPU: the frames "
                    "are slower) or issue (CPU time per stage of plain frames: shows where the CPU waits for the "
                    "GPU); stages.csv and summary.json \"stages\"")
        ->check(CLI::IsMember({"finish", "issue"}));
    cmd->add_option("--coverage-every", a->b.coverageEvery, "Measure coverage every K frames (0: never)")
        ->capture_default_str()
        ->group(benchGroup);
    cmd->add_option("--seed", a->b.seed, "Seed of the random path")->capture_default_str()->group(benchGroup);
    a->b.imagery.addTo(*cmd);
    a->b.clipmap.addTo(*cmd);
    a->b.canopy.addTo(*cmd);
    a->b.city.addTo(*cmd);
    return [a]() -> int {
        auto fail = [](const std::string& m) {
            std::fprintf(stderr, "seasonview bench: %s\n", m.c_str());
            return 1;
        };
        auto size = a->frame.frameSize();
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
