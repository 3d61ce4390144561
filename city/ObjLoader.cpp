// OBJ+MTL through tinyobjloader (double precision, so projected coordinates keep millimetres): each object or
// group is a building, map_Kd its texture, surfaces classified by their normal.
#define TINYOBJLOADER_USE_DOUBLE
#include <tiny_obj_loader.h>

#include "CityLoaders.h"
#include "GeoFrame.h"

#include <glm/common.hpp>

#include <filesystem>
#include <functional>
#include <limits>

namespace seasonview::city::detail {

Result<CityModel> loadObj(const std::string& path, const CityLoadOptions& options) {
    if (!options.localFrame && !options.crs)
        return fileError(path, "OBJ has no CRS; give one (--city-crs EPSG:CODE) or say it is in the scene's frame");
    tinyobj::ObjReaderConfig config;
    config.triangulate = false; // whole polygons: checked for planarity, then ear-clipped (triangulatePolygon)
    config.vertex_color = false;
    tinyobj::ObjReader reader;
    if (!reader.ParseFromFile(path, config))
        return fileError(path, "not a readable OBJ: " + firstLine(reader.Error().empty() ? "parse failed" : reader.Error()));
    const auto& attrib = reader.GetAttrib();
    const auto& shapes = reader.GetShapes();
    const auto& materials = reader.GetMaterials();
    if (attrib.vertices.empty() || shapes.empty()) return fileError(path, "no geometry (no vertices or faces)");

    CityModel model;
    model.source = path;
    model.sceneFrame = options.localFrame;
    if (options.crs) model.crs = *options.crs;
    const auto position = [&](int i) {
        const double x = attrib.vertices[3 * std::size_t(i)], y = attrib.vertices[3 * std::size_t(i) + 1],
                     z = attrib.vertices[3 * std::size_t(i) + 2];
        // OBJ is y-up by convention (-z north); 'z' = already x east, y north, z up.
        return options.objUp == 'z' ? glm::dvec3(x, y, z) : glm::dvec3(x, -z, y);
    };

    glm::dvec2 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
    for (std::size_t i = 0; i < attrib.vertices.size() / 3; ++i) {
        const glm::dvec2 p(position(int(i)));
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    model.origin = options.localFrame ? glm::dvec2(0.0) : 0.5 * (lo + hi);
    std::optional<GeoFrame> frame;
    if (!options.localFrame) frame.emplace(model.crs, model.origin);

    const std::filesystem::path dir = std::filesystem::path(path).parent_path();
    std::map<std::string, int> known;
    std::vector<std::string> missing;
    std::string unreadable;
    std::vector<int> materialTexture(materials.size(), -1);
    std::vector<bool> materialMissing(materials.size(), false);
    for (std::size_t m = 0; m < materials.size(); ++m) {
        if (materials[m].diffuse_texname.empty()) continue;
        const std::filesystem::path t(materials[m].diffuse_texname);
        materialTexture[m] = textureIndex(model, (t.is_absolute() ? t : dir / t).lexically_normal().string(), true,
                                          known, missing, unreadable);
        if (!unreadable.empty()) return Error{unreadable};
        materialMissing[m] = materialTexture[m] < 0;
    }

    // Limits before anything is built from the faces, and indices checked (a cut or edited file may name vertices
    // that do not exist).
    const std::size_t vertexCount = attrib.vertices.size() / 3, uvCount = attrib.texcoords.size() / 2;
    std::size_t faces = 0;
    for (const auto& shape : shapes) {
        faces += shape.mesh.num_face_vertices.size();
        // tinyobjloader stores each face's vertex count in a byte: a face of more lost its count, and the counts
        // no longer add up to the indices.
        std::size_t counted = 0;
        for (const unsigned char n : shape.mesh.num_face_vertices) counted += n;
        if (counted != shape.mesh.indices.size())
            return fileError(path, "a face of more than " + std::to_string(kMaxPolygonVertices) +
                                       " vertices, over the limit of " + std::to_string(kMaxPolygonVertices));
        std::size_t first = 0;
        for (std::size_t f = 0; f < shape.mesh.num_face_vertices.size(); first += shape.mesh.num_face_vertices[f], ++f) {
            const std::size_t n = shape.mesh.num_face_vertices[f];
            for (std::size_t k = 0; k < n; ++k) {
                const auto& idx = shape.mesh.indices[first + k];
                if (idx.vertex_index < 0 || std::size_t(idx.vertex_index) >= vertexCount)
                    return fileError(path, "a face refers to vertex " + std::to_string(idx.vertex_index + 1) +
                                               ", which does not exist (" + std::to_string(vertexCount) + " vertices)");
                if (idx.texcoord_index >= 0 && std::size_t(idx.texcoord_index) >= uvCount)
                    return fileError(path, "a face refers to texture coordinate " +
                                               std::to_string(idx.texcoord_index + 1) + ", which does not exist");
            }
        }
    }
    if (faces > options.maxPolygons)
        return fileError(path, std::to_string(faces) + " faces, over the limit of " + std::to_string(options.maxPolygons));

    PolygonChecks checks;
    std::size_t untexturedByMissing = 0;
    for (const auto& shape : shapes) {
        const auto building = std::uint32_t(model.buildingIds.size());
        model.buildingIds.push_back(shape.name.empty() ? "object" + std::to_string(building) : shape.name);
        const auto& mesh = shape.mesh;
        std::size_t first = 0; // index of the face's first vertex in mesh.indices
        for (std::size_t f = 0; f < mesh.num_face_vertices.size(); first += mesh.num_face_vertices[f], ++f) {
            std::vector<glm::dvec3> verts;
            std::vector<glm::dvec2> uvs;
            bool hasUv = true;
            for (std::size_t k = 0; k < mesh.num_face_vertices[f]; ++k) {
                const auto& idx = mesh.indices[first + k];
                glm::dvec3 p = position(idx.vertex_index);
                if (frame) {
                    const glm::dvec3 l = frame->toLocal(model.crs, glm::dvec2(p), p.z);
                    p = l;
                }
                verts.push_back(p);
                if (idx.texcoord_index < 0) hasUv = false;
                else
                    uvs.emplace_back(attrib.texcoords[2 * std::size_t(idx.texcoord_index)],
                                     attrib.texcoords[2 * std::size_t(idx.texcoord_index) + 1]);
            }
            const int m = f < mesh.material_ids.size() ? mesh.material_ids[f] : -1;
            int texture = m >= 0 && std::size_t(m) < materials.size() ? materialTexture[std::size_t(m)] : -1;
            if (m >= 0 && std::size_t(m) < materials.size() && materialMissing[std::size_t(m)]) ++untexturedByMissing;
            if (!hasUv) {
                texture = -1;
                uvs.clear();
            }
            addPolygon(model, verts, uvs, triangulatePolygon(verts), texture, building, Surface::Other, checks);
        }
    }
    if (model.triangles.empty()) return fileError(path, "no faces with area (all degenerate)");
    checks.addWarnings(model);
    if (!missing.empty())
        model.warnings.push_back(path + ": " + std::to_string(missing.size()) +
                                 " texture file(s) missing (first: " + missing.front() + "); " +
                                 std::to_string(untexturedByMissing) + " face(s) drawn untextured");
    if (!reader.Warning().empty() && missing.empty())
        model.warnings.push_back(path + ": " + firstLine(reader.Warning()));
    return model;
}

} // namespace seasonview::city::detail
