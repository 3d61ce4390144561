// `seasonview atlas build|info|compare|blockmaps`: the multiresolution texture-atlas tree of a city model
// (city/AtlasTreeBuild.h) and its BlockMaps (city/BlockMap.h).
#include "AtlasCodec.h"
#include "AtlasTreeBuild.h"
#include "BlockMap.h"
#include "AtomicFile.h"
#include "Raster.h"
#include "CityModel.h"
#include "Commands.h"

#include <nlohmann/json.hpp>

#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>

namespace seasonview::app {

namespace {

struct AtlasArgs {
    std::string input, out, dmin = "auto", format = "bc", roofs = "imagery", crs, objUp = "y", report, packer = "maxrects";
    int atlasSize = 512, screenWidth = 1920, border = 8;
    double tpp = 1.0, fovX = 90.0, cacheMb = 512.0;
    bool objLocal = false;
    std::string tree; // info
    std::vector<std::string> atlasPng;
    std::string treeA, treeB; // compare
    int blockMapSize = 64, wallTexels = 32; // blockmaps
    double leafTexel = 1.0;
};

double peakRssGb() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return double(u.ru_maxrss) / (1024.0 * 1024.0); // ru_maxrss is in KiB on Linux
}

} // namespace

Result<city::CityModel> loadCityForCli(const std::string& path, const std::string& crsText, bool objLocal,
                                       const std::string& objUp) {
    city::CityLoadOptions options;
    if (!crsText.empty()) {
        auto crs = city::crsFromSrsName(crsText);
        if (!crs) return Error{"--city-crs: " + crs.message()};
        options.crs = *crs;
    }
    options.localFrame = objLocal;
    options.objUp = objUp == "z" ? 'z' : 'y';
    return city::loadCityModel(path, options);
}

