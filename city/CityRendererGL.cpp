#include "CityRendererGL.h"

#include "AtlasCodec.h"
#include "GeoFrame.h"
#include "TerrainMeshGL.h"
#include "gl/GlContext.h"

#include <epoxy/gl.h>
#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <chrono>
#include <limits>
#include <thread>

namespace seasonview::city {

std::optional<CityMode> parseCityMode(const std::string& name) {
    if (name == "atlas") return CityMode::Atlas;
    if (name == "original") return CityMode::Original;
    if (name == "flat") return CityMode::Flat;
    if (name == "blockmap") return CityMode::BlockMap;
    return std::nullopt;
}

const char* cityModeName(CityMode m) {
    switch (m) {
    case CityMode::Atlas: return "atlas";
    case CityMode::Original: return "original";
    case CityMode::Flat: return "flat";
    case CityMode::BlockMap: return "blockmap";
    }
    return "?";
}

std::optional<MapOcclusion> parseMapOcclusion(const std::string& name) {
    if (name == "auto") return MapOcclusion::Auto;
    if (name == "conditional") return MapOcclusion::Conditional;
    if (name == "readback") return MapOcclusion::Readback;
    return std::nullopt;
}

const char* mapOcclusionName(MapOcclusion m) {
    switch (m) {
    case MapOcclusion::Auto: return "auto";
    case MapOcclusion::Conditional: return "conditional";
    case MapOcclusion::Readback: return "readback";
    }
    return "?";
}

CityView cityViewFor(const ImagerySettings& s) {
    CityView r;
    switch (s.view) {
    case ImageryView::LeafOff: r.season = 1; break;
    case ImageryView::Blend: r.blend = std::clamp(s.blend, 0.0f, 1.0f); break;
    case ImageryView::Swipe: r.swipe = std::clamp(s.swipe, 0.0f, 1.0f); break;
    case ImageryView::Canopy: r.season = std::clamp(s.groundElsewhere, 0, 1); break; // a roof is no tree's ground
    case ImageryView::Relief: r.imagery = false; break;
    case ImageryView::Levels: r.sources = true; break;
    default: break;
    }
    return r;
}

std::optional<AtlasUpload> parseAtlasUpload(const std::string& name) {
    if (name == "auto") return AtlasUpload::Auto;
    if (name == "compressed") return AtlasUpload::Compressed;
    if (name == "decoded") return AtlasUpload::Decoded;
    return std::nullopt;
}

const char* atlasUploadName(AtlasUpload u) {
    switch (u) {
    case AtlasUpload::Auto: return "auto";
    case AtlasUpload::Compressed: return "compressed";
    case AtlasUpload::Decoded: return "decoded";
    }
    return "?";
}

namespace {

constexpr glm::vec3 kPlainColour{0.72f, 0.70f, 0.66f};
constexpr glm::vec3 kRoofColour{0.55f, 0.35f, 0.30f};
// A BlockMap's box is tested for occlusion (a query, then a draw of its own) only where the eye is less than this
// many times the horizontal distance to it above its top (tan 20°): at street level the far blocks behind the near
// buildings; seen from higher up the maps are one instanced draw.
constexpr double kOcclusionSlope = 0.364;

void setVertexLayout(GLuint vao, GLuint vbo, bool tree) {
    const GLsizei stride = tree ? GLsizei(sizeof(TreeVertex)) : GLsizei(sizeof(glm::vec3));
    glVertexArrayVertexBuffer(vao, 0, vbo, 0, stride);
    glEnableVertexArrayAttrib(vao, 0);
    glVertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(vao, 0, 0);
    if (!tree) return;
    glEnableVertexArrayAttrib(vao, 1);
    glVertexArrayAttribFormat(vao, 1, 2, GL_FLOAT, GL_FALSE, GLuint(offsetof(TreeVertex, uv)));
    glVertexArrayAttribBinding(vao, 1, 0);
    glEnableVertexArrayAttrib(vao, 2);
    glVertexArrayAttribFormat(vao, 2, 2, GL_FLOAT, GL_FALSE, GLuint(offsetof(TreeVertex, root)));
    glVertexArrayAttribBinding(vao, 2, 0);
}

} // namespace

CityRendererGL::~CityRendererGL() = default;

std::size_t CityRendererGL::triangles() const {
    std::size_t n = m_plainRoofs + m_plainOthers;
    for (const auto& t : m_file.trees) n += t.vertices.size() / 3;
    return n;
}

// Into the scene's frame: point by point when the tree has its own CRS, then (`placeOnTerrain`) each building onto the
// DEM; then every node's bounds there (every node is a contiguous range, §4.8.1). A tree in the scene's frame already
// is left as it is.
void placeInSceneFrame(const Scene& scene, AtlasTreeFile& f, bool placeOnTerrain) {
    if (f.info.sceneFrame) return;
    const GeoFrame from(f.info.crs, f.info.origin);
    const bool translate = scene.frame.isTranslation() && f.info.crs == scene.frame.crs();
    const glm::dvec2 shift = translate ? f.info.origin - scene.frame.centre() : glm::dvec2(0.0);
    auto move = [&](glm::vec3& p) {
        if (translate) {
            p.x = float(double(p.x) + shift.x);
            p.y = float(double(p.y) + shift.y);
        } else {
            const glm::dvec3 l = scene.frame.toLocal(f.info.crs, from.fromLocal(f.info.crs, glm::dvec2(p)), double(p.z));
            p.x = float(l.x);
            p.y = float(l.y);
        }
    };
    for (auto& t : f.trees)
        for (auto& v : t.vertices) move(v.position);
    for (auto& p : f.plain.positions) move(p);
    if (placeOnTerrain && scene.elevation) {
        // Each building's lowest vertex onto the lowest ground under its vertices (CityModel.h's placeOnTerrain).
        std::map<std::uint32_t, std::pair<double, double>> lowest; // building -> (lowest z, lowest ground)
        auto see = [&](std::uint32_t b, const glm::vec3& p) {
            auto& lg = lowest.try_emplace(b, 1e30, 1e30).first->second;
            lg.first = std::min(lg.first, double(p.z));
            lg.second = std::min(lg.second, scene.terrainHeight(p.x, p.y));
        };
        for (const auto& t : f.trees)
            for (std::size_t i = 0; i < t.vertices.size(); ++i) see(t.triangleBuilding[i / 3], t.vertices[i].position);
        for (std::size_t i = 0; i < f.plain.positions.size(); ++i) see(f.plain.building[i / 3], f.plain.positions[i]);
        auto dz = [&](std::uint32_t b) { return float(lowest.at(b).second - lowest.at(b).first); };
        for (auto& t : f.trees)
            for (std::size_t i = 0; i < t.vertices.size(); ++i) t.vertices[i].position.z += dz(t.triangleBuilding[i / 3]);
        for (std::size_t i = 0; i < f.plain.positions.size(); ++i) f.plain.positions[i].z += dz(f.plain.building[i / 3]);
    }
    for (auto& t : f.trees)
        for (auto& n : t.nodes) {
            if (n.count == 0) continue;
            glm::vec3 lo(std::numeric_limits<float>::max()), hi(std::numeric_limits<float>::lowest());
            for (std::size_t v = std::size_t(n.first) * 3; v < std::size_t(n.first + n.count) * 3; ++v) {
                lo = glm::min(lo, t.vertices[v].position);
                hi = glm::max(hi, t.vertices[v].position);
            }
            n.boundsMin = lo;
            n.boundsMax = hi;
        }
}


Result<std::unique_ptr<CityRendererGL>> CityRendererGL::create(const Scene& scene, const std::string& treePath,
                                                               const CitySettings& settings) {
    auto file = AtlasTreeFile::open(treePath);
    if (!file) return file.error();
    std::unique_ptr<CityRendererGL> r(new CityRendererGL());
    r->m_file = std::move(*file);
    r->m_settings = settings;
    r->m_seasonsComplete = scene.leafon.direct && scene.leafoff.direct; // as the terrain's programs take it
    placeInSceneFrame(scene, r->m_file, settings.placeOnTerrain);
    if (auto st = r->buildPrograms(); !st) return st.error();
    if (settings.mode == CityMode::BlockMap)
        if (auto st = r->openBlockMaps(); !st) return st.error();
    r->createGeometry();
    r->createSamplers();
    if (auto st = r->createPagers(treePath); !st) return st.error();
    return r;
}

std::vector<std::string> CityRendererGL::roofDefines(int variant) const {
    std::vector<std::string> d;
    if (variant == 1) d.push_back("ROOF_BLEND");
    if (m_seasonsComplete) d.push_back("SEASONS_COMPLETE");
    return d;
}

int CityRendererGL::roofVariant() const {
    return m_settings.view.swipe < 0.0f && m_settings.view.blend >= 0.0f ? 1 : 0; // setRoofImagery's uBlend, uSwipeX
}

Status CityRendererGL::buildPrograms() {
    auto build = [](std::vector<std::string> defines) {
        return gl::ShaderProgram::build("city_building.vert", "city_building.frag", defines);
    };
    for (auto [prog, variant] : {std::pair{&m_atlasProgram, "ATLAS"}, {&m_originalProgram, "ORIGINAL"},
                                 {&m_flatProgram, "FLAT"}, {&m_plainProgram, "PLAIN"}}) {
        auto p = build({variant});
        if (!p) return p.error();
        *prog = std::move(*p);
    }
    for (int v = 0; v < 2; ++v) {
        std::vector<std::string> d = roofDefines(v);
        d.push_back("ROOF");
        auto p = build(d);
        if (!p) return p.error();
        m_roofPrograms[v] = std::move(*p);
    }
    auto box = gl::ShaderProgram::build("city_box.vert", "city_box.frag");
    if (!box) return box.error();
    m_boxProgram = std::move(*box);
    const bool s3tc = epoxy_has_gl_extension("GL_EXT_texture_compression_s3tc");
    const bool software = gl::currentIsSoftwareRenderer();
    m_decodeBc = m_file.info.format == AtlasFormat::Bc &&
                 (!s3tc || m_settings.upload == AtlasUpload::Decoded ||
                  (m_settings.upload == AtlasUpload::Auto && software));
    m_software = software;
    return Ok{};
}

void CityRendererGL::createGeometry() {
    const AtlasTreeFile& f = m_file;
    // Geometry: one vertex buffer per tree (§4.8.1 order), one for the plain triangles (roofs first).
    for (const auto& t : f.trees) {
        gl::Buffer vbo = gl::Buffer::create();
        glNamedBufferStorage(vbo.id(), GLsizeiptr(std::max<std::size_t>(t.vertices.size(), 1) * sizeof(TreeVertex)),
                             t.vertices.empty() ? nullptr : t.vertices.data(), 0);
        gl::VertexArray vao = gl::VertexArray::create();
        setVertexLayout(vao.id(), vbo.id(), true);
        m_vbo.push_back(std::move(vbo));
        m_vao.push_back(std::move(vao));
        m_traversals.push_back(std::make_unique<AtlasTraversal>(t, f.info));
        m_atlases.emplace_back();
    }
    std::vector<glm::vec3> plain;
    std::vector<std::uint32_t> passTriangles[2];
    for (std::size_t i = 0; i < f.plain.surface.size(); ++i)
        passTriangles[f.plain.surface[i] == Surface::Roof ? 0 : 1].push_back(std::uint32_t(i));
    for (int pass = 0; pass < 2; ++pass) {
        std::vector<std::uint32_t>& tris = passTriangles[pass];
        if (m_bmTree) {
            // Blockmap mode: in the maps' quadtree order, so what the polygons draw near the eye is a few ranges.
            std::vector<std::pair<glm::dvec2, glm::dvec2>> boxes;
            for (std::uint32_t i : tris) {
                const glm::vec3 a = f.plain.positions[i * 3], b = f.plain.positions[i * 3 + 1], c = f.plain.positions[i * 3 + 2];
                boxes.emplace_back(glm::dvec2(glm::min(a, glm::min(b, c))), glm::dvec2(glm::max(a, glm::max(b, c))));
            }
            BlockMapTriangleOrder& order = pass == 0 ? m_bmRoofOrder : m_bmOtherOrder;
            order = BlockMapTriangleOrder::of(*m_bmTree, boxes);
            std::vector<std::uint32_t> ordered;
            for (std::uint32_t k : order.order) ordered.push_back(tris[k]);
            tris = std::move(ordered);
        }
        for (std::uint32_t i : tris)
            for (int k = 0; k < 3; ++k) plain.push_back(f.plain.positions[i * 3 + std::size_t(k)]);
        (pass == 0 ? m_plainRoofs : m_plainOthers) = tris.size();
    }
    m_plainVbo = gl::Buffer::create();
    glNamedBufferStorage(m_plainVbo.id(), GLsizeiptr(std::max<std::size_t>(plain.size(), 1) * sizeof(glm::vec3)),
                         plain.empty() ? nullptr : plain.data(), 0);
    m_plainVao = gl::VertexArray::create();
    setVertexLayout(m_plainVao.id(), m_plainVbo.id(), false);
    // Occlusion-query boxes: the unit cube, 12 triangles.
    std::vector<glm::vec3> corners;
    for (int i = 0; i < 8; ++i) corners.emplace_back(float(i & 1), float((i >> 1) & 1), float((i >> 2) & 1));
    const std::uint8_t faces[36] = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                                    2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
    m_boxVbo = gl::Buffer::create();
    glNamedBufferStorage(m_boxVbo.id(), GLsizeiptr(corners.size() * sizeof(glm::vec3)), corners.data(), 0);
    m_boxIbo = gl::Buffer::create();
    glNamedBufferStorage(m_boxIbo.id(), sizeof faces, faces, 0);
    m_boxVao = gl::VertexArray::create();
    setVertexLayout(m_boxVao.id(), m_boxVbo.id(), false);
    glVertexArrayElementBuffer(m_boxVao.id(), m_boxIbo.id());
    for (const auto& t : f.trees) m_occlusion.push_back(std::make_unique<NodeOcclusion>(t));
}

void CityRendererGL::createSamplers() {
    // Samplers: atlases trilinear within their mip chain (clamped: fract() keeps coordinates inside), originals
    // repeated or clamped as their model says.
    m_atlasSampler = gl::Sampler::create();
    m_repeatSampler = gl::Sampler::create();
    m_clampSampler = gl::Sampler::create();
    for (GLuint s : {m_atlasSampler.id(), m_repeatSampler.id(), m_clampSampler.id()}) {
        glSamplerParameteri(s, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
        glSamplerParameteri(s, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
        glSamplerParameterf(s, GL_TEXTURE_MAX_ANISOTROPY, std::clamp(m_settings.anisotropy, 1.0f, 16.0f));
    }
    for (GLuint s : {m_atlasSampler.id(), m_clampSampler.id()}) {
        glSamplerParameteri(s, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
        glSamplerParameteri(s, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    }
    glSamplerParameteri(m_repeatSampler.id(), GL_TEXTURE_WRAP_S, GL_REPEAT);
    glSamplerParameteri(m_repeatSampler.id(), GL_TEXTURE_WRAP_T, GL_REPEAT);

    // The flat mode's one dummy texture: 64² of light grey with a faint grid (so it is still a texture fetch).
    std::vector<std::uint8_t> px(64 * 64 * 4);
    for (int y = 0; y < 64; ++y)
        for (int x = 0; x < 64; ++x) {
            const std::uint8_t v = (x % 16 == 0 || y % 16 == 0) ? 150 : 190;
            std::uint8_t* p = &px[std::size_t(y * 64 + x) * 4];
            p[0] = p[1] = p[2] = v;
            p[3] = 255;
        }
    m_dummy = gl::Texture::create(GL_TEXTURE_2D);
    glTextureStorage2D(m_dummy.id(), 7, GL_RGBA8, 64, 64);
    glTextureSubImage2D(m_dummy.id(), 0, 0, 0, 64, 64, GL_RGBA, GL_UNSIGNED_BYTE, px.data());
    glGenerateTextureMipmap(m_dummy.id());
}

// Pagers: one per tree (its atlases and the originals of its leaves); the capacity is shared in proportion to the
// trees' atlas bytes. Original mode pages originals only.
Status CityRendererGL::createPagers(const std::string& treePath) {
    const AtlasTreeFile& f = m_file;
    PagerSettings ps;
    ps.threaded = m_settings.threaded;
    ps.decodedAtlases = m_decodeBc;
    ps.uploadBytesPerFrame = m_settings.uploadBytesPerFrame;
    if (m_settings.mode == CityMode::Original && !f.trees.empty()) {
        ps.capacityBytes = m_settings.capacityBytes;
        ps.queueLength = 32;
        m_originalPager = std::make_unique<AtlasPager>(m_file, 0, ps);
        return Ok{};
    }
    if (m_settings.mode != CityMode::Atlas && m_settings.mode != CityMode::BlockMap) return Ok{};
    std::vector<std::uint64_t> share;
    std::uint64_t total = 0;
    for (const auto& t : f.trees) {
        std::uint64_t b = 0;
        for (const auto& n : t.nodes) b += n.atlasBytes + n.textureBytes;
        share.push_back(std::max<std::uint64_t>(b, 1));
        total += share.back();
    }
    for (std::size_t t = 0; t < f.trees.size(); ++t) {
        ps.capacityBytes = f.trees.size() == 1 ? m_settings.capacityBytes
                                               : std::max<std::uint64_t>(m_settings.capacityBytes * share[t] / total, 1);
        PagerSettings tps = ps;
        if (t == 0 && m_bmFile) {
            tps.blockMaps = m_bmFile.get(); // the maps share the first tree's pager
            tps.queueLength = 32;           // and its loader: maps are small and many change per frame as the eye climbs
        }
        m_pagers.push_back(std::make_unique<AtlasPager>(m_file, int(t), tps));
        // Every frame draws at least the root's atlas (the coarsest, never a missing texture): a capacity that
        // cannot hold it would leave the whole tree undrawn.
        const auto& nodes = f.trees[t].nodes;
        if (nodes.empty() || nodes[0].atlasBytes == 0) continue;
        const std::uint64_t root = m_pagers.back()->blockBytes({BlockKey::Kind::Atlas, 0});
        if (root <= ps.capacityBytes) continue;
        char msg[256];
        std::snprintf(msg, sizeof msg,
                      ": the city capacity (%.1f MB for this tree) cannot hold its root atlas (%.1f MB%s): "
                      "raise --city-capacity to at least %.0f MB",
                      double(ps.capacityBytes) / 1e6, double(root) / 1e6, ps.decodedAtlases ? ", decoded" : "",
                      std::ceil(double(root) * double(total) / double(share[t]) / 1e6));
        return Error{treePath + (f.trees[t].alpha ? " (RGBA tree)" : " (RGB tree)") + msg};
    }
    return Ok{};
}

AtlasView CityRendererGL::view(const Camera& camera, int width, int height) const {
    AtlasView v;
    v.eye = camera.position;
    const double aspect = double(width) / double(height);
    v.viewProj = camera.projectionMatrix(aspect, kNearPlane) * camera.viewMatrix();
    v.screenWidth = width;
    v.fovXDeg = 2.0 * std::atan(std::tan(camera.fovYDeg * M_PI / 360.0) * aspect) * 180.0 / M_PI;
    v.tpp = m_settings.tpp;
    return v;
}

void CityRendererGL::uploadAtlas(int tree, const LoadedBlock& b) {
    const bool alpha = m_file.trees[std::size_t(tree)].alpha;
    const int size = m_file.info.atlasSize, levels = atlasLevels(size);
    const AtlasFormat format = m_file.info.format;
    gl::Texture tex = gl::Texture::create(GL_TEXTURE_2D);
    const bool native = format == AtlasFormat::Bc && !m_decodeBc;
    const GLenum internal = native ? (alpha ? GL_COMPRESSED_RGBA_S3TC_DXT5_EXT : GL_COMPRESSED_RGB_S3TC_DXT1_EXT)
                                   : (alpha ? GL_RGBA8 : GL_RGB8);
    glTextureStorage2D(tex.id(), levels, internal, size, size);
    glTextureParameteri(tex.id(), GL_TEXTURE_MAX_LEVEL, levels - 1);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    for (int l = 0; l < levels; ++l) {
        const int s = std::max(4, size >> l);
        const auto data = atlasLevelData(format, alpha, b.data, size, l);
        if (data.empty()) {
            // Never drawn (the node stays out of m_atlases); said by readError().
            if (m_uploadError.empty())
                m_uploadError = m_file.path + ": corrupt atlas of node " + std::to_string(b.key.index) + " (tree " +
                                std::to_string(tree) + ", level " + std::to_string(l) + " does not decode)";
            glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
            return;
        }
        if (native) {
            glCompressedTextureSubImage2D(tex.id(), l, 0, 0, s, s, internal, GLsizei(data.size()), data.data());
        } else if (format == AtlasFormat::Bc) {
            const auto rgba = decodeBc(data.data(), s, alpha);
            glTextureSubImage2D(tex.id(), l, 0, 0, s, s, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
        } else {
            glTextureSubImage2D(tex.id(), l, 0, 0, s, s, alpha ? GL_RGBA : GL_RGB, GL_UNSIGNED_BYTE, data.data());
        }
    }
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    m_atlases[std::size_t(tree)][b.key.index] = std::move(tex);
}

std::string CityRendererGL::readError() const {
    if (!m_uploadError.empty()) return m_uploadError;
    for (const auto& p : m_pagers)
        if (std::string e = p->error(); !e.empty()) return e;
    return m_originalPager ? m_originalPager->error() : std::string();
}

void CityRendererGL::uploadMips(const gl::Texture& tex, const LoadedBlock& b) {
    glm::ivec2 s = b.size;
    for (std::size_t i = 0; i < b.mips.size(); ++i) {
        s = glm::max(s / 2, glm::ivec2(1));
        const int rows = int(b.mips[i].size() / (std::size_t(s.x) * 4));
        if (rows > 0)
            glTextureSubImage2D(tex.id(), int(i) + 1, 0, b.mipFirstRows[i], s.x, rows, GL_RGBA, GL_UNSIGNED_BYTE,
                                b.mips[i].data());
    }
}

void CityRendererGL::uploadTexture(const LoadedBlock& b) {
    auto allocate = [&] {
        gl::Texture tex = gl::Texture::create(GL_TEXTURE_2D);
        int levels = 1;
        while ((std::max(b.size.x, b.size.y) >> levels) > 0) ++levels;
        glTextureStorage2D(tex.id(), levels, GL_RGBA8, b.size.x, b.size.y);
        return tex;
    };
    const bool whole = b.parts <= 1;
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    if (whole) {
        gl::Texture tex = allocate();
        glTextureSubImage2D(tex.id(), 0, 0, 0, b.size.x, b.size.y, GL_RGBA, GL_UNSIGNED_BYTE, b.data.data());
        uploadMips(tex, b);
        if (b.mips.empty()) glGenerateTextureMipmap(tex.id()); // a custom loader's texture
        m_textures[b.key.index] = std::move(tex);
    } else {
        // One band of rows (and its rows of every mip level) into the texture the earlier parts went to; drawn once
        // the last part is in.
        auto [it, fresh] = m_partialTextures.try_emplace(b.key.index);
        PartialTexture& p = it->second;
        if (fresh) {
            p.texture = allocate();
            p.total = b.parts;
        }
        glTextureSubImage2D(p.texture.id(), 0, 0, b.firstRow, b.size.x, b.rows, GL_RGBA, GL_UNSIGNED_BYTE, b.data.data());
        uploadMips(p.texture, b);
        p.parts.insert(b.key.part);
        if (int(p.parts.size()) == p.total) {
            if (b.mips.empty()) glGenerateTextureMipmap(p.texture.id()); // a custom loader's bands
            m_textures[b.key.index] = std::move(p.texture);
            m_partialTextures.erase(it);
        }
    }
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
}

void CityRendererGL::apply(int tree, AtlasPager::Frame&& frame) {
    const auto t0 = std::chrono::steady_clock::now();
    m_frameEvicted += frame.evict.size();
    for (const auto& k : frame.evict) {
        if (k.kind == BlockKey::Kind::BlockMap) {
            if (auto it = m_blockMaps.find(k.index); it != m_blockMaps.end()) {
                m_bmPool->remove(it->second);
                m_blockMaps.erase(it);
            }
            continue;
        }
        if (k.kind == BlockKey::Kind::Atlas) {
            m_atlases[std::size_t(tree)].erase(k.index);
            continue;
        }
        const AtlasPager& pager = m_originalPager ? *m_originalPager : *m_pagers[std::size_t(tree)];
        const int parts = pager.textureParts(k.index);
        auto whole = m_textures.find(k.index);
        if (parts <= 1) {
            if (whole != m_textures.end()) m_textures.erase(whole);
            continue;
        }
        // One part of a split texture gone: the texture is unusable until that part is back; its other rows stay.
        if (whole != m_textures.end()) {
            PartialTexture& p = m_partialTextures[k.index];
            p.texture = std::move(whole->second);
            p.total = parts;
            for (int q = 0; q < parts; ++q) p.parts.insert(std::uint16_t(q));
            m_textures.erase(whole);
        }
        if (auto it = m_partialTextures.find(k.index); it != m_partialTextures.end()) {
            it->second.parts.erase(k.part);
            if (it->second.parts.empty()) m_partialTextures.erase(it);
        }
    }
    if (m_bmPool && tree == 0 && !m_pagers.empty()) {
        // The maps' pool grows its free room only within the capacity of their pager (the first tree's) less what
        // else the city holds there once this frame's other blocks are up (the first tree's atlases, every original
        // texture); the pager counts the maps alone (each in whole pages).
        std::uint64_t others = 0;
        std::size_t pagesComing = 0, mapsComing = 0;
        if (!m_atlases.empty())
            for (const auto& [node, tex] : m_atlases[0]) others += m_pagers[0]->blockBytes({BlockKey::Kind::Atlas, node});
        for (const auto& [i, tex] : m_textures) others += m_pagers[0]->textureBytes(i);
        for (const auto& [i, p] : m_partialTextures) others += m_pagers[0]->textureBytes(i);
        for (const auto& b : frame.upload) {
            if (b.key.kind != BlockKey::Kind::BlockMap) others += b.bytes;
            else if (b.blockMapPacked) {
                pagesComing += blockMapPages(b.blockMapPacked->words.size());
                ++mapsComing;
            }
        }
        const std::uint64_t capacity = m_pagers[0]->capacityBytes();
        if (auto st = m_bmPool->prepare(capacity > others ? capacity - others : 0, pagesComing, mapsComing);
            !st && m_uploadError.empty())
            m_uploadError = m_bmFile->path().string() + ": " + st.message();
    }
    for (const auto& b : frame.upload) {
        if (b.key.kind == BlockKey::Kind::BlockMap) {
            auto g = b.blockMap ? m_bmPool->add(*b.blockMap, b.blockMapPacked.get()) : Result<int>(Error{"no map"});
            if (g) m_blockMaps[b.key.index] = *g;
            else if (m_uploadError.empty()) m_uploadError = m_bmFile->path().string() + ": BlockMap " +
                                                            std::to_string(b.key.index) + ": " + g.message();
        } else if (b.key.kind == BlockKey::Kind::Atlas) uploadAtlas(tree, b);
        else uploadTexture(b);
        m_frameUploaded += b.bytes;
    }
    m_frameUploadMs += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void CityRendererGL::resetOcclusion() {
    for (auto& o : m_occlusion) o->reset();
    m_frameEndQueries.clear(); // their query objects are begun anew, which discards the answers
    m_queriesUsed = 0;
}

void CityRendererGL::collectQueries(bool wait) {
    if (m_frameEndQueries.empty()) return;
    if (!wait)
        for (const PendingQuery& q : m_frameEndQueries) { // only when all are in: the pager never waits for the GPU
            GLuint available = 0;
            glGetQueryObjectuiv(m_queries[q.query].id(), GL_QUERY_RESULT_AVAILABLE, &available);
            if (!available) return;
        }
    for (const PendingQuery& q : m_frameEndQueries) {
        GLuint any = 0;
        glGetQueryObjectuiv(m_queries[q.query].id(), GL_QUERY_RESULT, &any);
        m_occlusion[q.tree]->answered(q.node, any != 0, q.frame);
    }
    m_frameEndQueries.clear();
    m_queriesUsed = 0;
}

void CityRendererGL::queryBoxes(std::size_t tree, const std::vector<std::uint32_t>& nodes, const glm::mat4& viewProj,
                                std::vector<PendingQuery>& out) {
    if (nodes.empty()) return;
    GLboolean colourMask[4] = {GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE}, depthMask = GL_TRUE;
    GLint depthFunc = GL_GREATER;
    glGetBooleanv(GL_COLOR_WRITEMASK, colourMask);
    glGetBooleanv(GL_DEPTH_WRITEMASK, &depthMask);
    glGetIntegerv(GL_DEPTH_FUNC, &depthFunc);
    glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
    glDepthMask(GL_FALSE);
    glDepthFunc(GL_GEQUAL); // a face on its box still counts (reversed Z)
    glBindVertexArray(m_boxVao.id());
    m_boxProgram.set("uViewProj", viewProj);
    m_boxProgram.use();
    for (std::uint32_t n : nodes) {
        const auto [lo, hi] = m_occlusion[tree]->queryBox(n);
        m_boxProgram.set("uBoxMin", lo);
        m_boxProgram.set("uBoxMax", hi);
        if (m_queriesUsed == m_queries.size()) m_queries.push_back(gl::Query::create(GL_ANY_SAMPLES_PASSED_CONSERVATIVE));
        const std::size_t q = m_queriesUsed++;
        glBeginQuery(GL_ANY_SAMPLES_PASSED_CONSERVATIVE, m_queries[q].id());
        glDrawElements(GL_TRIANGLES, 36, GL_UNSIGNED_BYTE, nullptr);
        glEndQuery(GL_ANY_SAMPLES_PASSED_CONSERVATIVE);
        out.push_back(PendingQuery{tree, n, q, m_occlusion[tree]->frame()});
    }
    glColorMask(colourMask[0], colourMask[1], colourMask[2], colourMask[3]);
    glDepthMask(depthMask);
    glDepthFunc(GLenum(depthFunc));
}

void CityRendererGL::update(const Camera& camera, int width, int height) {
    if (m_settings.flushFirst) glFlush();
    ++m_frame;
    m_frameUploaded = 0;
    m_frameEvicted = 0;
    m_frameUploadMs = 0;
    const AtlasView v = view(camera, width, height);
    if (m_settings.mode == CityMode::Atlas || m_settings.mode == CityMode::BlockMap) {
        collectQueries(false); // the pager uses the answers if they are in, else the frame before's
        // Blockmap mode: the maps of the cut the view wants are asked for, and the atlases of what the maps drawn now
        // (those resident, or standing in) do not cover: a map still loading leaves its buildings to the polygons,
        // which are then drawn with the atlases the atlas mode would draw them with as those arrive (the pager loads
        // coarser blocks first), not with the root's alone. Once the maps are in, those atlases leave the ideal set.
        const BlockMapCut ideal = blockMapsOn() ? blockMapCut(v, true) : BlockMapCut{};
        const BlockMapCut drawn = blockMapsOn() ? blockMapCut(v, false) : BlockMapCut{};
        coverWith(blockMapsOn() ? &drawn : nullptr);
        // Nodes the last frame found hidden are paged as if outside the frustum.
        for (std::size_t t = 0; t < m_pagers.size(); ++t) {
            VisibilityFn vis;
            if (m_settings.occlusion) vis = [o = m_occlusion[t].get()](std::uint32_t n) { return o->forPaging(n); };
            auto req = m_traversals[t]->requests(v, vis);
            if (t == 0) req = requestsWithBlockMaps(std::move(req), v, ideal);
            apply(int(t), m_pagers[t]->update(req));
        }
        coverWith(nullptr);
    } else if (m_originalPager) {
        // The originals of every visible leaf, nearest first.
        std::vector<BlockRequest> req;
        std::map<std::uint32_t, double> nearest;
        for (const auto& trav : m_traversals)
            for (std::uint32_t n = 0; n < trav->tree().nodes.size(); ++n) {
                const AtlasNode& node = trav->tree().nodes[n];
                if (!node.leaf() || !trav->visible(n, v)) continue;
                const double d = trav->distance(n, v);
                for (auto t : node.textures) {
                    auto [it, fresh] = nearest.try_emplace(t, d);
                    if (!fresh) it->second = std::min(it->second, d);
                }
            }
        for (auto [t, d] : nearest) req.push_back(BlockRequest{{BlockKey::Kind::Texture, t}, BlockCategory::Needed, d, 0});
        std::sort(req.begin(), req.end());
        apply(0, m_originalPager->update(req));
    }
}

void CityRendererGL::complete(const Camera& camera, int width, int height) {
    const AtlasView v = view(camera, width, height);
    if (m_settings.mode == CityMode::Atlas || m_settings.mode == CityMode::BlockMap) {
        const BlockMapCut ideal = blockMapsOn() ? blockMapCut(v, true) : BlockMapCut{};
        coverWith(blockMapsOn() ? &ideal : nullptr);
        for (std::size_t t = 0; t < m_pagers.size(); ++t) {
            auto req = m_traversals[t]->requests(v);
            if (t == 0) req = requestsWithBlockMaps(std::move(req), v, ideal);
            apply(int(t), m_pagers[t]->complete(req));
        }
        coverWith(nullptr);
    } else if (m_originalPager) {
        update(camera, width, height);
        for (int i = 0; i < 100000 && (m_originalPager->stats().idealMissing > 0 || m_originalPager->stats().queued > 0); ++i) {
            if (m_settings.threaded) std::this_thread::sleep_for(std::chrono::milliseconds(1));
            update(camera, width, height);
        }
    }
}

// What one draw() shares between its passes: the view, the frame's counters, the texture bound on unit 0.
struct CityRendererGL::DrawState {
    AtlasView v;
    glm::mat4 viewProj;
    glm::vec3 sun;
    CityFrameStats& st;
    GLuint bound = 0;
    std::vector<std::vector<std::uint32_t>> drawnNodes; // per tree: the nodes drawn, for step (3)
    void bindTexture(GLuint id, GLuint sampler) {
        if (id == bound) return;
        glBindTextureUnit(0, id);
        glBindSampler(0, sampler);
        bound = id;
        ++st.textureBinds;
    }
};

// One tree's atlas-mode draw: the program bound last and the atlases drawn (distinct: deferred nodes may share an
// ancestor's stand-in).
struct CityRendererGL::AtlasPass {
    std::size_t tree;
    const gl::ShaderProgram* current = nullptr;
    std::vector<std::uint32_t> atlasesDrawn;
};

CityFrameStats CityRendererGL::draw(const Camera& camera, const ClipmapTerrainRendererGL* terrain,
                                    const gl::RenderTarget& target) {
    CityFrameStats st;
    const auto w0 = std::chrono::steady_clock::now();
    collectQueries(true);
    st.waitMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - w0).count();
    const bool occlusion =
        m_settings.occlusion && (m_settings.mode == CityMode::Atlas || m_settings.mode == CityMode::BlockMap);
    target.bind();
    glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE); // reversed Z, as the terrain draws (BlockMaps write depth in [0, 1])
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_GREATER);
    glDisable(GL_CULL_FACE); // CityGML rings are not reliably oriented
    DrawState ds{view(camera, target.width(), target.height()), glm::mat4(1.0f),
                 glm::vec3(glm::normalize(glm::dvec3(-0.5, 0.6, 0.75))), st, 0, {}};
    ds.viewProj = glm::mat4(ds.v.viewProj);
    ds.drawnNodes.resize(m_file.trees.size());
    // Blockmap mode: the maps resident where the cut wants them; the polygons draw the rest.
    const BlockMapCut cut = blockMapsOn() ? blockMapCut(ds.v, false) : BlockMapCut{};
    if (!m_settings.holdSwitches) m_lastCut = cut;
    coverWith(blockMapsOn() ? &cut : nullptr);
    for (std::size_t t = 0; t < m_file.trees.size(); ++t) {
        const AtlasTreeData& tree = m_file.trees[t];
        if (tree.vertices.empty()) continue;
        glBindVertexArray(m_vao[t].id());
        if (m_settings.mode == CityMode::Flat) drawFlat(t, ds);
        else if (m_settings.mode == CityMode::Original) drawOriginal(t, ds);
        else drawAtlas(t, ds, occlusion);
    }
    if (m_originalPager) {
        st.blocksResident = m_originalPager->stats().residentBlocks;
        st.residentBytes = m_originalPager->stats().residentBytes;
        st.requestedBytes = m_originalPager->stats().requestedBytes;
        st.idealBytes = m_originalPager->stats().idealBytes;
        st.loaderQueue = m_originalPager->stats().queued;
    }
    drawPlain(ds, terrain, target.width(), blockMapsOn() ? &cut : nullptr);
    if (blockMapsOn()) drawBlockMaps(cut, ds, terrain, target.width());
    coverWith(nullptr);
    // (3) The drawn nodes' boxes against the frame's depth, for the next frame.
    if (occlusion) {
        for (std::size_t t = 0; t < ds.drawnNodes.size(); ++t) {
            const std::size_t before = m_frameEndQueries.size();
            queryBoxes(t, m_occlusion[t]->endOfFrameTests(ds.drawnNodes[t], ds.v.eye), ds.viewProj, m_frameEndQueries);
            st.occlusionQueries += int(m_frameEndQueries.size() - before);
        }
    }
    glBindVertexArray(0);
    glBindSampler(0, 0);
    st.uploadedBytes = m_frameUploaded;
    st.uploadMs = m_frameUploadMs;
    st.evictedBlocks = std::size_t(m_frameEvicted);
    st.allocatedBytes = allocatedBytes();
    st.blockMapPoolBytes = m_bmPool ? m_bmPool->allocatedBytes() : 0;
    if (m_bmPool) {
        st.blockMapMovedBytes = m_bmPool->movedBytes() - m_bmMovedReported;
        m_bmMovedReported = m_bmPool->movedBytes();
    }
    return st;
}

// The GPU bytes of the resident atlases and original textures (whole, or allocated whole while their bands arrive:
// the pagers' size of a texture), and of the BlockMaps' pool.
std::uint64_t CityRendererGL::allocatedBytes() const {
    std::uint64_t bytes = 0;
    for (std::size_t t = 0; t < m_atlases.size() && t < m_pagers.size(); ++t)
        for (const auto& [node, tex] : m_atlases[t]) bytes += m_pagers[t]->blockBytes({BlockKey::Kind::Atlas, node});
    if (m_bmPool) bytes += m_bmPool->allocatedBytes(); // the maps' pool, its free room included
    const AtlasPager* pager = m_originalPager ? m_originalPager.get() : m_pagers.empty() ? nullptr : m_pagers[0].get();
    if (pager) {
        for (const auto& [i, tex] : m_textures) bytes += pager->textureBytes(i);
        for (const auto& [i, p] : m_partialTextures) bytes += pager->textureBytes(i);
    }
    return bytes;
}

glm::vec4 CityRendererGL::sourceColour(int source) const {
    if (!m_settings.view.sources) return glm::vec4(0.0f);
    const float* c = kSourceColours[std::clamp(source, 0, 3)];
    return glm::vec4(c[0], c[1], c[2], 1.0f);
}

void CityRendererGL::setBuildingUniforms(const gl::ShaderProgram& p, const DrawState& ds, float alphaCut) const {
    p.set("uSourceColour", sourceColour(&p == &m_originalProgram ? 1 : 0));
    p.set("uViewProj", ds.viewProj);
    p.set("uSunDir", ds.sun);
    p.set("uTexture", 0);
    p.set("uAlphaCut", alphaCut);
    p.set("uMaxAniso", std::clamp(m_settings.anisotropy, 1.0f, 16.0f));
}

// Flat mode: the whole tree in one call with the dummy texture (the upper bound of what texturing can cost).
void CityRendererGL::drawFlat(std::size_t t, DrawState& ds) {
    const AtlasTreeData& tree = m_file.trees[t];
    setBuildingUniforms(m_flatProgram, ds, -1.0f);
    m_flatProgram.use();
    ds.bindTexture(m_dummy.id(), m_repeatSampler.id());
    glDrawArrays(GL_TRIANGLES, 0, GLsizei(tree.vertices.size()));
    ++ds.st.drawCalls;
    ds.st.triangles += std::int64_t(tree.vertices.size() / 3);
}

// Original mode: every visible leaf's runs of one texture with that texture, the conventional way: one bind and one
// call each.
void CityRendererGL::drawOriginal(std::size_t t, DrawState& ds) {
    const AtlasTreeData& tree = m_file.trees[t];
    setBuildingUniforms(m_originalProgram, ds, tree.alpha ? 0.5f : -1.0f);
    m_originalProgram.use();
    const auto& trav = *m_traversals[t];
    for (std::uint32_t n = 0; n < tree.nodes.size(); ++n) {
        const AtlasNode& node = tree.nodes[n];
        if (!node.leaf() || !trav.visible(n, ds.v)) continue;
        for (std::uint32_t i = node.first; i < node.first + node.count;) {
            const std::uint32_t tex = tree.triangleTexture[i];
            std::uint32_t e = i + 1;
            while (e < node.first + node.count && tree.triangleTexture[e] == tex) ++e;
            auto it = m_textures.find(tex);
            if (it != m_textures.end())
                ds.bindTexture(it->second.id(), m_file.textures[tex].repeat ? m_repeatSampler.id() : m_clampSampler.id());
            else {
                ds.bindTexture(m_dummy.id(), m_repeatSampler.id());
                ++ds.st.missingOriginals;
            }
            glDrawArrays(GL_TRIANGLES, GLint(i * 3), GLsizei((e - i) * 3));
            ++ds.st.drawCalls;
            ds.st.triangles += e - i;
            i = e;
        }
    }
}

// One traversal result's draws, each with its atlas or (a leaf nearer than its atlas serves) original texture.
void CityRendererGL::issueDraws(const AtlasTraversalResult& result, AtlasPass& pass, DrawState& ds) {
    const std::size_t t = pass.tree;
    for (const AtlasDraw& d : result.draws)
        if (!d.original) pass.atlasesDrawn.push_back(d.node);
    ds.st.originalLeaves += int(result.originalLeaves);
    ds.st.coarserThanWanted += int(result.coarserThanWanted);
    ds.drawnNodes[t].insert(ds.drawnNodes[t].end(), result.drawn.begin(), result.drawn.end());
    for (const AtlasDraw& d : result.draws) {
        const gl::ShaderProgram& prog = d.original ? m_originalProgram : m_atlasProgram;
        if (&prog != pass.current) {
            prog.use();
            pass.current = &prog;
        }
        if (d.original) {
            auto it = m_textures.find(d.texture);
            if (it == m_textures.end()) continue; // cannot happen: the traversal checked residency
            ds.bindTexture(it->second.id(), m_file.textures[d.texture].repeat ? m_repeatSampler.id() : m_clampSampler.id());
        } else {
            auto it = m_atlases[t].find(d.node);
            if (it == m_atlases[t].end()) continue;
            ds.bindTexture(it->second.id(), m_atlasSampler.id());
            prog.set("uLevelScale", float(std::ldexp(1.0, d.level)));
        }
        glDrawArrays(GL_TRIANGLES, GLint(d.first * 3), GLsizei(d.count * 3));
        ++ds.st.drawCalls;
        ds.st.triangles += d.count;
    }
}

// Atlas mode: the traversal's draws with what the pager made resident; with occlusion culling, (1) what is known
// visible, then (2) the deferred nodes in rounds. Nothing before the root's atlas is resident (the first frames of a
// view that did not complete(); no occlusion answers from an empty picture either).
void CityRendererGL::drawAtlas(std::size_t t, DrawState& ds, bool occlusion) {
    if (!m_atlases[t].count(0)) return;
    const AtlasTreeData& tree = m_file.trees[t];
    AtlasPager& pager = *m_pagers[t];
    const AtlasTraversal& trav = *m_traversals[t];
    const auto atlasResident = [&](std::uint32_t n) { return pager.resident({BlockKey::Kind::Atlas, n}); };
    const auto textureResident = [&](std::uint32_t x) { return pager.textureResident(x); };
    NodeOcclusion& occ = *m_occlusion[t];
    VisibilityFn visibility;
    if (occlusion) {
        occ.beginFrame();
        visibility = [&occ](std::uint32_t n) { return occ.forTraversal(n); };
    }
    for (const gl::ShaderProgram* p : {&m_atlasProgram, &m_originalProgram})
        setBuildingUniforms(*p, ds, tree.alpha ? 0.5f : -1.0f);
    AtlasPass pass{t, nullptr, {}};
    // (1) What is known visible.
    const AtlasTraversalResult known = trav.draws(ds.v, atlasResident, textureResident, visibility);
    if (occlusion) occ.traversed(known);
    issueDraws(known, pass, ds);
    // (2) The deferred nodes, nearest first, in rounds: test the boxes, wait, draw the visible ones.
    std::vector<std::uint32_t> pending = known.deferred;
    const auto distance = [&](std::uint32_t n) { return trav.distance(n, ds.v); };
    for (int grown = 0; !pending.empty();) {
        NodeOcclusion::Round round = occ.nextRound(pending, distance, ds.v.eye, grown);
        std::vector<std::uint32_t>& visibleNow = round.visible;
        std::vector<PendingQuery> queries;
        queryBoxes(t, round.test, ds.viewProj, queries);
        ds.st.occlusionQueries += int(queries.size());
        if (!queries.empty()) ++ds.st.occlusionWaits;
        const auto w0 = std::chrono::steady_clock::now();
        for (const PendingQuery& q : queries) {
            GLuint any = 0;
            glGetQueryObjectuiv(m_queries[q.query].id(), GL_QUERY_RESULT, &any);
            if (any) visibleNow.push_back(q.node);
            else {
                occ.answered(q.node, false, occ.frame());
                ++ds.st.occludedNodes;
            }
        }
        ds.st.waitMs += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - w0).count();
        glBindVertexArray(m_vao[t].id());
        pass.current = nullptr;
        bool drew = false;
        for (std::uint32_t n : visibleNow) {
            occ.foundVisible(n); // against the depth so far: tested again at the end
            const AtlasTraversalResult below = trav.drawsBelow(n, ds.v, atlasResident, textureResident, visibility);
            if (occlusion) occ.traversed(below);
            issueDraws(below, pass, ds);
            drew = drew || !below.drawn.empty();
            pending.insert(pending.end(), below.deferred.begin(), below.deferred.end());
        }
        if (drew) ++grown; // rounds that only open inner nodes keep the batch small
    }
    std::sort(pass.atlasesDrawn.begin(), pass.atlasesDrawn.end());
    ds.st.atlasNodes += int(std::unique(pass.atlasesDrawn.begin(), pass.atlasesDrawn.end()) - pass.atlasesDrawn.begin());
    ds.st.blocksResident += pager.stats().residentBlocks;
    ds.st.residentBytes += pager.stats().residentBytes;
    ds.st.requestedBytes += pager.stats().requestedBytes;
    ds.st.idealBytes += pager.stats().idealBytes;
    ds.st.loaderQueue += pager.stats().queued;
}

// Plain triangles: roofs with the imagery (or one colour), the rest in one colour. Unit 0's sampler object would
// override the clipmap's own filtering.
void CityRendererGL::setRoofImagery(const gl::ShaderProgram& p, const DrawState& ds,
                                    const ClipmapTerrainRendererGL* terrain, int targetWidth) const {
    const CityView& ri = m_settings.view;
    p.set("uSeason", std::clamp(ri.season, 0, 1));
    p.set("uBlend", ri.blend < 0.0f ? -1.0f : std::clamp(ri.blend, 0.0f, 1.0f));
    p.set("uSwipeX", ri.swipe < 0.0f ? -1.0f : std::clamp(ri.swipe, 0.0f, 1.0f) * float(targetWidth));
    p.set("uHasImagery", terrain && ri.imagery ? 1 : 0);
    if (terrain) terrain->bindTerrain(p, ds.v.viewProj);
    else {
        // Nothing to sample, but samplers of two types on one unit (the defaults: all on unit 0) fail the draw.
        p.set("uClip", 12);
        p.set("uCoarse", 13);
        p.set("uClipTags", 11);
        p.set("uLocalToImage", 10);
    }
    p.set("uViewProj", ds.viewProj);
}

void CityRendererGL::drawPlain(DrawState& ds, const ClipmapTerrainRendererGL* terrain, int targetWidth,
                               const BlockMapCut* cut) {
    glBindSampler(0, 0);
    glBindVertexArray(m_plainVao.id());
    // All of them, or (blockmap mode) the ranges the maps do not cover.
    auto drawRanges = [&](std::size_t offset, std::size_t count, const BlockMapTriangleOrder& order) {
        const std::vector<std::pair<std::uint32_t, std::uint32_t>> all{{0u, std::uint32_t(count)}};
        for (const auto& [first, n] : cut ? order.ranges(*cut) : all) {
            glDrawArrays(GL_TRIANGLES, GLint((offset + first) * 3), GLsizei(std::size_t(n) * 3));
            ++ds.st.drawCalls;
            ds.st.triangles += std::int64_t(n);
        }
    };
    if (m_plainRoofs > 0) {
        const gl::ShaderProgram& roof = m_roofPrograms[roofVariant()];
        roof.set("uSunDir", ds.sun);
        roof.set("uPlainColour", kRoofColour);
        roof.set("uAlphaCut", -1.0f);
        roof.set("uSourceColour", sourceColour(2));
        setRoofImagery(roof, ds, terrain, targetWidth);
        roof.use();
        drawRanges(0, m_plainRoofs, m_bmRoofOrder);
        ds.bound = 0;
    }
    if (m_plainOthers > 0) {
        m_plainProgram.set("uViewProj", ds.viewProj);
        m_plainProgram.set("uSunDir", ds.sun);
        m_plainProgram.set("uPlainColour", kPlainColour);
        m_plainProgram.set("uAlphaCut", -1.0f);
        m_plainProgram.set("uSourceColour", sourceColour(2));
        m_plainProgram.use();
        drawRanges(m_plainRoofs, m_plainOthers, m_bmOtherOrder);
    }
}

Status CityRendererGL::openBlockMaps() {
    if (m_settings.blockMaps.empty()) return Error{m_file.path + ": --city blockmap needs the city's BlockMaps (none given)"};
    auto f = BlockMapFile::open(m_settings.blockMaps);
    if (!f) return f.error();
    auto q = BlockMapQuadtree::of(*f);
    if (!q) return q.error();
    if (m_file.trees.empty())
        return Error{m_file.path + ": --city blockmap needs a textured tree to page the maps with (the model has no textures)"};
    m_bmFile = std::make_unique<BlockMapFile>(std::move(*f));
    m_bmTree = std::make_unique<BlockMapQuadtree>(std::move(*q));
    m_bmTraversal = std::make_unique<BlockMapTraversal>(*m_bmTree, m_bmFile->records());
    // One pool holds every resident map, so a frame's maps are a few instanced draws: one map size per file.
    const auto& records = m_bmFile->records();
    for (const BlockMapRecord& r : records)
        if (r.size != records.front().size)
            return Error{m_bmFile->path().string() + ": BlockMaps of " + std::to_string(records.front().size) + "² and " +
                         std::to_string(r.size) + "² texels in one file (seasonview builds one size per city)"};
    m_bmPool = std::make_unique<BlockMapPoolGL>(records.empty() ? 64 : records.front().size);
    for (int v = 0; v < 2; ++v) {
        auto p = BlockMapPoolGL::buildProgram(true, false, roofDefines(v));
        if (!p) return p.error();
        m_bmPrograms[v] = std::move(*p);
        auto front = BlockMapPoolGL::buildProgram(true, true, roofDefines(v));
        if (!front) return front.error();
        m_bmFrontPrograms[v] = std::move(*front);
    }
    return Ok{};
}

BlockMapCut CityRendererGL::blockMapCut(const AtlasView& v, bool ideal) const {
    if (ideal || m_pagers.empty()) return m_bmTraversal->cut(v, m_settings.blockMapErrorPx);
    return m_bmTraversal->cut(v, m_settings.blockMapErrorPx, [this](std::uint32_t k) { return m_blockMaps.count(k) != 0; },
                              m_settings.holdSwitches ? &m_lastCut : nullptr);
}

void CityRendererGL::coverWith(const BlockMapCut* cut) {
    for (auto& t : m_traversals) {
        if (!cut) {
            t->setCovered({});
            continue;
        }
        t->setCovered([this, cut](const glm::dvec3& lo, const glm::dvec3& hi) {
            return std::uint8_t(m_bmTraversal->coverage(*cut, lo, hi));
        });
    }
}

std::vector<BlockRequest> CityRendererGL::requestsWithBlockMaps(std::vector<BlockRequest> req, const AtlasView& v,
                                                                const BlockMapCut& ideal) const {
    if (!blockMapsOn()) return req;
    const auto maps = m_bmTraversal->requests(v, m_settings.blockMapErrorPx, &ideal);
    req.insert(req.end(), maps.begin(), maps.end());
    std::sort(req.begin(), req.end());
    return req;
}

// The maps of the cut over the polygons, writing depth: a few instanced draws of the pool (BlockMapGL.h).
void CityRendererGL::drawBlockMaps(const BlockMapCut& cut, DrawState& ds, const ClipmapTerrainRendererGL* terrain,
                                   int targetWidth) {
    ds.st.blockMapsNotResident = int(cut.notResident);
    if (cut.drawn.empty()) return;
    glBindSampler(0, 0);
    BlockMapPoolGL::DrawSettings s;
    s.roofColour = kRoofColour;
    const double pixelAngle = 2.0 * std::tan(ds.v.fovXDeg * M_PI / 360.0) / double(std::max(ds.v.screenWidth, 1));
    // Three groups, each nearest first (the cut's order): the boxes the eye is well outside of, drawn over their
    // front faces (a hidden face skips the ray cast where the GL can tell) in one draw; those of them seen at a
    // grazing angle, which the near field may hide, each tested first (below) and drawn on its own only where some
    // of it shows; the boxes the eye is in or next to, over their back faces, in one draw.
    std::vector<BlockMapPoolGL::Instance> front, tested, back;
    for (std::uint32_t k : cut.drawn) {
        auto it = m_blockMaps.find(k);
        if (it == m_blockMaps.end()) continue; // cannot happen: the cut checked residency
        BlockMapPoolGL::Instance in{it->second, glm::vec4(0.0f)};
        if (m_settings.view.sources) {
            // Lighter for coarser maps: the finest level's colour at the leaves, towards white at the root.
            const glm::vec4 c = sourceColour(3);
            const float coarser = float(m_bmTree->depth - m_bmTree->nodes[k].level) / float(std::max(m_bmTree->depth, 1));
            in.sourceColour = glm::vec4(glm::mix(glm::vec3(c), glm::vec3(1.0f), 0.75f * coarser), 1.0f);
        }
        if (m_bmPool->needsBackFaces(in.handle, ds.v.eye, 2.0)) {
            back.push_back(in);
            continue;
        }
        // Grazing: the eye less than kOcclusionSlope × the horizontal distance above the box's top. Seen from higher
        // up (an overview), a block's roofs show whatever stands nearer, and a query would only cost a draw.
        const glm::dvec3 lo = m_bmPool->boxMin(in.handle), hi = m_bmPool->boxMax(in.handle);
        const glm::dvec2 nearest = glm::clamp(glm::dvec2(ds.v.eye), glm::dvec2(lo), glm::dvec2(hi));
        const double distance = glm::length(glm::dvec2(ds.v.eye) - nearest);
        const bool grazing = ds.v.eye.z - hi.z < kOcclusionSlope * distance;
        (m_settings.occlusion && grazing ? tested : front).push_back(in);
    }
    // Occlusion: each tested box against the depth drawn so far (the terrain, the near field's polygons) with a
    // query, writing nothing; its map is cast only where some of it shows (MapOcclusion: under conditional rendering,
    // or drawn with the front faces' maps once the answers are read): far maps behind the near buildings cost a box
    // each, not a ray per pixel.
    if (!tested.empty()) {
        GLboolean colourMask[4] = {GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE};
        glGetBooleanv(GL_COLOR_WRITEMASK, colourMask);
        glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
        glDepthMask(GL_FALSE);
        glEnable(GL_DEPTH_TEST);
        glDepthFunc(GL_GEQUAL); // a face on the depth drawn still counts (reversed Z)
        glBindVertexArray(m_boxVao.id());
        m_boxProgram.set("uViewProj", ds.viewProj);
        m_boxProgram.use();
        for (std::size_t q = 0; q < tested.size(); ++q) {
            m_boxProgram.set("uBoxMin", glm::vec3(m_bmPool->boxMin(tested[q].handle)));
            m_boxProgram.set("uBoxMax", glm::vec3(m_bmPool->boxMax(tested[q].handle)));
            if (q == m_bmQueries.size()) m_bmQueries.push_back(gl::Query::create(GL_ANY_SAMPLES_PASSED_CONSERVATIVE));
            glBeginQuery(GL_ANY_SAMPLES_PASSED_CONSERVATIVE, m_bmQueries[q].id());
            glDrawElements(GL_TRIANGLES, 36, GL_UNSIGNED_BYTE, nullptr);
            glEndQuery(GL_ANY_SAMPLES_PASSED_CONSERVATIVE);
        }
        glColorMask(colourMask[0], colourMask[1], colourMask[2], colourMask[3]);
        glDepthMask(GL_TRUE);
        glDepthFunc(GL_GREATER);
        ds.st.occlusionQueries += int(tested.size());
    }
    // The instances: the front group (with readback, the tested maps found visible after it), the conditionally
    // drawn ones, the back group.
    std::vector<BlockMapPoolGL::Instance> all = front;
    int nTested = 0;
    if (mapOcclusionUsed() == MapOcclusion::Readback) {
        const auto w0 = std::chrono::steady_clock::now();
        for (std::size_t q = 0; q < tested.size(); ++q) {
            GLuint any = 0;
            glGetQueryObjectuiv(m_bmQueries[q].id(), GL_QUERY_RESULT, &any);
            if (any) all.push_back(tested[q]);
        }
        ds.st.waitMs += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - w0).count();
        if (!tested.empty()) ++ds.st.occlusionWaits;
    } else {
        all.insert(all.end(), tested.begin(), tested.end());
        nTested = int(tested.size());
    }
    const int nFront = int(all.size()) - nTested, nBack = int(back.size());
    all.insert(all.end(), back.begin(), back.end());
    m_bmPool->setInstances(all);
    const gl::ShaderProgram &frontProgram = m_bmFrontPrograms[roofVariant()], &backProgram = m_bmPrograms[roofVariant()];
    if (nFront + nTested > 0) {
        setRoofImagery(frontProgram, ds, terrain, targetWidth);
        m_bmPool->begin(frontProgram, ds.v.viewProj, ds.v.eye, pixelAngle, s, true);
        if (nFront > 0) ds.st.drawCalls += m_bmPool->draw(frontProgram, 0, nFront);
        for (int q = 0; q < nTested; ++q) {
            glBeginConditionalRender(m_bmQueries[std::size_t(q)].id(), GL_QUERY_WAIT);
            ds.st.drawCalls += m_bmPool->draw(frontProgram, nFront + q, 1);
            glEndConditionalRender();
        }
    }
    if (nBack > 0) {
        setRoofImagery(backProgram, ds, terrain, targetWidth);
        m_bmPool->begin(backProgram, ds.v.viewProj, ds.v.eye, pixelAngle, s, false);
        ds.st.drawCalls += m_bmPool->draw(backProgram, nFront + nTested, nBack);
    }
    const std::size_t maps = front.size() + tested.size() + back.size();
    ds.st.blockMaps += int(maps);
    ds.st.triangles += 12 * std::int64_t(maps);
    BlockMapPoolGL::end();
    glDisable(GL_CULL_FACE);
    ds.bound = 0;
}

} // namespace seasonview::city
