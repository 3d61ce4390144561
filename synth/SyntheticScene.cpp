// `seasonview synth`: the pipeline from options to files. The pieces:
//   SynthLayout      parcels, roads, river (vector, layout space)
//   SynthSettlement  houses, farmsteads, sports ground, parking, cars
//   SynthVegetation  trees
//   SynthTerrain     fBm or real DEM elevation
//   SynthRaster      ground and object maps of a band of rows (shared by both seasons)
//   SynthShadow      cast shadows per season, swept band by band
//   SynthCamera      sun, sky, exposure, haze, noise per season
//   SynthMaterials / SynthPaint  pixel colours
#include "SyntheticScene.h"

#include "AtomicFile.h"
#include "GeoTiffStreamWriter.h"
#include "ImageStreamWriter.h"
#include "Raster.h"
#include "SynthCamera.h"
#include "SynthCity.h"
#include "SynthLayout.h"
#include "SynthObjects.h"
#include "SynthPaint.h"
#include "SynthParallel.h"
#include "SynthRandom.h"
#include "SynthRaster.h"
#include "SynthShadow.h"
#include "SynthTerrain.h"

#include <glm/common.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <thread>

namespace seasonview {

namespace {

using namespace synth;

// The tallest object (trees are clamped to 34 m) casts its shadow this far at the lowest leaf-off sun (19°):
// objects that far outside the scene still shadow it.
constexpr double kMaxCasterHeight = 35.0;

// Every tree whose crown disc reaches into the scene (its centre may lie just outside), streamed to `path`
// atomically.
Status writeTreesCsv(const std::filesystem::path& path, const Objects& o, float half, glm::dvec2 centre,
                     double& meanDeciduousHeight, int& nd, int& nc) {
    const std::filesystem::path tmp = temporaryPathFor(path);
    std::FILE* f = std::fopen(tmp.c_str(), "wb");
    if (!f) return fileError(path.string(), "cannot create file");
    std::vector<char> buffer(1 << 20);
    std::setvbuf(f, buffer.data(), _IOFBF, buffer.size());
    bool ok = std::fputs("id,type,x,y,easting,northing,radius_m,height_m\n", f) >= 0;
    double sum = 0.0;
    nd = nc = 0;
    for (size_t i = 0; i < o.trees.size() && ok; ++i) {
        const Tree& t = o.trees[i];
        const float dx = std::max(std::abs(t.centre.x) - half, 0.0f), dy = std::max(std::abs(t.centre.y) - half, 0.0f);
        if (dx * dx + dy * dy >= t.radius * t.radius) continue;
        ok = std::fprintf(f, "%zu,%s,%.3f,%.3f,%.3f,%.3f,%.3f,%.2f\n", i + 1, t.conifer ? "conifer" : "deciduous",
                          double(t.centre.x), double(t.centre.y), centre.x + double(t.centre.x),
                          centre.y + double(t.centre.y), double(t.radius), double(t.height)) > 0;
        if (t.conifer) ++nc;
        else {
            ++nd;
            sum += double(t.height);
        }
    }
    ok = std::fclose(f) == 0 && ok;
    if (!ok) {
        discardTemporary(tmp);
        return fileError(path.string(), "write failed (disk full?)");
    }
    meanDeciduousHeight = nd > 0 ? sum / nd : 0.0;
    std::string err;
    if (!commitTemporary(tmp, path, err)) return fileError(path.string(), err);
    return Ok{};
}

// The two truth masks, streamed band by band: PNGs up to SynthOptions::pngMasksUpTo pixels per side (PNG readers
// decode whole images), tiled 8-bit GeoTIFFs beyond.
class TruthWriters {
public:
    Status open(const std::filesystem::path& dir, int size, int pngUpTo, const Georef& georef, int threads,
                TiffCompression compression) {
        m_png = size <= pngUpTo;
        for (int k = 0; k < 2; ++k) {
            std::error_code ec; // a mask in the other format from an earlier run would contradict scene.json
            std::filesystem::remove(dir / (std::string(kStems[k]) + (m_png ? ".tif" : ".png")), ec);
            const std::filesystem::path path = dir / fileName(k);
            if (m_png) {
                auto w = ImageStreamWriter::open(path, size, size, 1);
                if (!w) return w.error();
                m_pngs[k] = std::move(*w);
            } else {
                GeoTiffWriteOptions options;
                options.threads = threads;
                options.compression = compression;
                auto w = GeoTiffStreamWriter::open(path, size, size, 1, SampleType::U8, georef, options);
                if (!w) return w.error();
                m_tiffs[k] = std::move(*w);
            }
        }
        return Ok{};
    }
    /// File name of mask k (0 deciduous, 1 conifer).
    std::string fileName(int k) const { return std::string(kStems[k]) + (m_png ? ".png" : ".tif"); }
    /// Mask k (0 deciduous, 1 conifer) rows [y0, y0 + rows).
    Status write(int k, int y0, int rows, const std::vector<std::uint8_t>& mask) {
        return m_png ? m_pngs[k]->writeRows(y0, rows, mask.data()) : m_tiffs[k]->writeRows(y0, rows, mask.data());
    }
    Status finish() {
        for (int k = 0; k < 2; ++k)
            if (auto st = m_png ? m_pngs[k]->finish() : m_tiffs[k]->finish(); !st) return st;
        return Ok{};
    }

private:
    static constexpr const char* kStems[2] = {"truth_deciduous", "truth_conifer"};
    bool m_png = true;
    std::optional<ImageStreamWriter> m_pngs[2];
    std::optional<GeoTiffStreamWriter> m_tiffs[2];
};

} // namespace

Result<SynthReport> generateSyntheticScene(const SynthOptions& options, const std::filesystem::path& outDir,
                                           const ProgressFn& progress) {
    const auto start = std::chrono::steady_clock::now();
    auto stage = [&](double f, const char* name) {
        if (progress) progress(f, name);
    };
    if (!std::isfinite(options.sizeM) || options.sizeM <= 0.0)
        return Error{"synth: the scene size must be a positive number of metres"};
    if (!std::isfinite(options.gsd) || options.gsd <= 0.0)
        return Error{"synth: the ground sample distance must be a positive number of metres"};
    const double pixels = options.sizeM / options.gsd;
    if (!(pixels >= 16.0 && pixels <= double(kMaxSynthPixels)))
        return Error{"synth: size / gsd must give 16 to " + std::to_string(kMaxSynthPixels) + " pixels per side (got " +
                     std::to_string(std::lround(pixels)) + ")"};
    if (options.bandRows < 0)
        return Error{"synth: the band height must be a positive number of rows (or 0 for the default)"};
    if (options.city && !options.facadePhotos.empty()) // checked before the scene is generated, not after
        if (auto pool = synth::facadePhotoPool(options.facadePhotos); !pool) return pool.error();
    const int size = static_cast<int>(std::lround(pixels));
    const int threads = options.threads > 0 ? options.threads : std::max(1, int(std::thread::hardware_concurrency()));
    const double gsd = options.gsd, extent = double(size) * gsd;
    // DEM spacing --dem-spacing or max(1 m, 4 gsd), adjusted to a whole number of samples covering exactly the imagery's extent.
    if (!(options.demSpacing >= 0.0) || !std::isfinite(options.demSpacing))
        return Error{"synth: the DEM spacing must be a positive number of metres (or 0 for the default)"};
    const double wantSpacing = options.demSpacing > 0.0 ? options.demSpacing : std::max(1.0, 4.0 * gsd);
    if (extent / wantSpacing > 65536.0)
        return Error{"synth: the DEM spacing gives more than 65536 samples per side"};
    const int demSamples = std::max(2, static_cast<int>(std::lround(extent / wantSpacing)));
    const double demSpacing = extent / demSamples;
    const std::uint64_t seed = mixSeed(options.seed, 0x5EA50F5EEDull);

    std::error_code ec;
    std::filesystem::create_directories(outDir, ec);
    if (ec) return fileError(outDir.string(), "cannot create folder (" + ec.message() + ")");
    // A stale manifest must not describe files that are about to be replaced.
    std::filesystem::remove(outDir / "scene.json", ec);

    // Where the scene is: near Münster (UTM 32N), or centred on the real DEM in its own UTM zone.
    stage(0.0, "layout");
    Crs crs = Crs::utm(32, true);
    glm::dvec2 centre(405000.0, 5757000.0);
    std::optional<DemSource> dem;
    if (!options.dem.empty()) {
        auto d = openDem(options.dem);
        if (!d) return d.error();
        const glm::dvec2 ll = d->centreLonLat;
        crs = Crs::utmAt(ll.x, ll.y);
        centre = glm::round(convert(Crs::geographic(), crs, ll));
        dem = std::move(*d);
    } else if (options.centreLonLat) {
        const glm::dvec2 ll = *options.centreLonLat;
        if (!(std::abs(ll.y) < 84.0) || !(std::abs(ll.x) <= 180.0))
            return Error{"synth: --centre must be longitude,latitude within UTM's range (|latitude| < 84)"};
        crs = Crs::utmAt(ll.x, ll.y);
        centre = glm::round(convert(Crs::geographic(), crs, ll));
    }
    const bool south = convert(crs, Crs::geographic(), centre).y < 0.0;
    const glm::dvec2 origin = centre + glm::dvec2(-0.5 * extent, 0.5 * extent);
    const Georef georef{crs, origin, glm::dvec2(gsd)};
    const Georef demGeoref{crs, origin, glm::dvec2(demSpacing)};

    const SeasonLook looks[2] = {makeSeasonLook(true, seed, south), makeSeasonLook(false, seed, south)};
    const double lowestSun = std::min(looks[0].sunElevationDeg, looks[1].sunElevationDeg) * 0.017453292519943295;
    const double marginM = kMaxCasterHeight / std::tan(lowestSun) + 2.0 * gsd;
    const float half = static_cast<float>(0.5 * extent);

    Layout layout = buildLayout(half + static_cast<float>(marginM) + 10.0f, seed);
    Objects objects;
    placeSettlement(layout, objects);
    placeVegetation(layout, objects, half);
    if (options.blockCity > 0) placeBlockCity(layout, objects, options.blockCity, seed);

    stage(0.1, "terrain");
    Terrain terrain;
    if (dem) {
        auto t = resampleDem(*dem, demSamples, static_cast<float>(demSpacing), crs, centre, threads);
        if (!t) return t.error();
        terrain = std::move(*t);
        dem.reset();
    } else {
        terrain = makeFbmTerrain(demSamples, static_cast<float>(demSpacing), layout, seed, threads);
    }
    if (auto s = writeGeoTiff(outDir / "dem.tif", terrain.z.data(), SampleType::F32, demSamples, demSamples, 1, demGeoref);
        !s)
        return s.error();

    // The imagery, band by band. Each band rasterises its objects (bucketed by rows, so only the objects that
    // touch it are visited) and ground, sweeps each season's shadows, shades the terrain rows under it, paints both
    // seasons and writes their tiles and the truth masks' rows.
    const PixelGrid grid{size, static_cast<int>(std::ceil(marginM / gsd)), static_cast<float>(gsd), half};
    const int e = grid.extSize(), m = grid.margin;
    const int bandRows = options.bandRows > 0 ? options.bandRows : kDefaultSynthBandRows;
    const int bands = (size + bandRows - 1) / bandRows;
    auto bandBegin = [&](int b) { return b * bandRows; };
    auto bandEnd = [&](int b) { return std::min(size, (b + 1) * bandRows); };

    const ObjectRasterizer raster(layout, objects, grid);
    ShadowSweep sweeps[2] = {ShadowSweep(grid, raster.ids(), objects, terrain, looks[0].towardSun, looks[0].leafOn),
                             ShadowSweep(grid, raster.ids(), objects, terrain, looks[1].towardSun, looks[1].leafOn)};
    ObjectRows objectRows;
    // Sweeps extended rows [r0, r1) (no output) for the seasons whose sweep runs forward (top down) or backward.
    auto sweepOnly = [&](int r0, int r1, bool forward) {
        raster.rasterize(r0, r1, objectRows, threads);
        for (ShadowSweep& sw : sweeps)
            if (sw.increasingRows() == forward) sw.sweep(objectRows, nullptr, threads);
    };
    // A sweep that runs top down (sun in the north) first crosses the top margin, then follows the bands. One that
    // runs bottom up (sun in the south, the usual case) is run once from the bottom margin to the top beforehand,
    // leaving a checkpoint of its rays at the start of every band: shadows then come out exactly as in one sweep,
    // however long they are, in memory that does not grow with the height.
    const bool anyForward = sweeps[0].increasingRows() || sweeps[1].increasingRows();
    const bool anyBackward = !sweeps[0].increasingRows() || !sweeps[1].increasingRows();
    std::vector<ShadowSweep::Checkpoint> checkpoints[2];
    stage(0.15, "shadows");
    if (anyForward)
        for (int r = 0; r < m; r += bandRows) sweepOnly(r, std::min(m, r + bandRows), true);
    if (anyBackward) {
        for (int s = 0; s < 2; ++s)
            if (!sweeps[s].increasingRows()) checkpoints[s].resize(size_t(bands));
        for (int r1 = e; r1 > size + m; r1 -= bandRows) sweepOnly(std::max(size + m, r1 - bandRows), r1, false);
        for (int b = bands - 1; b >= 0; --b) {
            for (int s = 0; s < 2; ++s)
                if (!sweeps[s].increasingRows())
                    checkpoints[s][size_t(b)] = sweeps[s].save(bandBegin(b) + m, bandEnd(b) + m);
            if (b > 0) sweepOnly(bandBegin(b) + m, bandEnd(b) + m, false);
            stage(0.15 + 0.1 * double(bands - b) / bands, "shadows");
        }
    }

    const std::vector<float> shadeHeights = shadingHeights(terrain, threads);
    std::optional<GeoTiffStreamWriter> imagery[2];
    for (int s = 0; s < 2; ++s) {
        GeoTiffWriteOptions o;
        o.threads = threads;
        o.compression = options.compression;
        auto w = GeoTiffStreamWriter::open(outDir / (looks[s].leafOn ? "leafon.tif" : "leafoff.tif"), size, size, 3,
                                           SampleType::U8, georef, o);
        if (!w) return w.error();
        imagery[s] = std::move(*w);
    }
    TruthWriters truth;
    // The masks stay lossless whatever the imagery's compression.
    const TiffCompression maskCompression =
        options.compression == TiffCompression::Jpeg ? TiffCompression::Zstd : options.compression;
    if (auto st = truth.open(outDir, size, options.pngMasksUpTo, georef, threads, maskCompression); !st)
        return st.error();

    std::vector<std::uint32_t> ground;
    std::vector<std::uint8_t> shadow, rgb, masks[2];
    std::vector<float> shade;
    for (int b = 0; b < bands; ++b) {
        const int y0 = bandBegin(b), rows = bandEnd(b) - y0;
        const size_t n = size_t(rows) * size_t(size);
        raster.rasterize(y0 + m, y0 + rows + m, objectRows, threads);
        rasterizeGround(layout, grid, y0, rows, ground, threads);

        for (auto& mask : masks) mask.assign(n, 0);
        parallelChunks(rows, 64, threads, [&](int r0, int r1) {
            for (int r = r0; r < r1; ++r)
                for (int c = 0; c < size; ++c) {
                    const std::uint32_t id = objectRows.object[objectRows.at(c + m, y0 + r + m)];
                    if (!raster.ids().isTree(id)) continue;
                    masks[objects.trees[id - 1].conifer ? 1 : 0][size_t(r) * size_t(size) + size_t(c)] = 255;
                }
        });
        for (int k = 0; k < 2; ++k)
            if (auto st = truth.write(k, y0, rows, masks[k]); !st) return st.error();

        // Terrain sample rows under the band (bilinear reads a row and the next).
        int shade0 = terrain.height, shade1 = -1;
        for (int r = y0; r < y0 + rows; ++r) {
            int first = 0, last = 0;
            terrain.rowsRead((terrain.halfExtent - grid.centreExt(0, r + m).y) / terrain.spacing - 0.5f, first, last);
            shade0 = std::min(shade0, first);
            shade1 = std::max(shade1, last);
        }
        shadow.resize(n);
        for (int s = 0; s < 2; ++s) {
            ShadowSweep& sw = sweeps[s];
            if (!sw.increasingRows()) {
                sw.restore(checkpoints[s][size_t(b)]);
                checkpoints[s][size_t(b)] = {};
            }
            sw.sweep(objectRows, shadow.data(), threads);
            terrainShadingRows(terrain, shadeHeights, looks[s].towardSun, shade0, shade1 + 1, shade, threads);
            const PaintInput in{layout, objects,    raster.ids(), grid,   terrain, y0,
                                rows,   ground,     objectRows,   shade,  shade0,  shadow};
            paintRows(in, looks[s], rgb, threads);
            if (auto w = imagery[s]->writeRows(y0, rows, rgb.data()); !w) return w.error();
        }
        stage(0.25 + 0.7 * double(b + 1) / bands, "painting");
    }
    for (auto& w : imagery)
        if (auto st = w->finish(); !st) return st.error();
    if (auto st = truth.finish(); !st) return st.error();

    stage(0.95, "trees");
    SynthReport report;
    double meanHeight = 0.0;
    if (auto st = writeTreesCsv(outDir / "trees.csv", objects, half, centre, meanHeight, report.deciduousTrees,
                                report.conifers);
        !st)
        return st.error();

    if (options.city && !objects.buildings.empty()) { // a scene without settlements has no city model
        stage(0.96, "city");
        synth::CityWriteOptions co;
        co.facadePhotos = options.facadePhotos;
        co.textureSize = options.facadeSize;
        co.threads = threads;
        // The terrain under a local point, as dem.tif holds it (sample (i, j) at the centre of its cell, row 0 north).
        const auto groundAt = [&](float x, float y) {
            return terrain.bilinear(terrain.z, (x + terrain.halfExtent) / terrain.spacing - 0.5f,
                                    (terrain.halfExtent - y) / terrain.spacing - 0.5f);
        };
        auto city = synth::writeSynthCity(outDir / "city", objects.buildings, layout.warp, half, groundAt, co);
        if (!city) return city.error();
        report.buildings = city->buildings;
        report.facadeBytes = city->textureBytes;
    }

    nlohmann::ordered_json j;
    j["name"] = "synthetic seed " + std::to_string(options.seed) + (options.dem.empty() ? "" : " on " + options.dem.stem().string());
    j["leafon"] = "leafon.tif";
    j["leafoff"] = "leafoff.tif";
    j["elevation"] = "dem.tif";
    if (report.buildings > 0) j["buildings"] = "city/city.obj";
    j["truth"] = {{"deciduous", truth.fileName(0)}, {"conifer", truth.fileName(1)}, {"trees", "trees.csv"}};
    j["parameters"] = {{"tree_height_m", std::round(meanHeight * 100.0) / 100.0}};
    j["generator"] = {{"program", "seasonview synth"}, {"version", kSynthGeneratorVersion},      {"seed", options.seed},
                      {"size_m", options.sizeM},       {"gsd", options.gsd}, {"dem", options.dem.string()}};
    j["generator"]["compression"] = tiffCompressionName(options.compression);
    if (options.blockCity > 0) j["generator"]["block_city"] = options.blockCity;
    if (report.buildings > 0) j["generator"]["facade_size"] = options.facadeSize;
    if (options.centreLonLat) j["generator"]["centre_lonlat"] = {options.centreLonLat->x, options.centreLonLat->y};
    std::string err;
    if (!writeTextAtomic(outDir / "scene.json", j.dump(2) + "\n", err))
        return fileError((outDir / "scene.json").string(), err);

    stage(1.0, "done");
    report.width = report.height = size;
    report.demWidth = report.demHeight = demSamples;
    report.crs = crs.name();
    report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return report;
}

} // namespace seasonview