namespace {

int fail(const std::string& m) {
    std::fprintf(stderr, "seasonview atlas: %s\n", m.c_str());
    return 1;
}

// atlas compare A B: the atlases of two trees of one model, size, decode time and PSNR of B against A.
int atlasCompare(const AtlasArgs* a) {
    auto fa = city::AtlasTreeFile::open(a->treeA);
    if (!fa) return fail(fa.error().message);
    auto fb = city::AtlasTreeFile::open(a->treeB);
    if (!fb) return fail(fb.error().message);
    if (fa->trees.size() != fb->trees.size() || fa->info.atlasSize != fb->info.atlasSize)
        return fail(a->treeB + ": not a tree of the same model and atlas size as " + a->treeA);
    struct Side {
        std::uint64_t bytes = 0;
        double decodeMs = 0.0;
    } sa, sb;
    double sq = 0.0;
    std::uint64_t samples = 0, atlases = 0;
    for (std::size_t t = 0; t < fa->trees.size(); ++t) {
        if (fa->trees[t].nodes.size() != fb->trees[t].nodes.size())
            return fail(a->treeB + ": a different tree structure than " + a->treeA);
        for (std::size_t n = 0; n < fa->trees[t].nodes.size(); ++n) {
            if (fa->trees[t].nodes[n].atlasBytes == 0) continue;
            std::vector<std::uint8_t> img[2];
            int k = 0;
            for (auto* f : {&*fa, &*fb}) {
                Side& side = k == 0 ? sa : sb;
                auto blob = f->readAtlasBlob(int(t), int(n));
                if (!blob) return fail(blob.error().message);
                side.bytes += blob->size();
                // Decode time: what the upload needs (deflate: inflate every level; BC: nothing unless
                // the GL lacks S3TC, so the CPU decode is measured as the worst case).
                const auto t0 = std::chrono::steady_clock::now();
                img[k] = city::decodeAtlasRgba(f->info.format, f->trees[t].alpha, *blob, f->info.atlasSize);
                side.decodeMs += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
                if (img[k].empty()) return fail(f->path + ": corrupt atlas of node " + std::to_string(n));
                ++k;
            }
            for (std::size_t i = 0; i < img[0].size(); i += 4)
                for (std::size_t c = 0; c < 3; ++c) {
                    const double d = double(img[0][i + c]) - double(img[1][i + c]);
                    sq += d * d;
                    ++samples;
                }
            ++atlases;
        }
    }
    const double mse = samples ? sq / double(samples) : 0.0;
    const double psnr = mse > 0.0 ? 10.0 * std::log10(255.0 * 255.0 / mse) : 99.0;
    std::printf("%llu atlases: A (%s) %.1f MB, decode %.2f ms/atlas; B (%s) %.1f MB, decode %.2f ms/atlas; "
                "B/A size %.3f; PSNR of B against A %.2f dB\n",
                (unsigned long long)atlases, city::atlasFormatName(fa->info.format), double(sa.bytes) / 1e6,
                atlases ? sa.decodeMs / double(atlases) : 0.0, city::atlasFormatName(fb->info.format),
                double(sb.bytes) / 1e6, atlases ? sb.decodeMs / double(atlases) : 0.0,
                sa.bytes ? double(sb.bytes) / double(sa.bytes) : 0.0, psnr);
    return 0;
}

// atlas info TREE: the tree's parameters, nodes and sizes; --atlas-png writes a node's atlas.
int atlasInfo(const AtlasArgs* a) {
    auto f = city::AtlasTreeFile::open(a->tree);
    if (!f) return fail(f.error().message);
    const auto& i = f->info;
    std::printf("%s: atlas %d² (%s), border %d, dmin %.2f m for %d px at %.0f° (τ %.2f), %zu textures, source %s\n",
                a->tree.c_str(), i.atlasSize, city::atlasFormatName(i.format), i.border, i.dmin, i.screenWidth,
                i.fovXDeg, i.tpp, f->textures.size(), i.source.c_str());
    for (const auto& t : f->trees) {
        int depth = 0;
        std::size_t leaves = 0;
        std::uint64_t bytes = 0;
        for (const auto& n : t.nodes) {
            depth = std::max(depth, n.level);
            leaves += n.leaf();
            bytes += n.atlasBytes;
        }
        std::printf("  %s tree: %zu nodes (%zu leaves, depth %d), %zu triangles, root minDistance %.1f m, "
                    "atlases %.1f MB\n",
                    t.alpha ? "RGBA" : "RGB", t.nodes.size(), leaves, depth, t.vertices.size() / 3,
                    double(t.nodes[0].minDistance), double(bytes) / 1e6);
    }
    std::printf("  plain triangles (roofs from imagery, untextured): %zu\n", f->plain.surface.size());
    for (const auto& spec : a->atlasPng) {
        const auto colon = spec.find(':');
        int node = -1;
        try {
            node = colon == std::string::npos ? -1 : std::stoi(spec.substr(0, colon));
        } catch (...) {
        }
        if (node < 0 || f->trees.empty() || node >= int(f->trees[0].nodes.size()))
            return fail("--atlas-png: expected NODE:FILE.png with NODE < " +
                        std::to_string(f->trees.empty() ? 0 : f->trees[0].nodes.size()) + ", got '" + spec + "'");
        auto rgba = f->readAtlasRgba(0, node);
        if (!rgba) return fail(rgba.error().message);
        const int n = f->info.atlasSize;
        std::vector<std::uint8_t> rgb(std::size_t(n) * std::size_t(n) * 3);
        for (int y = 0; y < n; ++y) // rows are bottom-up in the tree, top-down in the PNG
            for (int x = 0; x < n; ++x)
                for (int c = 0; c < 3; ++c)
                    rgb[(std::size_t(n - 1 - y) * std::size_t(n) + std::size_t(x)) * 3 + std::size_t(c)] =
                        (*rgba)[(std::size_t(y) * std::size_t(n) + std::size_t(x)) * 4 + std::size_t(c)];
        const std::string file = spec.substr(colon + 1);
        if (auto st = writeImageAtomic(file, rgb.data(), n, n, 3); !st) return fail(st.message());
        std::printf("  node %d (level %d, minDistance %.1f m, %u triangles) -> %s\n", node,
                    f->trees[0].nodes[std::size_t(node)].level, double(f->trees[0].nodes[std::size_t(node)].minDistance),
                    f->trees[0].nodes[std::size_t(node)].count, file.c_str());
    }
    return 0;
}

// atlas build INPUT --out TREE: loads the model and builds its texture-atlas tree (buildAtlasTree).
int atlasBuild(const AtlasArgs* a) {
    const auto t0 = std::chrono::steady_clock::now();
    auto model = loadCityForCli(a->input, a->crs, a->objLocal, a->objUp);
    if (!model) return fail(model.error().message);
    const double loadSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("%s: %zu buildings, %zu triangles (%zu textured), %zu textures, read in %.1f s\n", a->input.c_str(),
                model->buildingIds.size(), model->triangles.size(), model->texturedTriangles(),
                model->textures.size(), loadSeconds);
    std::fflush(stdout);

    city::AtlasBuildSettings s;
    s.atlasSize = a->atlasSize;
    if (a->dmin != "auto") {
        try {
            s.dmin = std::stod(a->dmin);
        } catch (...) {
            return fail("--dmin: expected metres or 'auto', got '" + a->dmin + "'");
        }
        if (!(s.dmin > 0.0)) return fail("--dmin must be positive");
    }
    if (!(a->tpp > 0.0)) return fail("--tpp must be positive");
    s.tpp = a->tpp;
    s.border = a->border;
    s.screenWidth = a->screenWidth;
    s.fovXDeg = a->fovX;
    s.format = a->format == "deflate" ? city::AtlasFormat::Deflate : city::AtlasFormat::Bc;
    s.roofsFromImagery = a->roofs == "imagery";
    s.packer = *city::parseAtlasPacker(a->packer);
    s.cacheBytes = std::uint64_t(std::max(16.0, a->cacheMb) * 1048576.0);
    s.progress = terminalProgress("atlas tree");
    auto r = city::buildAtlasTree(*model, s, a->out);
    // The model's warnings after the build: a failure is one line, with the first warning as its likely cause.
    if (!r) return fail(model->failureWithWarnings(r.error().message));
    for (const auto& w : model->warnings) std::fprintf(stderr, "seasonview atlas: warning: %s\n", w.c_str());
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("%s: %zu nodes (%zu leaves, %zu empty, depth %d), %zu tree triangles (%zu critical at dmin %.2f m, "
                "dmin now %.2f m, %zu split), %zu plain, mean leaf fill %.1f %%, atlases %.1f MB, file %.1f MB, "
                "%llu texture reads, %.1f s, peak RSS %.2f GB\n",
                a->out.c_str(), r->nodes, r->leaves, r->emptyLeaves, r->depth, r->treeTriangles, r->criticalAtDmin,
                r->dminInitial, r->dmin, r->criticalSplit, r->plainTriangles, 100.0 * r->meanLeafFill,
                double(r->atlasBytes) / 1e6, double(r->fileBytes) / 1e6, (unsigned long long)r->textureReads,
                seconds, peakRssGb());
    if (!a->report.empty()) {
        nlohmann::json j = {{"input", a->input},
                            {"buildings", model->buildingIds.size()},
                            {"triangles", model->triangles.size()},
                            {"textures", model->textures.size()},
                            {"tree_triangles", r->treeTriangles},
                            {"plain_triangles", r->plainTriangles},
                            {"critical_at_dmin", r->criticalAtDmin},
                            {"critical_split", r->criticalSplit},
                            {"dmin_initial_m", r->dminInitial},
                            {"dmin_m", r->dmin},
                            {"nodes", r->nodes},
                            {"leaves", r->leaves},
                            {"empty_leaves", r->emptyLeaves},
                            {"depth", r->depth},
                            {"mean_leaf_fill", r->meanLeafFill},
                            {"atlas_bytes", r->atlasBytes},
                            {"file_bytes", r->fileBytes},
                            {"texture_reads", r->textureReads},
                            {"peak_texture_cache_bytes", r->peakCacheBytes},
                            {"seconds", seconds},
                            {"peak_rss_gb", peakRssGb()},
                            {"format", city::atlasFormatName(s.format)},
                            {"atlas_size", s.atlasSize},
                            {"border", s.border},
                            {"tpp", s.tpp},
                            {"packer", city::atlasPackerName(s.packer)}};
        std::string err;
        if (!writeTextAtomic(a->report, j.dump(2) + "\n", err)) return fail(a->report + ": " + err);
    }
    return 0;
}

// atlas blockmaps INPUT --out FILE: the model's BlockMaps over a quadtree of its footprint (buildCityBlockMaps).
int atlasBlockMaps(const AtlasArgs* a) {
    const auto t0 = std::chrono::steady_clock::now();
    // An atlas tree (.svat): its triangles, wall colours through its atlases (what `--city blockmap` builds).
    std::optional<city::AtlasTreeFile> tree;
    Result<city::CityModel> model = Error{""};
    if (std::filesystem::path(a->input).extension() == ".svat") {
        auto f = city::AtlasTreeFile::open(a->input);
        if (!f) return fail(f.error().message);
        tree = std::move(*f);
        model = city::modelOfTree(*tree);
    } else {
        model = loadCityForCli(a->input, a->crs, a->objLocal, a->objUp);
    }
    if (!model) return fail(model.error().message);
    std::printf("%s: %zu buildings, %zu triangles, %zu textures\n", a->input.c_str(), model->buildingIds.size(),
                model->triangles.size(), model->textures.size());
    std::fflush(stdout);
    city::CityBlockMapSettings s;
    s.map.size = a->blockMapSize;
    s.map.wallTexels = a->wallTexels;
    s.leafTexel = a->leafTexel;
    s.cacheBytes = std::uint64_t(std::max(16.0, a->cacheMb) * 1048576.0);
    s.progress = terminalProgress("blockmaps");
    if (tree) s.atlasTree = &*tree;
    auto r = city::buildCityBlockMaps(*model, s, a->out);
    if (!r) return fail(model->failureWithWarnings(r.error().message));
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("%s: %zu BlockMaps of %d² texels (depth %d, root %.0f m, leaves %.1f m per texel), %zu wall columns, "
                "file %.1f MB, %llu texture reads, %llu atlas reads, %.1f s, peak RSS %.2f GB\n",
                a->out.c_str(), r->maps, s.map.size, r->depth, r->rootSide, r->rootSide / double(s.map.size << r->depth),
                r->columns, double(r->fileBytes) / 1e6, (unsigned long long)r->textureReads,
                (unsigned long long)r->atlasReads, seconds, peakRssGb());
    if (!a->report.empty()) {
        nlohmann::json j = {{"input", a->input},     {"buildings", model->buildingIds.size()},
                            {"triangles", model->triangles.size()}, {"maps", r->maps},
                            {"depth", r->depth},     {"root_side_m", r->rootSide},
                            {"size", s.map.size},    {"wall_texels", s.map.wallTexels},
                            {"columns", r->columns}, {"file_bytes", r->fileBytes},
                            {"texture_reads", r->textureReads}, {"atlas_reads", r->atlasReads},
                            {"seconds", seconds},
                            {"peak_rss_gb", peakRssGb()}};
        std::string err;
        if (!writeTextAtomic(a->report, j.dump(2) + "\n", err)) return fail(a->report + ": " + err);
    }
    return 0;
}

} // namespace

