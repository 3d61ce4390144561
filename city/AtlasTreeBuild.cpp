#include "AtlasTreeBuild.h"

#include "AtlasCodec.h"
#include "AtlasTreeIo.h"
#include "AtomicFile.h"
#include "ParallelIndices.h"
#include "TextureSource.h"

#include <libdeflate.h>
#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <numeric>
#include <set>
#include <thread>

namespace seasonview::city {

std::array<TexturedTriangle, 2> splitTriangle(const TexturedTriangle& tri, double fproj, glm::dvec2 maxTexels) {
    // The edge spanning the most atlas texels: its texture-space length times the texels per repetition.
    const WorldScale w = textureWorldScale(tri);
    const glm::dvec2 texels = glm::max(glm::min(glm::dvec2(w.s, w.t) * fproj, maxTexels), glm::dvec2(1.0));
    int best = 0;
    double bestLen = -1.0;
    for (int e = 0; e < 3; ++e) {
        const glm::dvec2 d = (tri.t[std::size_t((e + 1) % 3)] - tri.t[std::size_t(e)]) * texels;
        // Ties (and single-colour triangles) fall back to the world-space length.
        const double len = glm::length(d) + 1e-9 * glm::length(tri.v[std::size_t((e + 1) % 3)] - tri.v[std::size_t(e)]);
        if (len > bestLen) {
            bestLen = len;
            best = e;
        }
    }
    const auto a = std::size_t(best), b = std::size_t((best + 1) % 3), c = std::size_t((best + 2) % 3);
    const glm::dvec3 mv = 0.5 * (tri.v[a] + tri.v[b]);
    const glm::dvec2 mt = 0.5 * (tri.t[a] + tri.t[b]);
    TexturedTriangle t0 = tri, t1 = tri;
    t0.v = {tri.v[a], mv, tri.v[c]};
    t0.t = {tri.t[a], mt, tri.t[c]};
    t1.v = {mv, tri.v[b], tri.v[c]};
    t1.t = {mt, tri.t[b], tri.t[c]};
    return {t0, t1};
}

namespace {

struct TreeInput {
    bool alpha = false;
    std::vector<TexturedTriangle> tris;
    std::vector<std::uint32_t> building;
};

/// The original texture's size (texels per repetition never exceed it), infinite when unknown.
glm::dvec2 capOf(const CityTexture& t) {
    return t.width > 0 && t.height > 0 ? glm::dvec2(t.width, t.height) : glm::dvec2(INFINITY);
}

bool fits(const AtlasArea& a, int atlasSize) { return a.size.x <= atlasSize && a.size.y <= atlasSize; }

/// How much dmin must grow for a lone triangle to fit: its texel extent (without the border) scales as 1/dmin.
double growthToFit(const AtlasArea& a, int atlasSize, int border) {
    const double room = double(atlasSize - 2 * border);
    return std::max({1.0, double(a.size.x - 2 * border) / room, double(a.size.y - 2 * border) / room});
}

/// Groups one texture's triangles into clusters whose texture-space rectangles overlap (or come within `margin`):
/// each cluster gets its own atlas area. The thesis takes one rectangle per texture and node, assuming every
/// texture maps uniquely onto one surface; textures that are themselves atlases of many facades (PLATEAU) would then
/// cost the whole texture for every node that uses any part of it.
std::vector<std::vector<std::uint32_t>> clusterByUv(const std::vector<TexturedTriangle>& all,
                                                    const std::vector<std::uint32_t>& ids, glm::dvec2 margin) {
    struct Cluster {
        glm::dvec2 lo, hi;
        std::vector<std::uint32_t> ids;
    };
    std::vector<Cluster> cs;
    for (auto i : ids) {
        const auto& t = all[i].t;
        cs.push_back({glm::min(t[0], glm::min(t[1], t[2])), glm::max(t[0], glm::max(t[1], t[2])), {i}});
    }
    auto near = [&](const Cluster& a, const Cluster& b) {
        return a.lo.x <= b.hi.x + margin.x && b.lo.x <= a.hi.x + margin.x && a.lo.y <= b.hi.y + margin.y &&
               b.lo.y <= a.hi.y + margin.y;
    };
    for (bool merged = true; merged && cs.size() > 1;) {
        merged = false;
        std::sort(cs.begin(), cs.end(), [](const Cluster& a, const Cluster& b) { return a.lo.x < b.lo.x; });
        std::vector<Cluster> out;
        std::vector<std::size_t> open; // indices into out whose x range may still reach the sweep line
        for (auto& c : cs) {
            std::size_t into = SIZE_MAX;
            for (std::size_t k = 0; k < open.size();) {
                Cluster& o = out[open[k]];
                if (o.hi.x + margin.x < c.lo.x) { // left behind for good
                    open[k] = open.back();
                    open.pop_back();
                    continue;
                }
                if (near(o, c)) {
                    if (into == SIZE_MAX) {
                        into = open[k];
                        o.lo = glm::min(o.lo, c.lo);
                        o.hi = glm::max(o.hi, c.hi);
                        o.ids.insert(o.ids.end(), c.ids.begin(), c.ids.end());
                    }
                    merged = true;
                }
                ++k;
            }
            if (into == SIZE_MAX) {
                out.push_back(std::move(c));
                open.push_back(out.size() - 1);
            }
        }
        cs = std::move(out);
    }
    std::vector<std::vector<std::uint32_t>> groups;
    for (auto& c : cs) groups.push_back(std::move(c.ids));
    return groups;
}

/// A leaf's atlas plan: the packed areas and, per area, its triangles (indices into the tree input).
struct LeafPlan {
    std::vector<AtlasArea> areas;
    std::vector<std::vector<std::uint32_t>> areaTris;
};

/// Indices of `points` in the order of a Hilbert curve over their bounding box's two longest axes.
std::vector<std::uint32_t> hilbertOrder(const std::vector<glm::dvec3>& points) {
    glm::dvec3 lo(INFINITY), hi(-INFINITY);
    for (const auto& p : points) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    const glm::dvec3 d = hi - lo;
    std::array<int, 3> axes = {0, 1, 2};
    std::sort(axes.begin(), axes.end(), [&](int a, int b) { return d[a] > d[b]; });
    constexpr std::uint32_t n = 1u << 16;
    auto cell = [&](const glm::dvec3& p, int axis) {
        const double f = d[axis] > 0.0 ? (p[axis] - lo[axis]) / d[axis] : 0.0;
        return std::min(n - 1, std::uint32_t(std::max(0.0, f) * double(n)));
    };
    std::vector<std::uint64_t> key(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
        std::uint32_t x = cell(points[i], axes[0]), y = cell(points[i], axes[1]);
        std::uint64_t k = 0;
        for (std::uint32_t q = n / 2; q > 0; q /= 2) { // the classic xy → d conversion
            const std::uint32_t rx = (x & q) ? 1 : 0, ry = (y & q) ? 1 : 0;
            k += std::uint64_t(q) * q * ((3 * rx) ^ ry);
            if (ry == 0) {
                if (rx == 1) {
                    x = n - 1 - x;
                    y = n - 1 - y;
                }
                std::swap(x, y);
            }
        }
        key[i] = k;
    }
    std::vector<std::uint32_t> order(points.size());
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return key[a] < key[b]; });
    return order;
}

