#include "ClipmapCenters.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>

namespace seasonview {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr CenterPlacement kAll[] = {CenterPlacement::Concentric, CenterPlacement::Offset, CenterPlacement::Footprint};

// The view's rays, with the camera's basis and the field of view's tangent computed once: the same arithmetic as
// evaluating them per ray (groundHit), without five sine-cosine pairs and a tangent per ray (the footprint placement
// casts three rays per screen sample, about 27,000 a frame at 640×360).
struct ViewRays {
    glm::dvec3 forward, right, up, origin;
    double tanHalf, aspect, groundHeight;

    explicit ViewRays(const ViewSetup& v)
        : forward(v.camera.forward()), right(v.camera.right()), up(v.camera.up()), origin(v.camera.position),
          tanHalf(std::tan(v.camera.fovYDeg * 0.5 * kPi / 180.0)), aspect(v.aspect), groundHeight(v.groundHeight) {}

    glm::dvec3 direction(double ndcX, double ndcY) const {
        return forward + right * (ndcX * tanHalf * aspect) + up * (ndcY * tanHalf);
    }

    std::optional<glm::dvec2> groundHit(double ndcX, double ndcY) const {
        const glm::dvec3 d = direction(ndcX, ndcY);
        const glm::dvec3& o = origin;
        if (d.z >= -1e-12 || o.z <= groundHeight) return std::nullopt;
        const double t = (groundHeight - o.z) / d.z;
        return glm::dvec2(o.x + t * d.x, o.y + t * d.y);
    }
};

bool inside(glm::dvec2 p, glm::dvec2 c, double half) {
    return std::fabs(p.x - c.x) <= half && std::fabs(p.y - c.y) <= half;
}

// A screen sample on the ground: position and the level its footprint needs.
struct GroundSample {
    glm::dvec2 p;
    int needed;
};

std::vector<GroundSample> groundSamples(const ViewSetup& v, const ClipmapGeometry& g, int step) {
    std::vector<GroundSample> out;
    out.reserve(size_t((v.width / step + 1) * (v.height / step + 1)));
    const ViewRays rays(v);
    const double px = 2.0 / double(v.width), py = 2.0 / double(v.height); // NDC per pixel
    for (int y = step / 2; y < v.height; y += step)
        for (int x = step / 2; x < v.width; x += step) {
            const double nx = -1.0 + (x + 0.5) * px, ny = 1.0 - (y + 0.5) * py;
            const auto p = rays.groundHit(nx, ny);
            if (!p) continue;
            const auto qx = rays.groundHit(nx + px, ny);
            const auto qy = rays.groundHit(nx, ny - py);
            // Near the horizon a neighbour may miss the ground: the footprint is then huge (any level will do).
            const double fx = qx ? glm::length(*qx - *p) : 1e30;
            const double fy = qy ? glm::length(*qy - *p) : 1e30;
            out.push_back({*p, neededLevel(std::max(fx, fy), g)});
        }
    return out;
}

std::vector<glm::dvec2> concentric(const ViewSetup& v, const ClipmapGeometry& g) {
    return std::vector<glm::dvec2>(size_t(g.levels), glm::dvec2(v.camera.position));
}

// Ropinski 2007 §3.2: front edges coincide on the frustum's bottom edge; switch to §3.1 within ~15° of nadir.
std::vector<glm::dvec2> offset(const ViewSetup& v, const ClipmapGeometry& g) {
    const glm::dvec3 f = v.camera.forward();
    const double alpha = std::acos(std::clamp(-f.z, -1.0, 1.0)) * 180.0 / kPi;
    const glm::dvec2 horizontal(f.x, f.y);
    if (alpha < kNadirSwitchDeg || glm::length(horizontal) < 1e-9) return concentric(v, g);
    const glm::dvec2 gvec = glm::normalize(horizontal);
    const glm::dvec2 foot(v.camera.position);
    // The bottom plane of the frustum meets the ground along a line through the bottom-centre ray's hit.
    glm::dvec2 edge = foot;
    if (auto hit = groundHit(v, 0.0, -1.0)) edge = foot + gvec * std::max(0.0, glm::dot(*hit - foot, gvec));
    std::vector<glm::dvec2> c(size_t(g.levels));
    for (int l = 0; l < g.levels; ++l) c[size_t(l)] = edge + gvec * (0.5 * g.extent(l));
    return c;
}

// Ours: greedy per level over screen samples. Level l serves the samples not yet inside a finer level that need
// exactly level l (only levels <= l can serve them) and, with half weight, those that need a coarser level. Box
// mean-shift from several starts finds a dense window; each level stays inside the next coarser one (nesting),
// so trilinear blending and the coarser-level fallback always find both levels.
std::vector<glm::dvec2> footprint(const ViewSetup& v, const ClipmapGeometry& g) {
    const std::vector<glm::dvec2> off = offset(v, g);
    const std::vector<GroundSample> samples = groundSamples(v, g, std::max(4, v.height / 64));
    if (samples.empty()) return off;
    std::vector<char> covered(samples.size(), 0);
    std::vector<glm::dvec2> c(size_t(g.levels));
    for (int l = 0; l < g.levels; ++l) {
        const double half = 0.5 * g.extent(l);
        // The samples of weight > 0, with their weights: 1 for those that need exactly level l, 0.5 for those that
        // need a coarser one. The others (inside a finer level, or needing a finer one) add nothing to a sum or a
        // score and never weigh again at a coarser level. The same sums, in the same order, as over every sample.
        struct Weighted {
            glm::dvec2 p;
            double w;
        };
        std::vector<Weighted> active;
        active.reserve(samples.size());
        for (size_t i = 0; i < samples.size(); ++i)
            if (!covered[i] && samples[i].needed >= l)
                active.push_back({samples[i].p, samples[i].needed == l ? 1.0 : 0.5});
        // Allowed centres: inside the box that keeps level l-1 within level l.
        const glm::dvec2 lo = l == 0 ? glm::dvec2(-1e300) : c[size_t(l - 1)] - glm::dvec2(half - 0.5 * g.extent(l - 1));
        const glm::dvec2 hi = l == 0 ? glm::dvec2(1e300) : c[size_t(l - 1)] + glm::dvec2(half - 0.5 * g.extent(l - 1));
        auto score = [&](glm::dvec2 centre) {
            double s = 0;
            for (const Weighted& a : active)
                if (inside(a.p, centre, half)) s += a.w;
            return s;
        };
        std::vector<glm::dvec2> starts = {off[size_t(l)], glm::dvec2(v.camera.position)};
        if (l > 0) starts.push_back(c[size_t(l - 1)]);
        glm::dvec2 bmin(1e300), bmax(-1e300);
        for (const Weighted& a : active)
            if (a.w == 1.0) {
                bmin = glm::min(bmin, a.p);
                bmax = glm::max(bmax, a.p);
            }
        if (bmin.x <= bmax.x) starts.push_back(0.5 * (bmin + bmax));
        glm::dvec2 best = glm::clamp(starts[0], lo, hi);
        double bestScore = -1;
        for (glm::dvec2 s : starts) {
            glm::dvec2 centre = glm::clamp(s, lo, hi);
            for (int it = 0; it < 12; ++it) {
                glm::dvec2 sum(0.0);
                double w = 0;
                for (const Weighted& a : active)
                    if (inside(a.p, centre, half)) {
                        sum += a.w * a.p;
                        w += a.w;
                    }
                if (w <= 0) break;
                const glm::dvec2 next = glm::clamp(sum / w, lo, hi);
                if (glm::length(next - centre) < 1e-3 * half) break;
                centre = next;
            }
            const double sc = score(centre);
            if (sc > bestScore) {
                bestScore = sc;
                best = centre;
            }
        }
        c[size_t(l)] = best;
        for (size_t i = 0; i < samples.size(); ++i)
            if (inside(samples[i].p, best, half)) covered[i] = 1;
    }
    return c;
}

} // namespace