Runner addAtlasCommand(CLI::App& app) {
    auto a = std::make_shared<AtlasArgs>();
    CLI::App* cmd = app.add_subcommand("atlas", "Multiresolution texture-atlas trees of city models (build, info)");
    cmd->require_subcommand(1);
    CLI::App* build = cmd->add_subcommand("build", "Build the texture-atlas tree of a CityGML or OBJ city model");
    build->add_option("INPUT", a->input, "City model: CityGML (.gml/.xml) or OBJ (.obj with its .mtl)")->required();
    build->add_option("--out", a->out, "Tree file to write (written whole or not at all)")->required();
    build->add_option("--atlas-size", a->atlasSize, "Atlas width and height A, texels (power of two)")->capture_default_str();
    build->add_option("--dmin", a->dmin, "Minimum distance for atlases, metres, or 'auto' (bounding-box diagonal / 72)")
        ->capture_default_str();
    build->add_option("--tpp", a->tpp, "Pixels per texel the textures are sized for")->capture_default_str();
    build->add_option("--border", a->border,
                      "Texel border b around each texture in the atlas (thesis 4.5.2: b = 8 keeps mips 1-3 free of "
                      "neighbouring textures; 2b keeps one more level); areas are sized in multiples of b")
        ->check(CLI::Range(1, 64))
        ->capture_default_str();
    build->add_option("--format", a->format, "Atlas storage: bc (BC1/BC3, default) or deflate (lossless)")
        ->check(CLI::IsMember({"bc", "deflate"}))
        ->capture_default_str();
    build->add_option("--packer", a->packer,
                      "Atlas packing: maxrects (MAXRECTS, best short side fit, quarter turns; default) or skyline "
                      "(stb_rect_pack, no turns)")
        ->check(CLI::IsMember({"maxrects", "skyline"}))
        ->capture_default_str();
    build->add_option("--roofs", a->roofs, "imagery: roofs left to the terrain's imagery clipmap; model: their own textures")
        ->check(CLI::IsMember({"imagery", "model"}))
        ->capture_default_str();
    build->add_option("--screen-width", a->screenWidth, "Screen width the minDistances assume, pixels")->capture_default_str();
    build->add_option("--fov-x", a->fovX, "Horizontal field of view the minDistances assume, degrees")->capture_default_str();
    build->add_option("--cache-mb", a->cacheMb, "Original textures held in memory while building, MB")->capture_default_str();
    build->add_option("--city-crs", a->crs, "CRS of a model that names none (OBJ, CityGML without srsName): EPSG:CODE");
    build->add_flag("--obj-local", a->objLocal, "OBJ positions are already metres in the scene's local frame");
    build->add_option("--obj-up", a->objUp, "OBJ up axis")->check(CLI::IsMember({"y", "z"}))->capture_default_str();
    build->add_option("--report", a->report, "Write the build figures as JSON");
    CLI::App* compare = cmd->add_subcommand(
        "compare", "Compare the atlases of two trees of the same model (e.g. --format bc vs deflate): size, decode time, "
                   "PSNR of B against A");
    compare->add_option("A", a->treeA, "Reference tree (e.g. lossless)")->required();
    compare->add_option("B", a->treeB, "Tree to compare")->required();
    CLI::App* info = cmd->add_subcommand("info", "Print a tree file's parameters, nodes and sizes");
    info->add_option("TREE", a->tree, "Tree file")->required();
    info->add_option("--atlas-png", a->atlasPng, "Write node N's atlas (of the first tree) as a PNG: N:FILE.png")
        ->expected(1, 64);

    CLI::App* blockmaps = cmd->add_subcommand(
        "blockmaps", "Build a city model's BlockMaps (Cignoni et al. 2007): discrete textured prisms for the far field");
    blockmaps->add_option("INPUT", a->input,
                          "City model: CityGML (.gml/.xml) or OBJ (.obj with its .mtl), or its atlas tree (.svat: wall "
                          "colours through its atlases, as --city blockmap builds them)")
        ->required();
    blockmaps->add_option("--out", a->out, "BlockMap file to write (written whole or not at all)")->required();
    blockmaps->add_option("--size", a->blockMapSize, "Height-map texels per side of every BlockMap")
        ->check(CLI::Range(2, 4096))
        ->capture_default_str();
    blockmaps->add_option("--wall-texels", a->wallTexels, "Colours per wall column, foot to top")
        ->check(CLI::Range(1, 1024))
        ->capture_default_str();
    blockmaps->add_option("--leaf-texel", a->leafTexel, "Metres per texel of the finest BlockMaps")->capture_default_str();
    blockmaps->add_option("--cache-mb", a->cacheMb, "Original textures held in memory while building, MB")
        ->capture_default_str();
    blockmaps->add_option("--city-crs", a->crs, "CRS of a model that names none (OBJ, CityGML without srsName): EPSG:CODE");
    blockmaps->add_flag("--obj-local", a->objLocal, "OBJ positions are already metres in the scene's local frame");
    blockmaps->add_option("--obj-up", a->objUp, "OBJ up axis")->check(CLI::IsMember({"y", "z"}))->capture_default_str();
    blockmaps->add_option("--report", a->report, "Write the build figures as JSON");

    return [a, build, info, compare, blockmaps]() -> int {
        (void)build;
        if (blockmaps->parsed()) return atlasBlockMaps(a.get());
        if (compare->parsed()) return atlasCompare(a.get());
        if (info->parsed()) return atlasInfo(a.get());
        return atlasBuild(a.get());
    };
}

} // namespace seasonview::app