struct Builder {
    const AtlasBuildSettings& s;
    double fproj;
    TreeInput& in;
    AtlasTreeData& out;
    const std::vector<CityTexture>& textures;
    std::vector<TexturedTriangle> ordered;      // §4.8.1 order
    std::vector<std::uint32_t> orderedBuilding;
    std::vector<std::uint32_t> orderedArea;     // per ordered triangle: its area in its leaf's plan
    std::map<int, LeafPlan> plans;              // node -> plan
    std::vector<std::vector<int>> paths;        // node -> child indices from the root
    double fillSum = 0.0;
    std::size_t nonEmptyLeaves = 0;
    int depth = 0;

    glm::dvec2 cap(int texture) const { return capOf(textures[std::size_t(texture)]); }

    /// The atlas areas of one texture's triangles `texIds`: one per cluster of overlapping texture rectangles
    /// (rectangles whose borders would touch share one area), each with its triangles.
    void textureAreas(int tex, const std::vector<std::uint32_t>& texIds, std::vector<AtlasArea>& areas,
                      std::vector<std::vector<std::uint32_t>>& areaTris) const {
        const glm::dvec2 c = cap(tex);
        const glm::dvec2 margin = std::isfinite(c.x) ? 2.0 * double(s.border) / c : glm::dvec2(0.0);
        for (auto& group : clusterByUv(in.tris, texIds, margin)) {
            std::vector<const TexturedTriangle*> tris;
            for (auto i : group) tris.push_back(&in.tris[i]);
            areas.push_back(requiredAtlasArea(tris, fproj, s.border, c));
            areaTris.push_back(std::move(group));
        }
    }

