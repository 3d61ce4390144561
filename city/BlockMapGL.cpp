#include "BlockMapGL.h"

#include "TerrainMeshGL.h" // kNearPlane

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <string>

namespace seasonview::city {

namespace {

// Tiles per side of a layer: a layer of up to 1024² texels (16² maps of the usual 64²).
int tilesPerSide(int n) { return std::clamp(1024 / std::max(n, 1), 1, 16); }

gl::Texture arrayTexture(GLenum internalFormat, int side, int layers) {
    gl::Texture t = gl::Texture::create(GL_TEXTURE_2D_ARRAY);
    glTextureStorage3D(t.id(), 1, internalFormat, side, side, layers);
    glTextureParameteri(t.id(), GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTextureParameteri(t.id(), GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    return t;
}

// One instance record (common_blockmap.glsl's BmMap, std430).
struct Record {
    float geo[4];
    float z[4];
    std::int32_t tile[4];
    std::int32_t wall[4];
    float source[4];
};
static_assert(sizeof(Record) == 80);

} // namespace

Result<gl::ShaderProgram> BlockMapPoolGL::buildProgram(bool roofImagery, bool frontFaces) {
    std::vector<std::string> defines;
    if (roofImagery) defines.push_back("ROOF_IMAGERY");
    if (frontFaces) defines.push_back("FRONT_FACES");
    return gl::ShaderProgram::build("blockmap.vert", "blockmap.frag", defines);
}

BlockMapPoolGL::BlockMapPoolGL(int mapSize)
    : m_size(mapSize), m_tilesPerSide(tilesPerSide(mapSize)), m_instances(gl::Buffer::create()),
      m_vao(gl::VertexArray::create()) {}

Status BlockMapPoolGL::growLayers(int layers) {
    GLint maxLayers = 0;
    glGetIntegerv(GL_MAX_ARRAY_TEXTURE_LAYERS, &maxLayers);
    if (layers > maxLayers)
        return Error{"BlockMaps: " + std::to_string(std::int64_t(layers) * m_tilesPerSide * m_tilesPerSide) +
                     " maps resident at once do not fit this GL's " + std::to_string(maxLayers) + " texture layers"};
    const int side = m_tilesPerSide * m_size;
    gl::Texture texels = arrayTexture(GL_RGBA8UI, side, layers), columns = arrayTexture(GL_R32UI, side, layers);
    if (m_layers > 0) {
        glCopyImageSubData(m_texels.id(), GL_TEXTURE_2D_ARRAY, 0, 0, 0, 0, texels.id(), GL_TEXTURE_2D_ARRAY, 0, 0, 0, 0,
                           side, side, m_layers);
        glCopyImageSubData(m_columns.id(), GL_TEXTURE_2D_ARRAY, 0, 0, 0, 0, columns.id(), GL_TEXTURE_2D_ARRAY, 0, 0, 0,
                           0, side, side, m_layers);
    }
    m_texels = std::move(texels);
    m_columns = std::move(columns);
    m_layers = layers;
    return Ok{};
}

Status BlockMapPoolGL::repackWords(std::size_t capacity) {
    GLint maxTexels = 0;
    glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &maxTexels);
    if (capacity > std::size_t(maxTexels))
        return Error{"BlockMaps: " + std::to_string(capacity) + " words of walls resident at once do not fit this GL's " +
                     std::to_string(maxTexels) + "-texel texture buffers"};
    // The live maps' words copied one after another to the new buffer's start: no free range left between them.
    gl::Buffer buffer = gl::Buffer::create();
    glNamedBufferData(buffer.id(), GLsizeiptr(std::max<std::size_t>(capacity, 1) * 4), nullptr, GL_DYNAMIC_DRAW);
    RangeAllocator ranges(capacity);
    for (Slot& s : m_slots) {
        if (!s.live || s.wordCount == 0) continue;
        const std::size_t to = *ranges.allocate(s.wordCount); // they fit: capacity >= the words in use
        glCopyNamedBufferSubData(m_wordBuffer.id(), buffer.id(), GLintptr(s.words * 4), GLintptr(to * 4),
                                 GLsizeiptr(s.wordCount * 4));
        s.words = to;
    }
    gl::Texture words = gl::Texture::create(GL_TEXTURE_BUFFER);
    glTextureBuffer(words.id(), GL_R32UI, buffer.id());
    m_wordBuffer = std::move(buffer);
    m_words = std::move(words);
    m_wordRanges = std::move(ranges);
    m_wordCapacity = capacity;
    return Ok{};
}

Result<int> BlockMapPoolGL::add(const BlockMap& map, const BlockMapPacked* packed) {
    if (map.size != m_size)
        return Error{"BlockMaps: a map of " + std::to_string(map.size) + "² texels in a pool of " +
                     std::to_string(m_size) + "² maps"};
    BlockMapPacked own;
    if (!packed) {
        own = packBlockMap(map);
        packed = &own;
    }
    // Its words first: a map that does not fit changes nothing.
    const std::size_t words = packed->words.size();
    std::size_t first = 0;
    if (words > 0) {
        auto r = m_wordRanges.allocate(words);
        if (!r) {
            // No free range holds it: the live words repacked into a buffer an eighth larger than they and it need
            // (the pool's room stays small; each word is copied a few times while the pool grows).
            const std::size_t need = m_wordRanges.used() + words;
            if (auto st = repackWords(std::max<std::size_t>(need + need / 8, kMinWords)); !st) return st.error();
            r = m_wordRanges.allocate(words);
            if (!r) return Error{"BlockMaps: the wall words' pool did not grow"}; // cannot happen
        }
        first = *r;
    }
    int handle;
    if (!m_freeSlots.empty()) {
        handle = m_freeSlots.back();
        m_freeSlots.pop_back();
    } else {
        handle = int(m_slots.size());
        const int perLayer = m_tilesPerSide * m_tilesPerSide;
        if (handle / perLayer >= m_layers) {
            if (auto st = growLayers(m_layers + std::max(1, m_layers / 4)); !st) {
                if (words > 0) m_wordRanges.release(first, words);
                return st.error();
            }
        }
        m_slots.emplace_back();
    }
    Slot& s = m_slots[std::size_t(handle)];
    s.live = true;
    s.origin = map.origin;
    s.texel = map.texel;
    s.zBase = map.zBase;
    s.zTop = map.zTop;
    s.wallTexels = map.wallTexels;
    s.span = packed->span;
    s.columns = map.columns();
    s.words = first;
    s.wordCount = words;
    ++m_live;
    const glm::ivec3 tile = tileOf(handle);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTextureSubImage3D(m_texels.id(), 0, tile.x, tile.y, tile.z, m_size, m_size, 1, GL_RGBA_INTEGER, GL_UNSIGNED_BYTE,
                        packed->texels.data());
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTextureSubImage3D(m_columns.id(), 0, tile.x, tile.y, tile.z, m_size, m_size, 1, GL_RED_INTEGER, GL_UNSIGNED_INT,
                        map.column.data());
    if (words > 0)
        glNamedBufferSubData(m_wordBuffer.id(), GLintptr(first * 4), GLsizeiptr(words * 4), packed->words.data());
    return handle;
}

void BlockMapPoolGL::remove(int handle) {
    if (handle < 0 || std::size_t(handle) >= m_slots.size() || !m_slots[std::size_t(handle)].live) return;
    Slot& s = m_slots[std::size_t(handle)];
    if (s.wordCount > 0) m_wordRanges.release(s.words, s.wordCount);
    s = Slot{};
    m_freeSlots.push_back(handle);
    --m_live;
    // Mostly free (maps evicted): repacked into less, as add() sizes it.
    const std::size_t used = m_wordRanges.used(), fit = std::max<std::size_t>(used + used / 8, kMinWords);
    if (used < m_wordCapacity / 2 && fit < m_wordCapacity) (void)repackWords(fit); // smaller: cannot fail
}

glm::dvec3 BlockMapPoolGL::boxMin(int handle) const {
    const Slot& s = m_slots[std::size_t(handle)];
    return {s.origin, s.zBase};
}

glm::dvec3 BlockMapPoolGL::boxMax(int handle) const {
    const Slot& s = m_slots[std::size_t(handle)];
    return {s.origin + double(m_size) * s.texel, s.zTop};
}

bool BlockMapPoolGL::needsBackFaces(int handle, const glm::dvec3& eye, double margin) const {
    const glm::dvec3 lo = boxMin(handle) - margin, hi = boxMax(handle) + margin;
    return eye.x >= lo.x && eye.x <= hi.x && eye.y >= lo.y && eye.y <= hi.y && eye.z >= lo.z && eye.z <= hi.z;
}

glm::ivec3 BlockMapPoolGL::tileOf(int handle) const {
    const int perLayer = m_tilesPerSide * m_tilesPerSide, t = handle % perLayer;
    return {(t % m_tilesPerSide) * m_size, (t / m_tilesPerSide) * m_size, handle / perLayer};
}

std::uint64_t BlockMapPoolGL::allocatedBytes() const {
    const auto side = std::uint64_t(m_tilesPerSide) * std::uint64_t(m_size);
    return side * side * 8 * std::uint64_t(m_layers) + std::uint64_t(m_wordCapacity) * 4;
}

void BlockMapPoolGL::setInstances(const std::vector<Instance>& instances) {
    std::vector<Record> records(std::max<std::size_t>(instances.size(), 1), Record{});
    for (std::size_t i = 0; i < instances.size(); ++i) {
        const int h = instances[i].handle;
        const Slot& s = m_slots[std::size_t(h)];
        const glm::ivec3 tile = tileOf(h);
        Record& r = records[i];
        r = Record{{float(s.origin.x), float(s.origin.y), float(s.texel), float(s.zBase)},
                   {float(s.zTop), 0.0f, 0.0f, 0.0f},
                   {tile.x, tile.y, tile.z, std::int32_t(s.words)},
                   {s.wallTexels, s.span, s.columns, 0},
                   {instances[i].sourceColour.r, instances[i].sourceColour.g, instances[i].sourceColour.b,
                    instances[i].sourceColour.a}};
    }
    // A new store each frame: the GL need not wait for the last frame's draws to read the old one.
    glNamedBufferData(m_instances.id(), GLsizeiptr(records.size() * sizeof(Record)), records.data(), GL_STREAM_DRAW);
}

void BlockMapPoolGL::begin(const gl::ShaderProgram& p, const glm::dmat4& viewProj, const glm::dvec3& eye,
                           double pixelAngle, const DrawSettings& s, bool frontFaces) const {
    p.set("uPixelAngle", float(pixelAngle));
    p.set("uViewProj", glm::mat4(viewProj));
    p.set("uEye", glm::vec3(eye));
    p.set("uRoofColour", s.roofColour);
    p.set("uSunDir", glm::vec3(glm::normalize(glm::dvec3(-0.5, 0.6, 0.75))));
    p.set("uOutputKind", s.outputKind ? 1 : 0);
    p.set("uBmSize", m_size);
    p.set("uBmTexels", kUnit);
    p.set("uBmColumn", kUnit + 1);
    p.set("uBmWords", kUnit + 2);
    p.use();
    glBindTextureUnit(GLuint(kUnit), m_texels.id());
    glBindTextureUnit(GLuint(kUnit + 1), m_columns.id());
    glBindTextureUnit(GLuint(kUnit + 2), m_words.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, m_instances.id());
    glBindVertexArray(m_vao.id());
    glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE); // reversed Z in [0, 1]: gl_FragDepth is the hit's clip z / w
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_GREATER);
    glEnable(GL_CULL_FACE);
    // One fragment per pixel either way: the front faces (the eye outside), or the back faces (inside it or not).
    glCullFace(frontFaces ? GL_BACK : GL_FRONT);
}

