#include "SynthCity.h"

#include "AtomicFile.h"
#include "SynthLayout.h"
#include "SynthParallel.h"
#include "SynthRandom.h"

#include <OpenImageIO/imageio.h>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <stb/stb_easy_font.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <map>
#include <mutex>
#include <optional>

namespace seasonview::synth {

namespace {

using Rgb = std::array<float, 3>;

constexpr int kFacadeBays = 3;       // procedural facades: bays per texture repetition
constexpr float kBayWidth = 3.2f;    // metres

/// Wall colours: plasters (white, cream, ochre, pink, grey) and bricks (red, brown, yellow).
constexpr Rgb kPlasters[] = {{236, 232, 222}, {226, 212, 176}, {214, 178, 120}, {222, 186, 170}, {188, 186, 180},
                             {205, 196, 172}};
constexpr Rgb kBricks[] = {{150, 72, 52}, {122, 70, 52}, {196, 164, 110}};

void fillRect(std::vector<float>& img, int size, int x0, int y0, int x1, int y1, Rgb c) {
    for (int y = std::max(0, y0); y < std::min(size, y1); ++y)
        for (int x = std::max(0, x0); x < std::min(size, x1); ++x)
            for (int k = 0; k < 3; ++k) img[(std::size_t(y) * std::size_t(size) + std::size_t(x)) * 3 + std::size_t(k)] = c[std::size_t(k)];
}

/// The label: the building number in stb_easy_font's strokes, `scale` pixels per font unit, on a light plate.
void stampLabel(std::vector<float>& img, int size, std::uint32_t label) {
    const std::string text = std::to_string(label);
    static thread_local std::vector<char> buffer(20000);
    const int quads = stb_easy_font_print(0, 0, const_cast<char*>(text.c_str()), nullptr, buffer.data(), int(buffer.size()));
    const int scale = std::max(1, size / 128);
    const int x0 = 3 * scale, y0 = 3 * scale;
    const int w = stb_easy_font_width(const_cast<char*>(text.c_str())) * scale;
    fillRect(img, size, x0 - 2 * scale, y0 - 2 * scale, x0 + w + 2 * scale, y0 + 9 * scale, {245, 240, 225});
    for (int q = 0; q < quads; ++q) {
        const float* v0 = reinterpret_cast<const float*>(buffer.data() + q * 64);
        const float* v2 = reinterpret_cast<const float*>(buffer.data() + q * 64 + 32);
        fillRect(img, size, x0 + int(v0[0]) * scale, y0 + int(v0[1]) * scale, x0 + int(v2[0]) * scale,
                 y0 + int(v2[1]) * scale, {30, 30, 36});
    }
}

std::vector<std::uint8_t> toBytes(const std::vector<float>& img) {
    std::vector<std::uint8_t> out(img.size());
    for (std::size_t i = 0; i < img.size(); ++i) out[i] = std::uint8_t(std::clamp(img[i] + 0.5f, 0.0f, 255.0f));
    return out;
}

struct Photo {
    std::vector<std::uint8_t> rgb;
    int w = 0, h = 0;
};

std::optional<Photo> readPhoto(const std::filesystem::path& p) {
    auto in = OIIO::ImageInput::open(p.string());
    if (!in) return std::nullopt;
    Photo ph;
    ph.w = in->spec().width;
    ph.h = in->spec().height;
    const int n = in->spec().nchannels;
    std::vector<std::uint8_t> px(std::size_t(ph.w) * std::size_t(ph.h) * std::size_t(n));
    if (ph.w <= 0 || ph.h <= 0 || !in->read_image(0, 0, 0, n, OIIO::TypeDesc::UINT8, px.data())) return std::nullopt;
    ph.rgb.resize(std::size_t(ph.w) * std::size_t(ph.h) * 3);
    for (std::size_t i = 0; i < std::size_t(ph.w) * std::size_t(ph.h); ++i)
        for (std::size_t k = 0; k < 3; ++k) ph.rgb[i * 3 + k] = px[i * std::size_t(n) + std::min<std::size_t>(k, std::size_t(n - 1))];
    return ph;
}

} // namespace

std::vector<std::uint8_t> facadeTexture(const Building& b, std::uint32_t label, int size,
                                        const std::vector<std::uint8_t>* photo) {
    std::vector<float> img(std::size_t(size) * std::size_t(size) * 3);
    if (photo) {
        // The photo (size² RGB, already resampled) as it is.
        for (std::size_t i = 0; i < img.size(); ++i) img[i] = float((*photo)[i]);
    } else {
        Rng rng(std::uint64_t(b.seed) * 0x9E3779B97F4A7C15ull + 17);
        const bool brick = rng.chance(0.3);
        const Rgb wall = brick ? kBricks[rng.next() % 3] : kPlasters[rng.next() % 6];
        // The texture spans kFacadeBays bays of kBayWidth metres across and the eave height down, floors of
        // about 3 m (writeSynthCity maps it so).
        const int floors = std::max(1, int(std::lround(b.eave / 3.0f)));
        const float cellW = float(size) / float(kFacadeBays), cellH = float(size) / float(floors);
        for (int y = 0; y < size; ++y)
            for (int x = 0; x < size; ++x) {
                const float n = float(hash2(x, y, b.seed) & 255u) / 255.0f - 0.5f;
                const bool mortar = brick && (y % 4 == 0 || (x + ((y / 4) % 2) * 4) % 8 == 0);
                for (int k = 0; k < 3; ++k)
                    img[(std::size_t(y) * std::size_t(size) + std::size_t(x)) * 3 + std::size_t(k)] =
                        (mortar ? 0.8f * wall[std::size_t(k)] + 40.0f : wall[std::size_t(k)]) + 10.0f * n;
            }
        const Rgb frame = rng.chance(0.5) ? Rgb{240, 240, 236} : Rgb{90, 70, 55};
        const Rgb door = Rgb{92, 60, 40};
        const int doorBay = int(rng.next() % std::uint64_t(kFacadeBays));
        for (int f = 0; f < floors; ++f)     // f = 0: the ground floor (bottom rows)
            for (int k = 0; k < kFacadeBays; ++k) {
                const int cx0 = int(float(k) * cellW), cy1 = size - int(float(f) * cellH); // top-down rows
                const bool isDoor = f == 0 && k == doorBay;
                const int w = int(cellW * (isDoor ? 0.38f : 0.46f)), h = int(cellH * (isDoor ? 0.78f : 0.52f));
                const int x0 = cx0 + (int(cellW) - w) / 2;
                const int y1 = isDoor ? cy1 : cy1 - int(cellH * 0.22f), y0 = y1 - h;
                const int fr = std::max(1, size / 128);
                fillRect(img, size, x0 - fr, y0 - fr, x0 + w + fr, y1 + (isDoor ? 0 : fr), frame);
                if (isDoor) {
                    fillRect(img, size, x0, y0, x0 + w, y1, door);
                    continue;
                }
                // Glass: dark, a sky reflection fading downwards, a mullion.
                for (int y = y0; y < y1; ++y) {
                    const float t = float(y - y0) / float(std::max(1, h));
                    fillRect(img, size, x0, y, x0 + w, y + 1, {60 + 70 * (1 - t), 72 + 74 * (1 - t), 86 + 80 * (1 - t)});
                }
                fillRect(img, size, x0 + w / 2 - fr / 2, y0, x0 + w / 2 - fr / 2 + fr, y1, frame);
            }
        // A darker plinth.
        for (int y = size - std::max(2, size / 40); y < size; ++y)
            for (int x = 0; x < size; ++x)
                for (int k = 0; k < 3; ++k) img[(std::size_t(y) * std::size_t(size) + std::size_t(x)) * 3 + std::size_t(k)] *= 0.7f;
    }
    stampLabel(img, size, label);
    return toBytes(img);
}

Result<std::vector<std::filesystem::path>> facadePhotoPool(const std::filesystem::path& folder) {
    std::error_code ec;
    if (!std::filesystem::is_directory(folder, ec)) return fileError(folder.string(), "not a folder of facade photos");
    std::vector<std::filesystem::path> photos;
    for (const auto& e : std::filesystem::directory_iterator(folder, ec)) {
        std::string ext = e.path().extension().string();
        std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
        if (ext == ".jpg" || ext == ".jpeg" || ext == ".png") photos.push_back(e.path());
    }
    if (ec) return fileError(folder.string(), "cannot list the folder: " + ec.message());
    std::sort(photos.begin(), photos.end());
    if (photos.empty()) return fileError(folder.string(), "no JPEG or PNG photos in the folder");
    return photos;
}

Result<CityWriteReport> writeSynthCity(const std::filesystem::path& dir, const std::vector<Building>& buildings,
                                       const Warp& warp, float half,
                                       const std::function<float(float, float)>& groundAt,
                                       const CityWriteOptions& options) {
    CityWriteReport report;
    std::error_code ec;
    std::filesystem::create_directories(dir / "facades", ec);
    if (ec) return fileError((dir / "facades").string(), "cannot create folder: " + ec.message());

    std::vector<std::filesystem::path> photos;
    if (!options.facadePhotos.empty()) {
        auto pool = facadePhotoPool(options.facadePhotos);
        if (!pool) return pool.error();
        photos = std::move(*pool);
    }
    report.photos = photos.size();

    std::vector<std::size_t> inside;
    for (std::size_t i = 0; i < buildings.size(); ++i) {
        const glm::vec2 c = warp.toLocal(buildings[i].centre);
        if (std::abs(c.x) < half && std::abs(c.y) < half) inside.push_back(i);
    }
    report.buildings = inside.size();

    // Facade textures, in parallel; each building's photo aspect sets its facade width.
    const int S = options.textureSize;
    std::vector<float> aspect(inside.size(), 1.0f);
    std::mutex photoMutex;
    std::map<std::size_t, std::shared_ptr<Photo>> photoCache;
    std::atomic<std::uint64_t> bytes{0};
    std::optional<Error> failure;
    std::mutex failureMutex;
    parallelChunks(int(inside.size()), 16, std::max(1, options.threads), [&](int begin, int end) {
        for (int k = begin; k < end; ++k) {
            const Building& b = buildings[inside[std::size_t(k)]];
            std::vector<std::uint8_t> resized;
            if (!photos.empty()) {
                const std::size_t pi = hash32(b.seed) % photos.size();
                std::shared_ptr<Photo> ph;
                {
                    std::lock_guard lock(photoMutex);
                    auto& slot = photoCache[pi];
                    if (!slot) {
                        auto read = readPhoto(photos[pi]);
                        if (!read) {
                            std::lock_guard fl(failureMutex);
                            failure = fileError(photos[pi].string(), "unreadable facade photo");
                            return;
                        }
                        slot = std::make_shared<Photo>(std::move(*read));
                    }
                    ph = slot;
                }
                aspect[std::size_t(k)] = float(ph->w) / float(ph->h);
                resized.resize(std::size_t(S) * std::size_t(S) * 3);
                for (int y = 0; y < S; ++y)
                    for (int x = 0; x < S; ++x) {
                        const float fx = (float(x) + 0.5f) * float(ph->w) / float(S) - 0.5f;
                        const float fy = (float(y) + 0.5f) * float(ph->h) / float(S) - 0.5f;
                        const int x0 = std::clamp(int(std::floor(fx)), 0, ph->w - 1), y0 = std::clamp(int(std::floor(fy)), 0, ph->h - 1);
                        const int x1 = std::min(x0 + 1, ph->w - 1), y1 = std::min(y0 + 1, ph->h - 1);
                        const float tx = std::clamp(fx - float(x0), 0.0f, 1.0f), ty = std::clamp(fy - float(y0), 0.0f, 1.0f);
                        for (int c = 0; c < 3; ++c) {
                            auto at = [&](int xx, int yy) { return float(ph->rgb[(std::size_t(yy) * std::size_t(ph->w) + std::size_t(xx)) * 3 + std::size_t(c)]); };
                            const float v = (at(x0, y0) * (1 - tx) + at(x1, y0) * tx) * (1 - ty) + (at(x0, y1) * (1 - tx) + at(x1, y1) * tx) * ty;
                            resized[(std::size_t(y) * std::size_t(S) + std::size_t(x)) * 3 + std::size_t(c)] = std::uint8_t(std::clamp(v + 0.5f, 0.0f, 255.0f));
                        }
                    }
            }
            const auto px = facadeTexture(b, std::uint32_t(k), S, photos.empty() ? nullptr : &resized);
            const auto path = dir / "facades" / ("b" + std::to_string(k) + ".jpg");
            // Written under a temporary name and renamed: a killed synth leaves no facade cut short.
            const auto tmp = temporaryPathFor(path);
            auto out = OIIO::ImageOutput::create(tmp.string());
            OIIO::ImageSpec spec(S, S, 3, OIIO::TypeDesc::UINT8);
            spec.attribute("Compression", "jpeg:90");
            std::error_code renameError;
            const bool written =
                out && out->open(tmp.string(), spec) && out->write_image(OIIO::TypeDesc::UINT8, px.data()) && out->close();
            if (written) std::filesystem::rename(tmp, path, renameError);
            if (!written || renameError) {
                discardTemporary(tmp);
                std::lock_guard fl(failureMutex);
                failure = fileError(path.string(), written ? "cannot rename into place: " + renameError.message()
                                                           : std::string("cannot write facade texture"));
                return;
            }
            bytes += std::uint64_t(std::filesystem::file_size(path, ec));
        }
    });
    if (failure) return *failure;
    removeStaleTemporaries(dir / "facades"); // what an earlier, killed synth left (one sweep, not one per facade)
    report.textures = inside.size();
    report.textureBytes = bytes;

    // Geometry. OBJ is y-up: (x east, y north, z up) is written as (x, z, -y).
    std::string obj = "# seasonview synth: the synthetic scene's buildings (local frame, metres; y up, -z north)\n"
                      "mtllib city.mtl\n";
    std::string mtl = "# seasonview synth\nnewmtl roof\nKd 0.55 0.35 0.30\n";
    std::size_t vcount = 0, tcount = 0;
    char line[160];
    auto face = [&](const std::vector<glm::vec3>& p, const std::vector<glm::vec2>& uv) {
        for (std::size_t i = 0; i < p.size(); ++i) {
            std::snprintf(line, sizeof line, "v %.3f %.3f %.3f\n", double(p[i].x), double(p[i].z), double(-p[i].y));
            obj += line;
            if (!uv.empty()) {
                std::snprintf(line, sizeof line, "vt %.5f %.5f\n", double(uv[i].x), double(uv[i].y));
                obj += line;
            }
        }
        obj += "f";
        for (std::size_t i = 0; i < p.size(); ++i) {
            const std::size_t v = vcount + i + 1;
            if (uv.empty()) std::snprintf(line, sizeof line, " %zu", v);
            else std::snprintf(line, sizeof line, " %zu/%zu", v, tcount + i + 1);
            obj += line;
        }
        obj += "\n";
        vcount += p.size();
        if (!uv.empty()) tcount += p.size();
        report.triangles += p.size() - 2;
    };
    const auto P = [](glm::vec2 q, float z) { return glm::vec3(q.x, q.y, z); };
    const auto T = [](float u, float v) { return glm::vec2(u, v); };
    for (std::size_t k = 0; k < inside.size(); ++k) {
        const Building& b = buildings[inside[k]];
        const glm::vec2 a = b.axis, pn(-b.axis.y, b.axis.x);
        auto corner = [&](float u, float v) { return warp.toLocal(b.centre + a * u + pn * v); };
        const float hx = b.half.x, hy = b.half.y;
        const std::array<glm::vec2, 4> c = {corner(-hx, -hy), corner(hx, -hy), corner(hx, hy), corner(-hx, hy)};
        float g = INFINITY;
        for (const auto& q : c) g = std::min(g, groundAt(q.x, q.y));
        const float base = g - 0.5f, eave = g + b.eave;
        std::snprintf(line, sizeof line, "newmtl b%zu\nKd 1 1 1\nmap_Kd facades/b%zu.jpg\n", k, k);
        mtl += line;
        std::snprintf(line, sizeof line, "o building_%zu\nusemtl b%zu\n", k, k);
        obj += line;
        // Walls, u running on around the building: one texture repetition per facade width.
        const float facadeWidth = photos.empty() ? kFacadeBays * kBayWidth : std::max(1.0f, b.eave * aspect[k]);
        float s = 0.0f;
        for (int i = 0; i < 4; ++i) {
            const glm::vec2 p0 = c[std::size_t(i)], p1 = c[std::size_t((i + 1) % 4)];
            const float len = glm::length(p1 - p0);
            const float u0 = s / facadeWidth, u1 = (s + len) / facadeWidth;
            const float vb = (base - g) / b.eave;
            face({P(p0, base), P(p1, base), P(p1, eave), P(p0, eave)}, {T(u0, vb), T(u1, vb), T(u1, 1.0f), T(u0, 1.0f)});
            // Gable ends (the walls across the ridge, at u = ±hx) rise to the ridge.
            if (b.roof == Roof::Gable && (i == 1 || i == 3)) {
                const glm::vec2 m = 0.5f * (p0 + p1);
                // The gable shows the facade's top floors (v ends at 1 at the apex), not the next repetition's door.
                const float r = (b.ridge - b.eave) / b.eave;
                face({P(p0, eave), P(p1, eave), P(m, g + b.ridge)},
                     {T(u0, 1.0f - r), T(u1, 1.0f - r), T(0.5f * (u0 + u1), 1.0f)});
            }
            s += len;
        }
        // Roofs, untextured: the imagery is their texture (thesis §4.8.2).
        obj += "usemtl roof\n";
        const auto& at = P;
        if (b.roof == Roof::Flat) {
            face({at(c[0], eave), at(c[1], eave), at(c[2], eave), at(c[3], eave)}, {});
        } else if (b.roof == Roof::Gable) {
            const glm::vec2 r0 = corner(-hx, 0.0f), r1 = corner(hx, 0.0f);
            const float rz = g + b.ridge;
            face({at(c[0], eave), at(c[1], eave), at(r1, rz), at(r0, rz)}, {});
            face({at(c[2], eave), at(c[3], eave), at(r0, rz), at(r1, rz)}, {});
        } else { // hip: the ridge runs along the longer side
            const float slope = (b.ridge - b.eave) / hy;
            if (hx >= hy) {
                const glm::vec2 r0 = corner(-(hx - hy), 0.0f), r1 = corner(hx - hy, 0.0f);
                const float rz = eave + hy * slope;
                face({at(c[0], eave), at(c[1], eave), at(r1, rz), at(r0, rz)}, {});
                face({at(c[2], eave), at(c[3], eave), at(r0, rz), at(r1, rz)}, {});
                face({at(c[1], eave), at(c[2], eave), at(r1, rz)}, {});
                face({at(c[3], eave), at(c[0], eave), at(r0, rz)}, {});
            } else {
                const glm::vec2 r0 = corner(0.0f, -(hy - hx)), r1 = corner(0.0f, hy - hx);
                const float rz = eave + hx * slope;
                face({at(c[3], eave), at(c[0], eave), at(r0, rz), at(r1, rz)}, {});
                face({at(c[1], eave), at(c[2], eave), at(r1, rz), at(r0, rz)}, {});
                face({at(c[0], eave), at(c[1], eave), at(r0, rz)}, {});
                face({at(c[2], eave), at(c[3], eave), at(r1, rz)}, {});
            }
        }
    }
    std::string err;
    if (!writeTextAtomic(dir / "city.mtl", mtl, err)) return fileError((dir / "city.mtl").string(), err);
    if (!writeTextAtomic(dir / "city.obj", obj, err)) return fileError((dir / "city.obj").string(), err);
    return report;
}

} // namespace seasonview::synth