    /// Tries to pack `ids`; on success returns the plan.
    std::optional<LeafPlan> tryPack(const std::vector<std::uint32_t>& ids, double* fill) const {
        std::map<int, std::vector<std::uint32_t>> byTexture;
        for (auto i : ids) byTexture[in.tris[i].texture].push_back(i);
        LeafPlan plan;
        for (auto& [tex, texIds] : byTexture) textureAreas(tex, texIds, plan.areas, plan.areaTris);
        for (const auto& a : plan.areas)
            if (!fits(a, s.atlasSize)) return std::nullopt;
        if (!packAtlas(plan.areas, s.atlasSize, fill, s.packer)) return std::nullopt;
        return plan;
    }

    /// Atlas texels the triangles `texIds` (all of one texture) need at the leaves' resolution, as tryPack would
    /// place them (a quick upper bound before a trial packing).
    double atlasTexels(int tex, const std::vector<std::uint32_t>& texIds) const {
        std::vector<AtlasArea> areas;
        std::vector<std::vector<std::uint32_t>> areaTris;
        textureAreas(tex, texIds, areas, areaTris);
        double texels = 0.0;
        for (const auto& a : areas) texels += double(a.size.x) * double(a.size.y);
        return texels;
    }

    /// Texture -> its leaf run (see split), computed once for all of this tree's textures.
    std::map<int, int> runOf;
    /// The level of the leaves the runs become: ceil(log4(runs)).
    int runLevels = 0;

    /// Beyond the thesis: partitions all texture groups into leaf runs. The groups, in Hilbert order of their
    /// area-weighted midpoints (so a run, and a range of consecutive runs, is compact in space), are cut
    /// greedily into runs that still pack into one atlas (a trial packing decides; the summed areas only
    /// reject early). This is the bottom-up packing of Hilbert R-trees (Kamel & Faloutsos 1993) applied to the
    /// atlas tree: the thesis's top-down area-balanced quartering leaves leaves a quarter full when a node just
    /// missed fitting (28 % mean fill on a 10,000-building block city), and each extra node costs a draw and a
    /// bind per frame.
    void planRuns(const std::map<int, std::vector<std::uint32_t>>& byTexture) {
        std::vector<int> texs;
        std::vector<glm::dvec3> mid;
        std::vector<double> texels;
        for (const auto& [tex, tris] : byTexture) {
            glm::dvec3 m(0.0);
            double a = 0.0;
            for (auto i : tris) {
                const double ta = std::max(triangleArea(in.tris[i]), 1e-12);
                m += ta * (in.tris[i].v[0] + in.tris[i].v[1] + in.tris[i].v[2]) / 3.0;
                a += ta;
            }
            texs.push_back(tex);
            mid.push_back(m / a);
            texels.push_back(atlasTexels(tex, tris));
        }
        const double atlasTexelsMax = double(s.atlasSize) * double(s.atlasSize);
        int run = 0;
        double acc = 0.0;
        std::vector<std::uint32_t> runIds;
        for (auto g : hilbertOrder(mid)) {
            const auto& tris = byTexture.at(texs[g]);
            bool join = !runIds.empty() && acc + texels[g] <= atlasTexelsMax;
            if (join) {
                auto trial = runIds;
                trial.insert(trial.end(), tris.begin(), tris.end());
                join = tryPack(trial, nullptr).has_value();
            }
            if (!join && !runIds.empty()) {
                ++run;
                runIds.clear();
                acc = 0.0;
            }
            runIds.insert(runIds.end(), tris.begin(), tris.end());
            acc += texels[g];
            runOf[texs[g]] = run;
        }
        runLevels = 0;
        for (long capacity = 1; capacity < long(run) + 1; capacity *= 4) ++runLevels;
    }

