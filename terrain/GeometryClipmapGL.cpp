#include "GeometryClipmapGL.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <string>

namespace seasonview {

namespace {
constexpr int kLookupSize = 129; // local -> image lattice, per side
constexpr int kMaxElevationLevels = 24;
constexpr int kMaxGeometryLevels = 24;
} // namespace

Result<std::unique_ptr<GeometryClipmapGL>> GeometryClipmapGL::create(const Scene& scene, const ElevationGrid& grid,
                                                                     const ImagePyramid* elevation,
                                                                     const GeometryClipmapOptions& options) {
    assert(options.n >= 7 && ((options.n + 1) & options.n) == 0 && "GeometryClipmapGL: n must be 2^k - 1");
    auto g = std::unique_ptr<GeometryClipmapGL>(new GeometryClipmapGL());
    g->m_scene = &scene;
    g->m_grid = grid;
    g->m_options = options;
    g->m_ring = RingLayout::make(options.n);
    g->m_options.layerN = std::min(options.layerN, options.n);
    assert(g->m_options.layerN >= 7 && ((g->m_options.layerN + 1) & g->m_options.layerN) == 0 &&
           "GeometryClipmapGL: layerN must be 2^k - 1");
    g->m_layerRing = RingLayout::make(g->m_options.layerN);
    // DEM levels: enough for the coarsest to cover the DEM and the imagery from anywhere inside them. Then levels
    // finer than the DEM down to finestCellMetres, as many as fit (level coordinates in units of 2^−sub samples
    // stay below 2^30).
    g->m_imageryMin = scene.localMin;
    g->m_imageryMax = scene.localMax;
    const glm::dvec2 imagery = glm::max(scene.localMax - scene.localMin, glm::dvec2(0.0)) / grid.spacing;
    const int extentSamples = int(std::min(std::ceil(std::max({double(grid.width), double(grid.height), imagery.x,
                                                         imagery.y})), 1e9));
    const int demLevels = std::max(options.levels, geometryLevelCount(options.n, extentSamples));
    int sub = 0;
    while (std::ldexp(grid.spacing, -sub) > options.finestCellMetres * (1.0 + 1e-9) &&
           demLevels + sub < kMaxGeometryLevels &&
           double(options.n - 1) * std::ldexp(1.0, demLevels + sub) <= std::ldexp(1.0, 30))
        ++sub;
    g->m_subLevels = sub;
    g->m_levels = std::min(demLevels + sub, kMaxGeometryLevels);
    if (scene.elevation) {
        // Per-tile height ranges from the DEM's own samples under each tile (its corners taken through the CRS): the
        // resampled grid and everything interpolated from it stay inside them.
        const Heightfield& hf = *scene.elevation;
        const int W = hf.heights.width, H = hf.heights.height;
        g->m_bounds = HeightBounds::build(grid.width, grid.height, 128, [&](glm::dvec2 lo, glm::dvec2 hi) {
            lo = glm::floor(lo); // the grid samples any point of the box interpolates
            hi = glm::ceil(hi);
            glm::dvec2 pmin(1e300), pmax(-1e300);
            for (const glm::dvec2 c : {lo, hi, glm::dvec2(lo.x, hi.y), glm::dvec2(hi.x, lo.y)}) {
                const glm::dvec2 px =
                    hf.georef.crsToPixel(scene.frame.fromLocal(hf.georef.crs, grid.samplePosition(c.x, c.y))) - 0.5;
                pmin = glm::min(pmin, px);
                pmax = glm::max(pmax, px);
            }
            // The DEM samples around those (a hundredth of a pixel for the corners' curvature in another CRS).
            const int x0 = std::clamp(int(std::floor(pmin.x - 0.01)), 0, W - 1);
            const int x1 = std::clamp(int(std::ceil(pmax.x + 0.01)), 0, W - 1);
            const int y0 = std::clamp(int(std::floor(pmin.y - 0.01)), 0, H - 1);
            const int y1 = std::clamp(int(std::ceil(pmax.y + 0.01)), 0, H - 1);
            glm::vec2 r(1e30f, -1e30f);
            for (int y = y0; y <= y1; ++y)
                for (int x = x0; x <= x1; ++x) {
                    const float v = hf.heights.at(x, y);
                    r = glm::vec2(std::min(r.x, v), std::max(r.y, v));
                }
            return r;
        });
    } else {
        g->m_bounds = HeightBounds::flat(0.0f);
    }
    if (elevation) {
        if (elevation->format != TexelFormat::R32F || elevation->width() != grid.width ||
            elevation->height() != grid.height)
            return fileError(elevation->folder.string(), "elevation pyramid does not match the scene's elevation grid");
        if (elevation->levels.size() > size_t(kMaxElevationLevels))
            return fileError(elevation->folder.string(), "elevation pyramid has too many levels");
        ClipmapOptions co;
        co.size = std::max(256, options.elevationClipSize);
        co.uploadBudgetTexels = options.uploadBudgetTexels;
        co.cacheMegabytes = 64;
        auto clip = ClipmapGL::create({*elevation}, co);
        if (!clip) return clip.error();
        g->m_elevation = std::move(*clip);
        for (const PyramidLevel& l : elevation->levels) g->m_elevationLevelSizes.emplace_back(l.width, l.height);
    }

    // Local -> leaf-on image coordinates on a lattice reaching 1/8 of the extent past the imagery, so every
    // triangle touching the imagery interpolates between exact values (affine for UTM scenes, smooth otherwise).
    const glm::dvec2 extent = scene.localMax - scene.localMin;
    g->m_lookupMin = scene.localMin - extent / 8.0;
    g->m_lookupSize = extent * 1.25;
    std::vector<float> uv(size_t(kLookupSize) * kLookupSize * 2);
    const glm::dvec2 image(scene.leafon.info.width, scene.leafon.info.height);
    for (int j = 0; j < kLookupSize; ++j)
        for (int i = 0; i < kLookupSize; ++i) {
            const glm::dvec2 local = g->m_lookupMin + g->m_lookupSize * glm::dvec2(i, j) / double(kLookupSize - 1);
            const glm::dvec2 px = scene.localToImagePixel(local) / image;
            uv[(size_t(j) * kLookupSize + size_t(i)) * 2] = float(px.x);
            uv[(size_t(j) * kLookupSize + size_t(i)) * 2 + 1] = float(px.y);
        }
    auto uvAt = [&](int i, int j) {
        const size_t k = (size_t(j) * kLookupSize + size_t(i)) * 2;
        return glm::vec2(uv[k], uv[k + 1]);
    };
    g->m_lookupSlope = glm::mat2(uvAt(kLookupSize - 1, 0) - uvAt(0, 0), uvAt(0, kLookupSize - 1) - uvAt(0, 0));
    g->m_localToImage = gl::Texture::create(GL_TEXTURE_2D);
    glTextureStorage2D(g->m_localToImage.id(), 1, GL_RG32F, kLookupSize, kLookupSize);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTextureSubImage2D(g->m_localToImage.id(), 0, 0, 0, kLookupSize, kLookupSize, GL_RG, GL_FLOAT, uv.data());
    glTextureParameteri(g->m_localToImage.id(), GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTextureParameteri(g->m_localToImage.id(), GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTextureParameteri(g->m_localToImage.id(), GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTextureParameteri(g->m_localToImage.id(), GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);

    // The vertices of a piece of w × h cells: its grid positions in cells, x fastest (aGrid).
    auto gridVertices = [](int w, int h) {
        std::vector<float> v;
        for (int y = 0; y <= h; ++y)
            for (int x = 0; x <= w; ++x) {
                v.push_back(float(x));
                v.push_back(float(y));
            }
        return v;
    };
    auto upload = [](Mesh& m, const std::vector<float>& v, const std::vector<std::uint32_t>& idx) {
        m.vertices = gl::Buffer::create();
        m.indices = gl::Buffer::create();
        m.vao = gl::VertexArray::create();
        glNamedBufferStorage(m.vertices.id(), GLsizeiptr(v.size() * sizeof(float)), v.data(), 0);
        glNamedBufferStorage(m.indices.id(), GLsizeiptr(idx.size() * sizeof(std::uint32_t)), idx.data(), 0);
        m.indexCount = GLsizei(idx.size());
        glVertexArrayVertexBuffer(m.vao.id(), 0, m.vertices.id(), 0, 2 * sizeof(float));
        glVertexArrayElementBuffer(m.vao.id(), m.indices.id());
        glEnableVertexArrayAttrib(m.vao.id(), 0);
        glVertexArrayAttribFormat(m.vao.id(), 0, 2, GL_FLOAT, GL_FALSE, 0);
        glVertexArrayAttribBinding(m.vao.id(), 0, 0);
    };
    // One mesh per piece shape (blocks, fix-ups, trims, the finest level's cross), made up front.
    for (const RingLayout* ring : {&g->m_ring, &g->m_layerRing}) {
    GeometryPlacement probe = placeGeometryLevels(glm::dvec2(0.0), ring->n, 2, 0);
    for (TrimSide tx : {TrimSide::Low, TrimSide::High})
        for (TrimSide ty : {TrimSide::Low, TrimSide::High}) {
            probe.levels[1].trimX = tx;
            probe.levels[1].trimY = ty;
            for (int level : {0, 1})
                for (const GridRect& r : levelPieces(*ring, probe, level)) {
                    const auto key = std::make_pair(r.cellsX(), r.cellsY());
                    if (g->m_meshes.count(key)) continue;
                    upload(g->m_meshes[key], gridVertices(r.cellsX(), r.cellsY()), pieceTriangles(r.cellsX(), r.cellsY()));
                }
        }
    }
    // drawPatches(): every patch shape up to layerPatchCells² cells, the instance buffer as attribute 1.
    g->m_options.layerPatchCells = std::clamp(options.layerPatchCells, 1, g->m_options.layerN - 1);
    g->m_instances = gl::Buffer::create();
    glNamedBufferData(g->m_instances.id(), 16, nullptr, GL_STREAM_DRAW);
    for (int h = 1; h <= g->m_options.layerPatchCells; ++h)
        for (int w = 1; w <= g->m_options.layerPatchCells; ++w) {
            Mesh& m = g->m_patchMeshes[{w, h}];
            upload(m, gridVertices(w, h), pieceTriangles(w, h));
            glVertexArrayVertexBuffer(m.vao.id(), 1, g->m_instances.id(), 0, sizeof(glm::ivec4));
            glVertexArrayBindingDivisor(m.vao.id(), 1, 1);
            glEnableVertexArrayAttrib(m.vao.id(), 1);
            glVertexArrayAttribIFormat(m.vao.id(), 1, 4, GL_INT, 0);
            glVertexArrayAttribBinding(m.vao.id(), 1, 1);
        }
    return g;
}

ClipmapFrameStats GeometryClipmapGL::update(const Camera& camera, int viewportHeight) {
    const double unit = std::ldexp(1.0, -m_subLevels); // DEM samples per placement unit
    const glm::dvec2 viewer = m_grid.sampleCoords({camera.position.x, camera.position.y}) / unit;
    const double above = camera.position.z - m_scene->terrainHeight(camera.position.x, camera.position.y);
    const double pixelsPerRadian = double(viewportHeight) / (2.0 * std::tan(camera.fovYDeg * M_PI / 360.0));
    const int finest = finestActiveLevel(m_levels, cellMetres(0), above, pixelsPerRadian);
    m_placement = placeGeometryLevels(viewer, m_options.n, m_levels, finest);
    m_layerPlacement = placeGeometryLevels(viewer, m_options.layerN, m_levels, finest);
    if (!m_elevation) return {};
    const int clipLevels = m_elevation->schedule().layout().clipLevels();
    std::vector<glm::dvec2> centres;
    const double half = double(m_options.n - 1) / 2.0;
    for (int l = 0; l < clipLevels; ++l) { // DEM level l is geometry level l + subLevels
        const GeometryLevel& g = m_placement.levels[size_t(std::min(l + m_subLevels, m_levels - 1))];
        centres.push_back((glm::dvec2(g.origin) + half * double(g.cell)) * unit + 0.5);
    }
    return m_elevation->update(centres);
}

ClipmapFrameStats GeometryClipmapGL::completeSynchronously() {
    return m_elevation ? m_elevation->completeSynchronously() : ClipmapFrameStats{};
}

void GeometryClipmapGL::bind(const gl::ShaderProgram& program, int firstUnit) const {
    program.set("uHasElevation", m_elevation ? 1 : 0);
    if (m_elevation) {
        m_elevation->bind(program, firstUnit, "uElev");
        program.set("uElevLevels", int(m_elevationLevelSizes.size()));
        for (size_t k = 0; k < m_elevationLevelSizes.size(); ++k)
            program.set(("uElevLevelSize[" + std::to_string(k) + "]").c_str(), glm::vec2(m_elevationLevelSizes[k]));
    }
    glBindTextureUnit(GLuint(firstUnit + 4), m_localToImage.id());
    program.set("uLocalToImage", firstUnit + 4);
    program.set("uLookupMin", glm::vec2(m_lookupMin));
    program.set("uLookupSize", glm::vec2(m_lookupSize));
    program.set("uLookupTexels", float(kLookupSize));
    program.set("uLookupSlope", m_lookupSlope);
    program.set("uGridOrigin", glm::vec2(m_grid.origin));
    program.set("uGridSpacing", float(m_grid.spacing));
}

void GeometryClipmapGL::drawMesh(const Mesh& mesh, int instances) const {
    glBindVertexArray(mesh.vao.id());
    if (instances == 1) glDrawElements(GL_TRIANGLES, mesh.indexCount, GL_UNSIGNED_INT, nullptr);
    else glDrawElementsInstanced(GL_TRIANGLES, mesh.indexCount, GL_UNSIGNED_INT, nullptr, instances);
}

GeometryFrameStats GeometryClipmapGL::draw(const gl::ShaderProgram& program, const glm::dmat4& viewProj) const {
    return drawPieces(program, viewProj, 0.0, nullptr);
}

GeometryFrameStats GeometryClipmapGL::drawPatches(const gl::ShaderProgram& program, const glm::dmat4& viewProj,
                                                  double lift, const PatchInstances& instances) const {
    return drawPieces(program, viewProj, lift, &instances);
}

GeometryFrameStats GeometryClipmapGL::drawPieces(const gl::ShaderProgram& program, const glm::dmat4& viewProj,
                                                 double lift, const PatchInstances* instances) const {
    GeometryFrameStats st;
    const FrustumPlanes frustum = FrustumPlanes::fromViewProj(viewProj);
    const double s = m_grid.spacing;
    // The terrain's rings, or the coarser ones of the instanced layers.
    const RingLayout& ring = instances ? m_layerRing : m_ring;
    const GeometryPlacement& placement = instances ? m_layerPlacement : m_placement;
    const int n = ring.n;
    program.set("uHalfCells", float(n - 1) / 2.0f);
    program.set("uTransitionWidth", float(std::max(2, n / 10)));
    const double half = double(n - 1) / 2.0;
    const double unit = std::ldexp(1.0, -m_subLevels); // DEM samples per placement unit (exact in float)
    auto setLevel = [&](int l) {
        const GeometryLevel& g = placement.levels[size_t(l)];
        // The shader works in DEM samples: uLevel is the DEM level (negative below the DEM's resolution).
        program.set("uLevel", l - m_subLevels);
        program.set("uDrawnLevel", l - placement.finest);
        program.set("uLevelOrigin", glm::vec2(glm::dvec2(g.origin) * unit));
        program.set("uCell", float(double(g.cell) * unit));
        program.set("uLevelCentre", glm::vec2((glm::dvec2(g.origin) + half * double(g.cell)) * unit));
        program.set("uBlendToCoarser", m_options.stitchLevels && l + 1 < m_levels ? 1 : 0);
    };
    // drawPatches(): per level and patch shape, the instances (x0, y0, a, b); drawn once all are known, from one
    // buffer.
    struct PatchDraw {
        int level;
        std::pair<int, int> shape;
        std::vector<glm::ivec4> records;
    };
    std::vector<PatchDraw> patchDraws;
    std::vector<glm::ivec2> patchOut;
    for (int l = placement.finest; l < m_levels; ++l) {
        const GeometryLevel& g = placement.levels[size_t(l)];
        if (!instances) setLevel(l);
        bool any = false;
        // Placement units -> local box (j runs south).
        auto box = [&](int x0, int y0, int x1, int y1) {
            return std::pair{m_grid.samplePosition(double(g.origin.x + x0 * g.cell) * unit,
                                                   double(g.origin.y + y1 * g.cell) * unit),
                             m_grid.samplePosition(double(g.origin.x + x1 * g.cell) * unit,
                                                   double(g.origin.y + y0 * g.cell) * unit)};
        };
        // Outside the frustum, or wholly outside the imagery (every fragment there would be discarded).
        // Heights within two of the level's cells of the piece (the coarser level's samples its transition blends
        // towards lie within one coarse cell).
        const double margin = 2.0 * double(g.cell) * unit;
        glm::vec2 hr(0.0f); // the last piece's height range
        const bool stitched = m_options.stitchLevels && l + 1 < m_levels;
        auto visible = [&](int x0, int y0, int x1, int y1) {
            // A piece on the outer edge that starts at an odd vertex reaches one cell past its low side (x - 1 along
            // the rows at y = 0 and n - 1, y - 1 along those columns: that vertex is drawn on the even one before
            // it, terrain_geometry.vert), over its neighbour's cells: it is culled with that cell included.
            const bool onRow = y0 == 0 || y1 == n - 1, onColumn = x0 == 0 || x1 == n - 1;
            if (stitched && onRow && x0 % 2 == 1) --x0;
            if (stitched && onColumn && y0 % 2 == 1) --y0;
            const auto [a, b] = box(x0, y0, x1, y1);
            if (b.x < m_imageryMin.x - s || a.x > m_imageryMax.x + s || b.y < m_imageryMin.y - s ||
                a.y > m_imageryMax.y + s)
                return false;
            hr = m_bounds.range(glm::dvec2(g.origin.x + x0 * g.cell, g.origin.y + y0 * g.cell) * unit - margin,
                                glm::dvec2(g.origin.x + x1 * g.cell, g.origin.y + y1 * g.cell) * unit + margin);
            return !frustum.outside({a.x - s, a.y - s, double(hr.x) - 1.0},
                                    {b.x + s, b.y + s, double(hr.y) + 1.0 + std::max(lift, 0.0)});
        };
        const size_t levelFirstDraw = patchDraws.size();
        for (const GridRect& r : levelPieces(ring, placement, l)) {
            if (!visible(r.x0, r.y0, r.x1, r.y1)) {
                ++st.piecesCulled;
                continue;
            }
            if (instances) {
                // Patches of at most P × P cells, each culled and given its own instances.
                const int P = m_options.layerPatchCells;
                for (int y0 = r.y0; y0 < r.y1; y0 += P)
                    for (int x0 = r.x0; x0 < r.x1; x0 += P) {
                        const int x1 = std::min(x0 + P, r.x1), y1 = std::min(y0 + P, r.y1);
                        if (!visible(x0, y0, x1, y1)) continue;
                        const auto [a, b] = box(x0, y0, x1, y1);
                        patchOut.clear();
                        (*instances)(l, glm::dvec3(a, hr.x), glm::dvec3(b, hr.y), patchOut);
                        if (patchOut.empty()) continue;
                        const std::pair<int, int> shape{x1 - x0, y1 - y0};
                        auto it = std::find_if(patchDraws.begin() + std::ptrdiff_t(levelFirstDraw), patchDraws.end(),
                                               [&](const PatchDraw& d) { return d.shape == shape; });
                        if (it == patchDraws.end()) it = patchDraws.insert(patchDraws.end(), PatchDraw{l, shape, {}});
                        for (const glm::ivec2 v : patchOut) it->records.push_back({x0, y0, v.x, v.y});
                    }
                continue;
            }
            const auto it = m_meshes.find({r.cellsX(), r.cellsY()});
            assert(it != m_meshes.end() && "GeometryClipmapGL: piece shape without a mesh");
            program.set("uPieceOffset", glm::vec2(float(r.x0), float(r.y0)));
            drawMesh(it->second, 1);
            st.triangles += std::int64_t(it->second.indexCount / 3);
            ++st.drawCalls;
            any = true;
        }
        st.levelsDrawn += any ? 1 : 0;
    }
    if (instances && !patchDraws.empty()) {
        // Higher instances first within each draw (stacked layers: the top one first, so early depth tests spare
        // the fragments of lower ones behind its kept ones).
        std::vector<glm::ivec4> all;
        std::vector<GLuint> base;
        for (PatchDraw& d : patchDraws) {
            std::stable_sort(d.records.begin(), d.records.end(),
                             [](const glm::ivec4& p, const glm::ivec4& q) { return p.z > q.z; });
            base.push_back(GLuint(all.size()));
            all.insert(all.end(), d.records.begin(), d.records.end());
        }
        glNamedBufferData(m_instances.id(), GLsizeiptr(all.size() * sizeof(glm::ivec4)), all.data(), GL_STREAM_DRAW);
        int level = -1;
        for (size_t i = 0; i < patchDraws.size(); ++i) {
            const PatchDraw& d = patchDraws[i];
            if (d.level != level) {
                setLevel(d.level);
                level = d.level;
                ++st.levelsDrawn;
            }
            const Mesh& mesh = m_patchMeshes.at(d.shape);
            glBindVertexArray(mesh.vao.id());
            glDrawElementsInstancedBaseInstance(GL_TRIANGLES, mesh.indexCount, GL_UNSIGNED_INT, nullptr,
                                                GLsizei(d.records.size()), base[i]);
            st.triangles += std::int64_t(mesh.indexCount / 3) * std::int64_t(d.records.size());
            ++st.drawCalls;
        }
    }
    glBindVertexArray(0);
    return st;
}

} // namespace seasonview