const char* placementName(CenterPlacement p) {
    switch (p) {
    case CenterPlacement::Concentric: return "concentric";
    case CenterPlacement::Offset: return "offset";
    case CenterPlacement::Footprint: return "footprint";
    }
    return "?";
}

std::optional<CenterPlacement> parsePlacement(const std::string& name) {
    for (CenterPlacement p : kAll)
        if (name == placementName(p)) return p;
    return std::nullopt;
}

std::string placementNames() {
    std::string s;
    for (CenterPlacement p : kAll) s += (s.empty() ? "" : "|") + std::string(placementName(p));
    return s;
}

std::optional<glm::dvec2> groundHit(const ViewSetup& view, double ndcX, double ndcY) {
    return ViewRays(view).groundHit(ndcX, ndcY);
}

std::vector<glm::dvec2> placeCenters(CenterPlacement placement, const ViewSetup& view, const ClipmapGeometry& geometry) {
    switch (placement) {
    case CenterPlacement::Concentric: return concentric(view, geometry);
    case CenterPlacement::Offset: return offset(view, geometry);
    case CenterPlacement::Footprint: return footprint(view, geometry);
    }
    return concentric(view, geometry);
}

int neededLevel(double footprint, const ClipmapGeometry& geometry) {
    if (!(footprint > geometry.texelSize0)) return 0;
    const int r = int(std::floor(std::log2(footprint / geometry.texelSize0)));
    return std::clamp(r, 0, geometry.levels);
}

CoverageStats measureCoverage(const ViewSetup& view, const ClipmapGeometry& geometry,
                              const std::vector<glm::dvec2>& centres, int step) {
    CoverageStats s;
    s.usedLevelHistogram.assign(size_t(geometry.levels) + 1, 0.0);
    const std::vector<GroundSample> samples = groundSamples(view, geometry, std::max(1, step));
    int good = 0;
    double deficit = 0;
    for (const GroundSample& g : samples) {
        int used = geometry.levels;
        for (int l = 0; l < geometry.levels; ++l)
            if (inside(g.p, centres[size_t(l)], 0.5 * geometry.extent(l))) {
                used = l;
                break;
            }
        good += used <= g.needed ? 1 : 0;
        deficit += std::max(0, used - g.needed);
        s.usedLevelHistogram[size_t(used)] += 1.0;
    }
    s.groundSamples = int(samples.size());
    if (s.groundSamples > 0) {
        s.coverage = double(good) / s.groundSamples;
        s.meanLevelDeficit = deficit / s.groundSamples;
        for (double& h : s.usedLevelHistogram) h /= s.groundSamples;
    }
    return s;
}

} // namespace seasonview