    /// §4.5.3's split, of whole texture groups while the node has several textures: the thesis assumes each
    /// texture maps uniquely, so that splitting triangles splits texture area; a facade texture repeated around
    /// a building is needed whole by every wall, and splitting the walls apart would copy it into every child.
    /// A node's runs (planRuns) are dealt to its four children in consecutive shares, full ones first: a node k
    /// levels above the leaves' level gets up to 4^k runs, so every inner node but those of the Hilbert order's tail
    /// holds as many runs as its minDistance (dmin · 2^k) allows — the bottom-up grouping of a Hilbert R-tree (the
    /// tail's leaves may sit higher up).
    /// (Near-equal shares leave nodes two levels above a leaf holding about 4.5 runs instead of 16 when the run
    /// count is just over a power of four, so about 3.5 times the nodes are drawn at those distances.) Only a node
    /// of one texture that does not fit is split by triangles, area-balanced along the two longest axes as in the
    /// thesis.
    std::array<std::vector<std::uint32_t>, 4> split(const std::vector<std::uint32_t>& ids, int level) {
        std::map<int, std::vector<std::uint32_t>> byTexture;
        for (auto i : ids) byTexture[in.tris[i].texture].push_back(i);
        if (byTexture.size() < 2) return splitByArea(in.tris, ids);
        if (runOf.empty()) planRuns(byTexture); // the first split is the root's: all textures
        std::map<int, std::vector<std::uint32_t>> byRun;
        for (const auto& [tex, tris] : byTexture) {
            auto& r = byRun[runOf.at(tex)];
            r.insert(r.end(), tris.begin(), tris.end());
        }
        std::array<std::vector<std::uint32_t>, 4> parts;
        // One run packs (planRuns tried exactly its triangles), so a node that did not pack holds two or more;
        // should that ever fail, the thesis's triangle split still ends the recursion.
        if (byRun.size() < 2) return splitByArea(in.tris, ids);
        const std::size_t m = byRun.size();
        // 4^(height - 1), height the levels down to the leaves' level, but no more than the node's own runs need
        // (4^(ceil(log4 m) - 1)): a tail node of few runs would otherwise pass them all to one child, a copy of itself.
        std::size_t perChild = 1;
        for (int h = runLevels - level; h > 1 && 4 * perChild < m; --h) perChild *= 4;
        std::size_t k = 0;
        for (const auto& [run, tris] : byRun) {
            // Consecutive runs (a node's are), full shares first; near-equal shares should a node ever hold more.
            const std::size_t c = m <= 4 * perChild ? k / perChild : k * 4 / m;
            parts[c].insert(parts[c].end(), tris.begin(), tris.end());
            ++k;
        }
        return parts;
    }

    int node(const std::vector<std::uint32_t>& ids, int level, int parent, std::vector<int> path) {
        const int index = int(out.nodes.size());
        out.nodes.emplace_back();
        paths.push_back(path);
        depth = std::max(depth, level);
        {
            AtlasNode& n = out.nodes.back();
            n.level = level;
            n.parent = parent;
            n.first = std::uint32_t(ordered.size());
        }
        double fill = 0.0;
        std::optional<LeafPlan> plan;
        if (ids.empty()) plan = LeafPlan{};
        else plan = tryPack(ids, &fill);
        if (plan) {
            for (std::size_t a = 0; a < plan->areaTris.size(); ++a)
                for (auto i : plan->areaTris[a]) {
                    ordered.push_back(in.tris[i]);
                    orderedBuilding.push_back(in.building[i]);
                    orderedArea.push_back(std::uint32_t(a));
                }
            if (!ids.empty()) {
                fillSum += fill;
                ++nonEmptyLeaves;
            }
            plans.emplace(index, std::move(*plan));
        } else {
            const auto groups = split(ids, level);
            for (int c = 0; c < 4; ++c) {
                auto childPath = path;
                childPath.push_back(c);
                const int child = node(groups[std::size_t(c)], level + 1, index, childPath);
                out.nodes[std::size_t(index)].children[std::size_t(c)] = child;
            }
        }
        AtlasNode& n = out.nodes[std::size_t(index)];
        n.count = std::uint32_t(ordered.size()) - n.first;
        return index;
    }
};

} // namespace