void BlockMapPoolGL::draw(const gl::ShaderProgram& p, int first, int count) const {
    if (count <= 0) return;
    p.set("uFirstInstance", first);
    glDrawArraysInstanced(GL_TRIANGLES, 0, 36, count);
}

void BlockMapPoolGL::end() {
    glBindVertexArray(0);
    glDisable(GL_CULL_FACE);
    glCullFace(GL_BACK);
    for (int i = 0; i < kTextures; ++i) glBindTextureUnit(GLuint(kUnit + i), 0);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, 0);
}

Result<std::unique_ptr<BlockMapGL>> BlockMapGL::create(const BlockMap& map) {
    auto program = BlockMapPoolGL::buildProgram(false);
    if (!program) return program.error();
    std::unique_ptr<BlockMapGL> b(new BlockMapGL());
    b->m_program = std::move(*program);
    b->m_pool = std::make_unique<BlockMapPoolGL>(map.size);
    auto h = b->m_pool->add(map);
    if (!h) return h.error();
    b->m_pool->setInstances({BlockMapPoolGL::Instance{*h, glm::vec4(0.0f)}});
    return b;
}

int BlockMapGL::draw(const Camera& camera, const gl::RenderTarget& target, const DrawSettings& s) const {
    target.bind();
    const double aspect = double(target.width()) / double(target.height());
    const double pixelAngle = 2.0 * std::tan(camera.fovYDeg * M_PI / 360.0) / double(target.height());
    m_pool->begin(m_program, camera.projectionMatrix(aspect, kNearPlane) * camera.viewMatrix(), camera.position,
                  pixelAngle, s);
    m_pool->draw(m_program, 0, 1);
    BlockMapPoolGL::end();
    return 1;
}

} // namespace seasonview::city
