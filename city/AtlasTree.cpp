#include "AtlasTree.h"

#include "AtlasCodec.h"
#include "AtlasTreeIo.h"

#include <libdeflate.h>

#include <cstring>
#include <fstream>

namespace seasonview::city {

namespace {
// Fuzz builds skip the checksums (CMakeLists.txt), so that mutated files reach the index parser and the decoders.
#ifdef FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION
constexpr bool kCheckCrc = false;
#else
constexpr bool kCheckCrc = true;
#endif
} // namespace

namespace {

class Writer {
public:
    std::vector<std::uint8_t> bytes;
    template <typename T> void pod(const T& v) {
        const auto* p = reinterpret_cast<const std::uint8_t*>(&v);
        bytes.insert(bytes.end(), p, p + sizeof(T));
    }
    void str(const std::string& s) {
        pod(std::uint32_t(s.size()));
        bytes.insert(bytes.end(), s.begin(), s.end());
    }
    template <typename T> void vec(const std::vector<T>& v) {
        pod(std::uint64_t(v.size()));
        const auto* p = reinterpret_cast<const std::uint8_t*>(v.data());
        bytes.insert(bytes.end(), p, p + v.size() * sizeof(T));
    }
};

class Reader {
public:
    Reader(const std::vector<std::uint8_t>& b) : m_b(b) {}
    bool ok = true;
    template <typename T> T pod() {
        T v{};
        if (m_pos + sizeof(T) > m_b.size()) {
            ok = false;
            return v;
        }
        std::memcpy(&v, &m_b[m_pos], sizeof(T));
        m_pos += sizeof(T);
        return v;
    }
    std::string str() {
        const auto n = pod<std::uint32_t>();
        if (!ok || m_pos + n > m_b.size()) {
            ok = false;
            return {};
        }
        std::string s(reinterpret_cast<const char*>(&m_b[m_pos]), n);
        m_pos += n;
        return s;
    }
    template <typename T> std::vector<T> vec() {
        const auto n = pod<std::uint64_t>();
        if (!ok || n > (m_b.size() - m_pos) / sizeof(T)) {
            ok = false;
            return {};
        }
        std::vector<T> v(n);
        if (n > 0) std::memcpy(v.data(), &m_b[m_pos], n * sizeof(T)); // an empty vector's data() may be null
        m_pos += n * sizeof(T);
        return v;
    }

private:
    const std::vector<std::uint8_t>& m_b;
    std::size_t m_pos = 0;
};

constexpr char kMagic[8] = {'S', 'V', 'A', 'T', 'L', 'A', 'S', '\0'};

} // namespace

namespace detail {

std::vector<std::uint8_t> serializeIndex(const AtlasTreeFile& f) {
    Writer w;
    const auto& i = f.info;
    w.pod(std::int32_t(i.atlasSize));
    w.pod(std::int32_t(i.border));
    w.pod(i.dmin);
    w.pod(i.tpp);
    w.pod(std::int32_t(i.screenWidth));
    w.pod(i.fovXDeg);
    w.pod(std::uint32_t(i.format));
    w.str(i.crs.identifier());
    w.pod(i.origin);
    w.pod(std::uint8_t(i.sceneFrame));
    w.str(i.source);
    w.pod(std::uint64_t(f.textures.size()));
    for (std::size_t t = 0; t < f.textures.size(); ++t) {
        w.str(f.textures[t].path);
        w.pod(std::uint8_t(f.textures[t].repeat));
        w.pod(std::int32_t(f.textureChannels[t]));
        w.pod(f.textureSizes[t]);
    }
    w.pod(std::uint32_t(f.trees.size()));
    for (const auto& tree : f.trees) {
        w.pod(std::uint8_t(tree.alpha));
        w.pod(std::uint64_t(tree.nodes.size()));
        for (const auto& n : tree.nodes) {
            w.pod(n.boundsMin);
            w.pod(n.boundsMax);
            w.pod(n.minDistance);
            w.pod(n.level);
            w.pod(n.parent);
            w.pod(n.children);
            w.pod(n.first);
            w.pod(n.count);
            w.pod(n.atlasOffset);
            w.pod(n.atlasBytes);
            w.pod(n.atlasCrc);
            w.vec(n.textures);
            w.pod(n.textureBytes);
        }
        w.vec(tree.vertices);
        w.vec(tree.triangleTexture);
        w.vec(tree.triangleBuilding);
    }
    w.vec(f.plain.positions);
    w.vec(f.plain.surface);
    w.vec(f.plain.building);
    return w.bytes;
}

std::vector<std::uint8_t> fileHeader(std::uint64_t indexOffset, std::uint64_t indexBytes, std::uint32_t indexCrc) {
    Writer w;
    for (char c : kMagic) w.pod(c);
    w.pod(AtlasTreeFile::kVersion);
    w.pod(indexCrc);
    w.pod(indexOffset);
    w.pod(indexBytes);
    return w.bytes;
}

} // namespace detail

Result<AtlasTreeFile> AtlasTreeFile::open(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return fileError(path, "cannot open atlas tree");
    in.seekg(0, std::ios::end);
    const auto fileSize = std::uint64_t(in.tellg());
    in.seekg(0);
    std::vector<std::uint8_t> head(detail::kHeaderBytes);
    if (fileSize < head.size() || !in.read(reinterpret_cast<char*>(head.data()), std::streamsize(head.size())))
        return fileError(path, "truncated atlas tree (no header)");
    if (std::memcmp(head.data(), kMagic, sizeof kMagic) != 0) return fileError(path, "not a seasonview atlas tree");
    Reader h(head);
    for (int k = 0; k < 8; ++k) (void)h.pod<char>();
    const auto version = h.pod<std::uint32_t>();
    const auto indexCrc = h.pod<std::uint32_t>();
    const auto indexOffset = h.pod<std::uint64_t>(), indexBytes = h.pod<std::uint64_t>();
    if (version != kVersion)
        return fileError(path, "atlas tree version " + std::to_string(version) + ", this seasonview reads " +
                                   std::to_string(kVersion) + " (rebuild it with `seasonview atlas build`)");
    if (indexOffset < head.size() || indexOffset + indexBytes != fileSize)
        return fileError(path, "truncated atlas tree (index missing)");
    std::vector<std::uint8_t> index(indexBytes);
    in.seekg(std::streamoff(indexOffset));
    if (!in.read(reinterpret_cast<char*>(index.data()), std::streamsize(index.size())))
        return fileError(path, "truncated atlas tree (index)");
    if (kCheckCrc && std::uint32_t(libdeflate_crc32(0, index.data(), index.size())) != indexCrc)
        return fileError(path, "corrupt atlas tree index (checksum)");

    AtlasTreeFile f;
    f.path = path;
    Reader r(index);
    auto& i = f.info;
    i.atlasSize = r.pod<std::int32_t>();
    i.border = r.pod<std::int32_t>();
    i.dmin = r.pod<double>();
    i.tpp = r.pod<double>();
    i.screenWidth = r.pod<std::int32_t>();
    i.fovXDeg = r.pod<double>();
    i.format = AtlasFormat(r.pod<std::uint32_t>());
    const std::string crsText = r.str();
    i.origin = r.pod<glm::dvec2>();
    i.sceneFrame = r.pod<std::uint8_t>() != 0;
    i.source = r.str();
    if (!i.sceneFrame) {
        auto crs = Crs::fromUserInput(crsText);
        if (!crs) return fileError(path, "atlas tree's CRS: " + crs.message());
        i.crs = *crs;
    }
    const auto nt = r.pod<std::uint64_t>();
    for (std::uint64_t t = 0; r.ok && t < nt; ++t) {
        CityTexture ct;
        ct.path = r.str();
        ct.repeat = r.pod<std::uint8_t>() != 0;
        ct.channels = r.pod<std::int32_t>();
        f.textures.push_back(ct);
        f.textureChannels.push_back(ct.channels);
        f.textureSizes.push_back(r.pod<glm::ivec2>());
    }
    const auto trees = r.pod<std::uint32_t>();
    for (std::uint32_t t = 0; r.ok && t < trees && t < 2; ++t) {
        AtlasTreeData tree;
        tree.alpha = r.pod<std::uint8_t>() != 0;
        const auto nn = r.pod<std::uint64_t>();
        for (std::uint64_t k = 0; r.ok && k < nn; ++k) {
            AtlasNode n;
            n.boundsMin = r.pod<glm::vec3>();
            n.boundsMax = r.pod<glm::vec3>();
            n.minDistance = r.pod<float>();
            n.level = r.pod<std::int32_t>();
            n.parent = r.pod<std::int32_t>();
            n.children = r.pod<std::array<std::int32_t, 4>>();
            n.first = r.pod<std::uint32_t>();
            n.count = r.pod<std::uint32_t>();
            n.atlasOffset = r.pod<std::uint64_t>();
            n.atlasBytes = r.pod<std::uint64_t>();
            n.atlasCrc = r.pod<std::uint32_t>();
            n.textures = r.vec<std::uint32_t>();
            n.textureBytes = r.pod<std::uint64_t>();
            tree.nodes.push_back(std::move(n));
        }
        tree.vertices = r.vec<TreeVertex>();
        tree.triangleTexture = r.vec<std::uint32_t>();
        tree.triangleBuilding = r.vec<std::uint32_t>();
        f.trees.push_back(std::move(tree));
    }
    f.plain.positions = r.vec<glm::vec3>();
    f.plain.surface = r.vec<Surface>();
    f.plain.building = r.vec<std::uint32_t>();
    if (!r.ok || f.plain.building.size() != f.plain.surface.size() || f.plain.positions.size() != 3 * f.plain.surface.size()) return fileError(path, "corrupt atlas tree index");
    // Consistency: ranges inside the triangle list, children inside the node list, atlases inside the file.
    for (const auto& tree : f.trees) {
        const std::uint64_t tris = tree.vertices.size() / 3;
        if (tree.nodes.empty() || tree.triangleTexture.size() != tris) return fileError(path, "corrupt atlas tree index");
        for (const auto& n : tree.nodes) {
            // Written so that no sum can wrap: a damaged index may hold any 64-bit value.
            if (std::uint64_t(n.first) + n.count > tris || n.atlasBytes > indexOffset ||
                n.atlasOffset > indexOffset - n.atlasBytes)
                return fileError(path, "corrupt atlas tree index");
            for (int c : n.children)
                if (c >= int(tree.nodes.size())) return fileError(path, "corrupt atlas tree index");
        }
        for (auto t : tree.triangleTexture)
            if (t >= f.textures.size()) return fileError(path, "corrupt atlas tree index");
    }
    // Atlases are decoded whole (atlasSize² RGBA): a size past what `atlas build` writes is damage.
    if (i.atlasSize < 4 || i.atlasSize > 16384 || (i.atlasSize & (i.atlasSize - 1)) != 0)
        return fileError(path, "corrupt atlas tree index");
    return f;
}

Result<std::vector<std::uint8_t>> AtlasTreeFile::readAtlasBlob(int tree, int node) const {
    const AtlasNode& n = trees[std::size_t(tree)].nodes[std::size_t(node)];
    std::vector<std::uint8_t> blob(n.atlasBytes);
    if (n.atlasBytes == 0) return blob;
    std::ifstream in(path, std::ios::binary);
    in.seekg(std::streamoff(n.atlasOffset));
    if (!in || !in.read(reinterpret_cast<char*>(blob.data()), std::streamsize(blob.size())))
        return fileError(path, "cannot read atlas of node " + std::to_string(node) + " (file changed or truncated?)");
    if (kCheckCrc && std::uint32_t(libdeflate_crc32(0, blob.data(), blob.size())) != n.atlasCrc)
        return fileError(path, "corrupt atlas of node " + std::to_string(node) + " (checksum)");
    return blob;
}

Result<std::vector<std::uint8_t>> AtlasTreeFile::readAtlasRgba(int tree, int node) const {
    auto blob = readAtlasBlob(tree, node);
    if (!blob) return blob.error();
    const bool alpha = trees[std::size_t(tree)].alpha;
    if (blob->empty()) return std::vector<std::uint8_t>(std::size_t(info.atlasSize) * std::size_t(info.atlasSize) * 4, 0);
    auto rgba = decodeAtlasRgba(info.format, alpha, *blob, info.atlasSize);
    if (rgba.empty()) return fileError(path, "corrupt atlas of node " + std::to_string(node));
    return rgba;
}

CityModel modelOfTree(const AtlasTreeFile& f) {
    CityModel m;
    m.source = f.path;
    m.crs = f.info.crs;
    m.origin = f.info.origin;
    m.sceneFrame = true;
    m.textures = f.textures;
    for (std::size_t t = 0; t < m.textures.size() && t < f.textureSizes.size(); ++t) {
        m.textures[t].width = f.textureSizes[t].x;
        m.textures[t].height = f.textureSizes[t].y;
    }
    m.buildingIds = {"city"};
    for (const AtlasTreeData& tree : f.trees)
        for (std::size_t i = 0; i + 2 < tree.vertices.size(); i += 3) {
            TexturedTriangle t;
            for (std::size_t k = 0; k < 3; ++k) {
                t.v[k] = glm::dvec3(tree.vertices[i + k].position);
                t.t[k] = glm::dvec2(tree.vertices[i + k].uv);
            }
            t.texture = int(tree.triangleTexture[i / 3]);
            m.triangles.push_back(t);
            m.building.push_back(0);
            m.surface.push_back(Surface::Wall);
        }
    for (std::size_t i = 0; i < f.plain.surface.size(); ++i) {
        TexturedTriangle t;
        for (std::size_t k = 0; k < 3; ++k) t.v[k] = glm::dvec3(f.plain.positions[i * 3 + k]);
        t.texture = -1;
        m.triangles.push_back(t);
        m.building.push_back(0);
        m.surface.push_back(f.plain.surface[i]);
    }
    // The file keeps no buildings: its triangles joined by shared corners are one (BlockMaps take a texel's walls
    // and feet from the buildings over it).
    labelConnectedBuildings(m);
    return m;
}

} // namespace seasonview::city