namespace {

// Which triangles go where: textured ones into the RGB or RGBA tree (thesis §4.2), roofs (when the terrain's imagery
// textures them, §4.8.2) and untextured ones into the file's plain list.
Result<std::array<TreeInput, 2>> sortTriangles(const CityModel& model, const AtlasBuildSettings& s, AtlasTreeFile& file,
                                               AtlasBuildReport& report) {
    std::array<TreeInput, 2> inputs;
    inputs[1].alpha = true;
    for (std::size_t i = 0; i < model.triangles.size(); ++i) {
        TexturedTriangle t = model.triangles[i];
        const bool roof = model.surface[i] == Surface::Roof && s.roofsFromImagery;
        if (t.texture < 0 || roof) {
            for (const auto& v : t.v) file.plain.positions.emplace_back(v);
            file.plain.surface.push_back(model.surface[i]);
            file.plain.building.push_back(model.building[i]);
            continue;
        }
        const CityTexture& tex = model.textures[std::size_t(t.texture)];
        // A repeating texture's coordinates may move by whole repetitions: start each triangle's rectangle in
        // [0, 1) so triangles sharing a texture at different offsets share one atlas area (§4.5.2 assumes this
        // implicitly; it keeps A_tex small for facades whose u runs on around the building).
        if (tex.repeat) {
            const glm::dvec2 lo = glm::floor(glm::min(t.t[0], glm::min(t.t[1], t.t[2])));
            for (auto& c : t.t) c -= lo;
        }
        auto& input = inputs[tex.channels >= 4 ? 1 : 0];
        input.tris.push_back(t);
        input.building.push_back(model.building[i]);
    }
    report.plainTriangles = file.plain.surface.size();
    report.inputTreeTriangles = inputs[0].tris.size() + inputs[1].tris.size();
    if (report.inputTreeTriangles == 0) return fileError(model.source, "no textured triangles to build a tree from");
    return inputs;
}

// Texels per metre of distance an atlas needs at distance d (§4.5.2).
double fprojAt(const AtlasBuildSettings& s, double d) { return projectionFactor(d, s.fovXDeg, s.screenWidth) / s.tpp; }

// dmin: given, or D/72 (the thesis's Berlin test) with D the bounding-box diagonal; enlarged when more than the
// allowed fraction of triangles is critical (§4.5.3).
double chooseDmin(const CityModel& model, const AtlasBuildSettings& s, const std::array<TreeInput, 2>& inputs,
                  AtlasBuildReport& report) {
    const glm::dvec3 diag = model.boundsMax() - model.boundsMin();
    double dmin = s.dmin > 0.0 ? s.dmin : glm::length(diag) / 72.0;
    report.dminInitial = dmin;

    // Critical triangles (§4.5.3): if more than c are critical, enlarge dmin so that c are; split the rest.
    {
        std::vector<double> growth;
        for (const auto& input : inputs)
            for (const auto& t : input.tris) {
                // Critical: too large for an atlas at dmin even capped at the original's size. Enlarging dmin helps
                // by the uncapped size's factor (the capped one is then the uncapped one).
                const glm::dvec2 cap = capOf(model.textures[std::size_t(t.texture)]);
                const bool critical = !fits(requiredAtlasArea({&t}, fprojAt(s, dmin), s.border, cap), s.atlasSize);
                growth.push_back(critical ? growthToFit(requiredAtlasArea({&t}, fprojAt(s, dmin), s.border), s.atlasSize, s.border) : 1.0);
            }
        report.criticalAtDmin = std::size_t(std::count_if(growth.begin(), growth.end(), [](double g) { return g > 1.0; }));
        const double fraction = double(report.criticalAtDmin) / double(growth.size());
        if (fraction > s.maxCriticalFraction) {
            std::sort(growth.begin(), growth.end());
            // The smallest growth that leaves at most c·n triangles critical: the ceil((1 - c)·n)-th smallest.
            const auto k = std::size_t(std::ceil((1.0 - s.maxCriticalFraction) * double(growth.size())));
            const double g = growth[std::min(std::max<std::size_t>(k, 1) - 1, growth.size() - 1)];
            dmin *= g * 1.0001; // rounding of sizes: a hair more so the quantile's triangle fits
        }
    }
    report.dmin = dmin;
    return dmin;
}

// The triangles still critical at the final dmin are split until each fits an atlas (§4.5.3).
Status splitCritical(const CityModel& model, const AtlasBuildSettings& s, double fproj, std::array<TreeInput, 2>& inputs,
                     AtlasBuildReport& report) {
    for (auto& input : inputs) {
        std::vector<TexturedTriangle> done;
        std::vector<std::uint32_t> doneBuilding;
        std::vector<std::pair<TexturedTriangle, std::uint32_t>> work;
        for (std::size_t i = 0; i < input.tris.size(); ++i) work.emplace_back(input.tris[i], input.building[i]);
        while (!work.empty()) {
            auto [t, b] = work.back();
            work.pop_back();
            const glm::dvec2 cap = capOf(model.textures[std::size_t(t.texture)]);
            if (fits(requiredAtlasArea({&t}, fproj, s.border, cap), s.atlasSize)) {
                done.push_back(t);
                doneBuilding.push_back(b);
                continue;
            }
            if (++report.criticalSplit > 4 * input.tris.size() + 100000)
                return fileError(model.source, "critical triangles do not shrink by splitting (texture coordinates broken?)");
            for (const auto& half : splitTriangle(t, fproj, cap)) work.emplace_back(half, b);
        }
        input.tris = std::move(done);
        input.building = std::move(doneBuilding);
    }
    return Ok{};
}

// The atlases of one tree bottom-up (post-order), each written to the file as soon as it is made; a node's level-0
// image is kept until its parent has used it, so at most 4 per level of the current path are in memory.
struct AtlasMaker {
    const AtlasBuildSettings& s;
    Builder& b;
    AtlasTreeData& tree;
    AtlasTreeFile& file;
    TextureCache& cache;
    std::ofstream& os;
    std::uint64_t& offset;
    AtlasBuildReport& report;
    const std::function<void(double, const char*)>& progress;
    double dmin;
    int threads;
    std::size_t totalTris;
    std::size_t& trisDone;
    std::vector<std::vector<std::uint8_t>> images; // per node, until its parent has used it
    std::vector<double> base; // per node: the distance from which its atlas suffices (its parent's minDistance)
    std::optional<Error> failure;

    void make(int ni) {
        if (failure) return;
        AtlasNode& n = tree.nodes[std::size_t(ni)];
        const int A = s.atlasSize;
        std::vector<std::uint8_t> img(std::size_t(A) * std::size_t(A) * 4, 0);
        const bool empty = n.leaf() ? leaf(ni, img) : inner(ni, img);
        if (failure) return;
        // Bounds of the node's triangles.
        glm::vec3 lo(INFINITY), hi(-INFINITY);
        for (std::uint32_t t = n.first; t < n.first + n.count; ++t)
            for (const auto& v : b.ordered[t].v) {
                lo = glm::min(lo, glm::vec3(v));
                hi = glm::max(hi, glm::vec3(v));
            }
        n.boundsMin = n.count ? lo : glm::vec3(0.0f);
        n.boundsMax = n.count ? hi : glm::vec3(0.0f);
        if (!empty) {
            const auto blob = encodeAtlas(s.format, tree.alpha, img, A, threads);
            n.atlasOffset = offset;
            n.atlasBytes = blob.size();
            n.atlasCrc = std::uint32_t(libdeflate_crc32(0, blob.data(), blob.size()));
            os.write(reinterpret_cast<const char*>(blob.data()), std::streamsize(blob.size()));
            offset += blob.size();
            report.atlasBytes += blob.size();
        }
        images[std::size_t(ni)] = std::move(img);
    }

    // A leaf's atlas: its plan's areas sampled from the original textures (§4.5.2), its triangles' atlas and root
    // atlas coordinates (§4.5.4). True when it holds nothing.
    bool leaf(int ni, std::vector<std::uint8_t>& img) {
        AtlasNode& n = tree.nodes[std::size_t(ni)];
        const int A = s.atlasSize;
        n.minDistance = float(dmin);
        const LeafPlan& plan = b.plans.at(ni);
        // Where an original capped the stored size, the leaf holds all the detail there is but less than
        // a view at dmin could use: its ancestors' atlases (halved per level) suffice only from
        // capFactor times further away than the thesis's doubling says.
        double cap = 1.0;
        for (const auto& a : plan.areas) cap = std::max(cap, a.capFactor);
        base[std::size_t(ni)] = dmin * cap;
        const bool empty = plan.areas.empty();
        std::uint64_t texBytes = 0;
        std::set<int> leafTextures;
        std::vector<int> wanted;
        for (const auto& a : plan.areas) wanted.push_back(a.texture);
        if (auto st = cache.prefetch(wanted, threads); !st) {
            failure = st.error();
            return true;
        }
        std::vector<std::shared_ptr<const SourceTexture>> sources;
        for (const auto& a : plan.areas) {
            auto src = cache.get(a.texture);
            if (!src) {
                failure = src.error();
                return true;
            }
            sources.push_back(*src);
            file.textureSizes[std::size_t(a.texture)] = (*src)->sizes[0];
            if (leafTextures.insert(a.texture).second) {
                texBytes += (*src)->bytes();
                n.textures.push_back(std::uint32_t(a.texture));
            }
        }
        // Each atlas texel samples the source rectangle linearly; the footprint chooses the mip level. Areas
        // do not overlap, so they are filled in parallel.
        parallelIndices(int(plan.areas.size()), threads, [&](int ai, int) {
            const AtlasArea& a = plan.areas[std::size_t(ai)];
            const SourceTexture& st = *sources[std::size_t(ai)];
            const glm::dvec2 span = a.srcMax - a.srcMin;
            const double texelsPer = std::max(span.x * st.sizes[0].x / a.size.x, span.y * st.sizes[0].y / a.size.y);
            for (int y = 0; y < a.size.y; ++y)
                for (int x = 0; x < a.size.x; ++x) {
                    const glm::dvec2 uv = a.srcMin + span * glm::dvec2((x + 0.5) / a.size.x, (y + 0.5) / a.size.y);
                    const glm::vec4 c = st.sample(uv, texelsPer);
                    const glm::ivec2 at(a.atlasTexel(glm::dvec2(x, y)));
                    std::uint8_t* d = &img[(std::size_t(at.y) * std::size_t(A) + std::size_t(at.x)) * 4];
                    for (int k = 0; k < 4; ++k) d[k] = std::uint8_t(std::clamp(c[k] + 0.5f, 0.0f, 255.0f));
                }
        });
        // Empty atlas space continues the areas' edges (no black bleeding into coarse mips and wide
        // anisotropic footprints at the areas' rims).
        std::vector<std::uint8_t> covered(std::size_t(A) * std::size_t(A), 0);
        for (const auto& a : plan.areas)
            for (int y = 0; y < a.footprint().y; ++y)
                std::fill_n(&covered[std::size_t(a.position.y + y) * std::size_t(A) + std::size_t(a.position.x)],
                            std::size_t(a.footprint().x), std::uint8_t(1));
        dilateRgba(img, A, covered);
        n.textureBytes = texBytes;
        // Atlas coordinates of the leaf's triangles, then the root atlas's (§4.5.4).
        const auto& path = b.paths[std::size_t(ni)];
        for (std::uint32_t t = n.first; t < n.first + n.count; ++t) {
            const TexturedTriangle& tri = b.ordered[t];
            const AtlasArea& a = plan.areas[b.orderedArea[t]];
            for (int k = 0; k < 3; ++k) {
                const glm::dvec2 local =
                    a.atlasTexel((tri.t[std::size_t(k)] - a.srcMin) / (a.srcMax - a.srcMin) * glm::dvec2(a.size)) /
                    double(A);
                TreeVertex v;
                v.position = glm::vec3(tri.v[std::size_t(k)]);
                v.uv = glm::vec2(tri.t[std::size_t(k)]);
                v.root = glm::vec2(rootAtlasCoord(local, path));
                tree.vertices[std::size_t(t) * 3 + std::size_t(k)] = v;
            }
        }
        trisDone += n.count;
        progress(0.05 + 0.9 * double(trisDone) / double(totalTris), "atlases");
        return empty;
    }

    // An inner node's atlas: its children's atlases halved into its quadrants (§4.5.1). True when it holds nothing.
    bool inner(int ni, std::vector<std::uint8_t>& img) {
        AtlasNode& n = tree.nodes[std::size_t(ni)];
        const int A = s.atlasSize;
        double md = 0.0;
        bool any = false;
        for (int q = 0; q < 4; ++q) {
            const int c = n.children[std::size_t(q)];
            make(c);
            if (failure) return true;
            const AtlasNode& cn = tree.nodes[std::size_t(c)];
            if (cn.count > 0) {
                md = std::max(md, base[std::size_t(c)]);
                any = true;
            }
            // The child's atlas, halved, into quadrant q (0 bottom-left, 1 bottom-right, 2 top-left, 3 top-right).
            const auto half = halveRgba(images[std::size_t(c)], A);
            const int ox = (q % 2) * (A / 2), oy = (q / 2) * (A / 2);
            for (int y = 0; y < A / 2; ++y)
                std::copy_n(&half[std::size_t(y) * std::size_t(A / 2) * 4], std::size_t(A / 2) * 4,
                            &img[(std::size_t(oy + y) * std::size_t(A) + std::size_t(ox)) * 4]);
            images[std::size_t(c)].clear();
            images[std::size_t(c)].shrink_to_fit();
        }
        // Quadrants of empty children continue their neighbours, as a leaf's empty space does.
        std::vector<std::uint8_t> covered(std::size_t(A) * std::size_t(A), 0);
        bool gaps = false;
        for (int q = 0; q < 4; ++q) {
            const int c = n.children[std::size_t(q)];
            if (tree.nodes[std::size_t(c)].count == 0) {
                gaps = true;
                continue;
            }
            const int ox = (q % 2) * (A / 2), oy = (q / 2) * (A / 2);
            for (int y = 0; y < A / 2; ++y)
                std::fill_n(&covered[std::size_t(oy + y) * std::size_t(A) + std::size_t(ox)], std::size_t(A / 2),
                            std::uint8_t(1));
        }
        if (gaps && any) dilateRgba(img, A, covered);
        n.minDistance = float(2.0 * md); // §4.5.1: half the resolution is enough from twice the distance
        base[std::size_t(ni)] = 2.0 * md;
        return !any;
    }
};

} // namespace

Result<AtlasBuildReport> buildAtlasTree(const CityModel& model, const AtlasBuildSettings& s, const std::string& outPath) {
    AtlasBuildReport report;
    auto progress = [&](double f, const char* stage) {
        if (s.progress) s.progress(f, stage);
    };
    if (s.atlasSize < 64 || s.atlasSize > 16384 || (s.atlasSize & (s.atlasSize - 1)) != 0)
        return Error{"--atlas-size must be a power of two from 64 to 16384 (got " + std::to_string(s.atlasSize) + ")"};

    AtlasTreeFile file;
    auto sorted = sortTriangles(model, s, file, report);
    if (!sorted) return sorted.error();
    std::array<TreeInput, 2>& inputs = *sorted;

    const double dmin = chooseDmin(model, s, inputs, report);
    const double fproj = fprojAt(s, dmin);
    if (auto st = splitCritical(model, s, fproj, inputs, report); !st) return st.error();
    report.treeTriangles = inputs[0].tris.size() + inputs[1].tris.size();
    progress(0.05, "tree structure");

    // The file: header placeholder, atlases as they are made, the index last.
    const std::filesystem::path target(outPath);
    const auto tmp = temporaryPathFor(target);
    std::ofstream os(tmp, std::ios::binary | std::ios::trunc);
    if (!os) return fileError(outPath, "cannot write (directory missing or not writable?)");
    const std::vector<std::uint8_t> placeholder(detail::kHeaderBytes, 0);
    os.write(reinterpret_cast<const char*>(placeholder.data()), std::streamsize(placeholder.size()));
    std::uint64_t offset = detail::kHeaderBytes;

    file.textures = model.textures;
    file.textureChannels.assign(model.textures.size(), 3);
    file.textureSizes.assign(model.textures.size(), glm::ivec2(0));
    for (std::size_t t = 0; t < model.textures.size(); ++t) file.textureChannels[t] = model.textures[t].channels;
    TextureCache cache(model.textures, s.cacheBytes);
    const int threads = s.threads > 0 ? s.threads : std::max(1, int(std::thread::hardware_concurrency()));

    const std::size_t totalTris = report.treeTriangles;
    std::size_t trisDone = 0;
    double fillSum = 0.0;
    std::size_t fillCount = 0;
    for (auto& input : inputs) {
        if (input.tris.empty()) continue;
        AtlasTreeData tree;
        tree.alpha = input.alpha;
        Builder b{s, fproj, input, tree, model.textures, {}, {}, {}, {}, {}, 0.0, 0, 0, {}};
        std::vector<std::uint32_t> all(input.tris.size());
        std::iota(all.begin(), all.end(), 0u);
        b.node(all, 0, -1, {});
        report.depth = std::max(report.depth, b.depth);
        fillSum += b.fillSum;
        fillCount += b.nonEmptyLeaves;

        tree.vertices.resize(b.ordered.size() * 3);
        AtlasMaker maker{s,         b,         tree,     file,     cache,
                         os,        offset,    report,   progress, dmin,
                         threads,   totalTris, trisDone, std::vector<std::vector<std::uint8_t>>(tree.nodes.size()),
                         std::vector<double>(tree.nodes.size(), 0.0), std::nullopt};
        maker.make(0);
        if (maker.failure) {
            os.close();
            discardTemporary(tmp);
            return *maker.failure;
        }
        for (std::size_t t = 0; t < b.ordered.size(); ++t) {
            tree.triangleTexture.push_back(std::uint32_t(b.ordered[t].texture));
            tree.triangleBuilding.push_back(b.orderedBuilding[t]);
        }
        report.nodes += tree.nodes.size();
        for (const auto& n : tree.nodes)
            if (n.leaf()) {
                ++report.leaves;
                if (n.count == 0) ++report.emptyLeaves;
            }
        file.trees.push_back(std::move(tree));
    }
    report.meanLeafFill = fillCount ? fillSum / double(fillCount) : 0.0;
    report.textureReads = cache.reads();
    report.peakCacheBytes = cache.peakBytes();
    report.textures = model.textures.size();

    file.info.atlasSize = s.atlasSize;
    file.info.border = s.border;
    file.info.dmin = dmin;
    file.info.tpp = s.tpp;
    file.info.screenWidth = s.screenWidth;
    file.info.fovXDeg = s.fovXDeg;
    file.info.format = s.format;
    file.info.crs = model.crs;
    file.info.origin = model.origin;
    file.info.sceneFrame = model.sceneFrame;
    file.info.source = model.source;
    const auto index = detail::serializeIndex(file);
    os.write(reinterpret_cast<const char*>(index.data()), std::streamsize(index.size()));
    const auto header = detail::fileHeader(offset, index.size(), std::uint32_t(libdeflate_crc32(0, index.data(), index.size())));
    os.seekp(0);
    os.write(reinterpret_cast<const char*>(header.data()), std::streamsize(header.size()));
    os.close();
    if (!os) {
        discardTemporary(tmp);
        return fileError(outPath, "write failed (disk full?)");
    }
    std::string err;
    if (!commitTemporary(tmp, target, err)) return fileError(outPath, err);
    report.fileBytes = offset + index.size();
    progress(1.0, "done");
    return report;
}

} // namespace seasonview::city
