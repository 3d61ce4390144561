#include "TestUtil.h"

#include <gdal_priv.h>
#include <gdal_utils.h>
#include <ogr_spatialref.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <sstream>

#include <fcntl.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

namespace seasonview::test {

std::filesystem::path outputDir() {
    std::filesystem::path p = SEASONVIEW_TEST_OUTPUT_DIR;
    std::filesystem::create_directories(p);
    return p;
}

TempDir::TempDir(const std::string& name) {
    static int counter = 0;
    m_path = outputDir() / (name + "-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
    std::filesystem::remove_all(m_path);
    std::filesystem::create_directories(m_path);
}

TempDir::~TempDir() {
    if (!std::getenv("SEASONVIEW_KEEP_TEST_FILES")) {
        std::error_code ec;
        std::filesystem::remove_all(m_path, ec);
    }
}

namespace {
// What identifies the build a shared fixture was made by: seasonview's and this binary's sizes and times.
std::string buildStamp() {
    std::string stamp;
    for (const char* p : {SEASONVIEW_BINARY, "/proc/self/exe"}) {
        std::error_code ec;
        const auto target = std::filesystem::canonical(p, ec);
        const auto size = ec ? 0 : std::filesystem::file_size(target, ec);
        const auto time = ec ? 0 : std::filesystem::last_write_time(target, ec).time_since_epoch().count();
        stamp += target.string() + " " + std::to_string(size) + " " + std::to_string(time) + "\n";
    }
    return stamp;
}
} // namespace

std::optional<std::filesystem::path> sharedFixture(const std::string& name,
                                                   const std::function<bool(const std::filesystem::path&)>& make) {
    const auto root = outputDir() / "shared";
    std::filesystem::create_directories(root);
    const auto dir = root / name, stampFile = dir / ".made-by";
    const int lock = ::open((root / (name + ".lock")).c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (lock < 0 || ::flock(lock, LOCK_EX) != 0) {
        ADD_FAILURE() << "cannot lock " << (root / (name + ".lock"));
        if (lock >= 0) ::close(lock);
        return std::nullopt;
    }
    const std::string stamp = buildStamp();
    std::optional<std::filesystem::path> out = dir;
    if (!std::filesystem::exists(stampFile) || readBytes(stampFile) != stamp) {
        std::error_code ec;
        std::filesystem::remove_all(dir, ec);
        std::filesystem::create_directories(dir);
        if (make(dir)) {
            std::ofstream(stampFile, std::ios::binary) << stamp;
        } else {
            std::filesystem::remove_all(dir, ec);
            out = std::nullopt;
        }
    }
    ::flock(lock, LOCK_UN);
    ::close(lock);
    return out;
}

std::optional<std::filesystem::path> realDataDir() {
    std::filesystem::path p = SEASONVIEW_DATA_DIR;
    if (const char* e = std::getenv("SEASONVIEW_DATA"); e && *e) p = e;
    std::error_code ec;
    if (std::filesystem::is_directory(p / "seasons", ec)) return p;
    return std::nullopt;
}

Georef testGeoref(double gsd, double easting, double northing) {
    Georef g;
    g.crs = Crs::utm(32, true);
    g.origin = {easting, northing};
    g.pixelSize = {gsd, gsd};
    return g;
}

void writeTestImage(const std::filesystem::path& path, int w, int h, const Georef& g, bool sixteenBit, int seed) {
    std::vector<std::uint16_t> px16(size_t(w) * size_t(h) * 3);
    std::vector<std::uint8_t> px8(px16.size());
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c) {
                const double v = 0.5 + 0.25 * std::sin((x + seed * 7) * 0.21 + c) + 0.2 * std::cos((y - seed) * 0.13 * (c + 1)) +
                                 ((x / 8 + y / 8) % 2 ? 0.05 : -0.05);
                const double t = std::clamp(v, 0.0, 1.0);
                const size_t i = (size_t(y) * size_t(w) + size_t(x)) * 3 + size_t(c);
                px8[i] = std::uint8_t(t * 255.0 + 0.5);
                px16[i] = std::uint16_t(300.0 + t * 2200.0); // Sentinel-2-like reflectance x10000
            }
    Status st = sixteenBit ? writeGeoTiff(path, px16.data(), SampleType::U16, w, h, 3, g)
                           : writeGeoTiff(path, px8.data(), SampleType::U8, w, h, 3, g);
    ASSERT_TRUE(st.ok()) << st.message();
}

namespace {

std::vector<char*> argv(const std::vector<std::string>& args, std::vector<std::string>& storage) {
    storage = args;
    std::vector<char*> v;
    for (std::string& s : storage) v.push_back(s.data());
    v.push_back(nullptr);
    return v;
}

} // namespace

void gdalWarp(const std::filesystem::path& src, const std::filesystem::path& dst, const std::vector<std::string>& args) {
    GDALAllRegister();
    std::vector<std::string> storage;
    auto a = argv(args, storage);
    GDALWarpAppOptions* o = GDALWarpAppOptionsNew(a.data(), nullptr);
    ASSERT_TRUE(o) << "gdalwarp arguments";
    GDALDatasetH in = GDALOpen(src.c_str(), GA_ReadOnly);
    ASSERT_TRUE(in) << src;
    int usageError = 0;
    GDALDatasetH out = GDALWarp(dst.c_str(), nullptr, 1, &in, o, &usageError);
    GDALWarpAppOptionsFree(o);
    GDALClose(in);
    ASSERT_TRUE(out && !usageError) << "gdalwarp " << src << " -> " << dst << ": " << CPLGetLastErrorMsg();
    GDALClose(out);
}

void gdalTranslate(const std::filesystem::path& src, const std::filesystem::path& dst,
                   const std::vector<std::string>& args) {
    GDALAllRegister();
    std::vector<std::string> storage;
    auto a = argv(args, storage);
    GDALTranslateOptions* o = GDALTranslateOptionsNew(a.data(), nullptr);
    ASSERT_TRUE(o) << "gdal_translate arguments";
    GDALDatasetH in = GDALOpen(src.c_str(), GA_ReadOnly);
    ASSERT_TRUE(in) << src;
    int usageError = 0;
    GDALDatasetH out = GDALTranslate(dst.c_str(), in, o, &usageError);
    GDALTranslateOptionsFree(o);
    GDALClose(in);
    ASSERT_TRUE(out && !usageError) << "gdal_translate " << src << " -> " << dst << ": " << CPLGetLastErrorMsg();
    GDALClose(out);
}

void gdalBuildVrt(const std::filesystem::path& dst, const std::vector<std::filesystem::path>& sources,
                  const std::vector<std::string>& args) {
    GDALAllRegister();
    std::vector<std::string> storage;
    auto a = argv(args, storage);
    GDALBuildVRTOptions* o = GDALBuildVRTOptionsNew(a.data(), nullptr);
    ASSERT_TRUE(o) << "gdalbuildvrt arguments";
    std::vector<std::string> names;
    for (const auto& s : sources) names.push_back(s.string());
    std::vector<const char*> list;
    for (const auto& n : names) list.push_back(n.c_str());
    int usageError = 0;
    GDALDatasetH out = GDALBuildVRT(dst.c_str(), int(list.size()), nullptr, list.data(), o, &usageError);
    GDALBuildVRTOptionsFree(o);
    ASSERT_TRUE(out && !usageError) << "gdalbuildvrt " << dst << ": " << CPLGetLastErrorMsg();
    GDALClose(out);
}

std::array<double, 6> geotransformOf(const Georef& g) {
    return {g.origin.x, g.pixelSize.x, 0.0, g.origin.y, 0.0, -g.pixelSize.y};
}

void writeGdalRaster(const std::filesystem::path& path, const void* data, SampleType type, int w, int h, int bands,
                     const GdalRasterSpec& spec) {
    GDALAllRegister();
    GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
    GDALDriver* target = GetGDALDriverManager()->GetDriverByName(spec.driver.c_str());
    ASSERT_TRUE(mem && target) << "GDAL driver " << spec.driver;
    const GDALDataType t = type == SampleType::U8 ? GDT_Byte : type == SampleType::U16 ? GDT_UInt16
                           : type == SampleType::I16 ? GDT_Int16 : GDT_Float32;
    GDALDataset* ds = mem->Create("", w, h, bands, t, nullptr);
    ASSERT_TRUE(ds);
    const int size = GDALGetDataTypeSizeBytes(t);
    std::vector<int> map(static_cast<size_t>(bands));
    for (int b = 0; b < bands; ++b) map[size_t(b)] = b + 1;
    ASSERT_EQ(ds->RasterIO(GF_Write, 0, 0, w, h, const_cast<void*>(data), w, h, t, bands, map.data(),
                           GSpacing(size) * bands, GSpacing(size) * bands * w, size, nullptr),
              CE_None);
    if (spec.geotransform) {
        std::array<double, 6> gt = *spec.geotransform;
        ds->SetGeoTransform(gt.data());
    }
    if (!spec.crs.empty()) {
        OGRSpatialReference srs;
        ASSERT_EQ(srs.SetFromUserInput(spec.crs.c_str()), OGRERR_NONE) << spec.crs;
        ds->SetSpatialRef(&srs);
    }
    for (int b = 1; b <= bands; ++b) {
        if (spec.nodata) ds->GetRasterBand(b)->SetNoDataValue(*spec.nodata);
        if (bands >= 3 && b <= 3) ds->GetRasterBand(b)->SetColorInterpretation(GDALColorInterp(GCI_RedBand + b - 1));
    }
    if (spec.lastBandIsAlpha) ds->GetRasterBand(bands)->SetColorInterpretation(GCI_AlphaBand);
    if (spec.mask) {
        ASSERT_EQ(ds->CreateMaskBand(GMF_PER_DATASET), CE_None);
        ASSERT_EQ(ds->GetRasterBand(1)->GetMaskBand()->RasterIO(GF_Write, 0, 0, w, h, const_cast<std::uint8_t*>(spec.mask),
                                                               w, h, GDT_Byte, 0, 0, nullptr),
                  CE_None);
    }
    std::vector<const char*> options;
    for (const std::string& o : spec.creationOptions) options.push_back(o.c_str());
    options.push_back(nullptr);
    CPLSetConfigOption("GDAL_TIFF_INTERNAL_MASK", "YES");
    GDALDataset* out = target->CreateCopy(path.c_str(), ds, FALSE, const_cast<char**>(options.data()), nullptr, nullptr);
    GDALClose(ds);
    ASSERT_TRUE(out) << "cannot write " << path << ": " << CPLGetLastErrorMsg();
    GDALClose(out);
}

Result<Scene> writeTestPair(const std::filesystem::path& dir, int w, int h, double gsd, bool sixteenBit) {
    writeTestImage(dir / "on.tif", w, h, testGeoref(gsd), sixteenBit, 1);
    writeTestImage(dir / "off.tif", w, h, testGeoref(gsd), sixteenBit, 2);
    SceneSources s;
    s.leafon = dir / "on.tif";
    s.leafoff = dir / "off.tif";
    return loadScene(s, dir / "cache");
}

void writeTiledTestPair(const std::filesystem::path& dir) {
    std::filesystem::create_directories(dir / "tiles");
    const TreePair p = makeTreePair(128, 96, 5);
    const Georef g = testGeoref(0.5);
    // The leaf-on's halves: a geotransform and no CRS.
    for (int half = 0; half < 2; ++half) {
        std::vector<std::uint8_t> px(size_t(64) * 96 * 3);
        for (int y = 0; y < 96; ++y)
            for (int x = 0; x < 64; ++x)
                for (int c = 0; c < 3; ++c)
                    px[(size_t(y) * 64 + size_t(x)) * 3 + size_t(c)] = p.on.at(half * 64 + x, y, c);
        Georef t = g;
        t.origin.x += half * 64 * g.pixelSize.x;
        GdalRasterSpec s;
        s.geotransform = geotransformOf(t);
        writeGdalRaster(dir / "tiles" / (half ? "on_e.tif" : "on_w.tif"), px.data(), SampleType::U8, 64, 96, 3, s);
    }
    // The leaf-off's halves, cut from one GeoTIFF that carries its CRS.
    const Status st = writeGeoTiff(dir / "off_whole.tif", p.off.pixels.data(), SampleType::U8, 128, 96, 3, g);
    ASSERT_TRUE(st.ok()) << st.message();
    gdalTranslate(dir / "off_whole.tif", dir / "tiles/off_n.tif", {"-srcwin", "0", "0", "128", "48"});
    gdalTranslate(dir / "off_whole.tif", dir / "tiles/off_s.tif", {"-srcwin", "0", "48", "128", "48"});
}

TreePair makeTreePair(int w, int h, int seed) {
    TreePair p;
    for (Image<std::uint8_t>* img : {&p.on, &p.off, &p.truth}) {
        img->width = w;
        img->height = h;
        img->channels = img == &p.truth ? 1 : 3;
        img->pixels.assign(size_t(w) * size_t(h) * size_t(img->channels), 0);
    }
    // Deterministic per-pixel noise in [-1, 1].
    auto noise = [seed](int x, int y, int salt) {
        std::uint32_t v =
            std::uint32_t(x) * 73856093u ^ std::uint32_t(y) * 19349663u ^ std::uint32_t(seed + salt) * 83492791u;
        v ^= v >> 13;
        v *= 0x5bd1e995u;
        v ^= v >> 15;
        return double(v & 0xFFFF) / 32767.5 - 1.0;
    };
    const int cropX = w * 2 / 3;
    const double r0 = std::max(3.0, std::min(h / 9.0, cropX / 12.0)); // crowns keep clear of the crop field
    for (int i = 0; i < 3; ++i) {
        const double r = r0 * (1.0 + 0.25 * i);
        p.crowns.push_back({(i + 0.5) * cropX / 3.0 + 0.5, h * (0.3 + 0.2 * i) + 0.5, r});
    }
    auto put = [](Image<std::uint8_t>& img, int x, int y, double r, double g, double b) {
        const double c[3] = {r, g, b};
        for (int k = 0; k < 3; ++k) img.at(x, y, k) = std::uint8_t(std::clamp(c[k] + 0.5, 0.0, 255.0));
    };
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const double n = noise(x, y, 1), m = noise(x, y, 2);
            if (x >= cropX) { // crop: smooth green in summer, bare soil in winter
                put(p.on, x, y, 55 * (1 + 0.01 * n), 120 * (1 + 0.01 * n), 40 * (1 + 0.01 * n));
                put(p.off, x, y, 120 * (1 + 0.01 * m), 95 * (1 + 0.01 * m), 75 * (1 + 0.01 * m));
                continue;
            }
            bool crown = false;
            double shade = 1.0;
            for (const auto& c : p.crowns) {
                const double dx = x + 0.5 - c[0], dy = y + 0.5 - c[1];
                if (dx * dx + dy * dy <= c[2] * c[2]) {
                    crown = true;
                    shade = 1.0 + 0.35 * (-dx - dy) / (2.0 * c[2]); // lit from the top left
                }
            }
            if (crown) {
                p.truth.at(x, y) = 255;
                const double t = shade * (1.0 + 0.25 * n);
                put(p.on, x, y, 60 * t, 110 * t, 40 * t);
                const double u = 1.0 + 0.2 * m;
                put(p.off, x, y, 100 * u, 92 * u, 85 * u);
            } else { // meadow: green in both seasons
                put(p.on, x, y, 70 * (1 + 0.03 * n), 100 * (1 + 0.03 * n), 50 * (1 + 0.03 * n));
                put(p.off, x, y, 72 * (1 + 0.03 * m), 98 * (1 + 0.03 * m), 52 * (1 + 0.03 * m));
            }
        }
    return p;
}

gl::GlContext* headlessContext() {
    static std::unique_ptr<gl::GlContext> ctx = [] {
        auto c = gl::createHeadlessContext();
        EXPECT_TRUE(c.ok()) << c.message();
        return c.ok() ? std::move(*c) : nullptr;
    }();
    if (ctx) ctx->makeCurrent();
    return ctx.get();
}

std::string readBytes(const std::filesystem::path& p) {
    std::ifstream f(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

void flipByte(const std::filesystem::path& p, std::uint64_t at, std::uint8_t mask) {
    std::fstream f(p, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(std::streamoff(at));
    char c = 0;
    f.read(&c, 1);
    c = char(c ^ char(mask));
    f.seekp(std::streamoff(at));
    f.write(&c, 1);
    EXPECT_TRUE(f.good()) << "cannot flip byte " << at << " of " << p;
}

std::vector<float> noiseHeights(std::size_t n, std::uint32_t seed, float base, float range) {
    std::vector<float> v(n);
    for (auto& h : v) {
        seed = seed * 1664525u + 1013904223u;
        h = base + float(seed >> 8) / float(1 << 24) * range;
    }
    return v;
}

std::vector<std::uint8_t> rgbOf(const std::vector<std::uint8_t>& rgba) {
    std::vector<std::uint8_t> rgb;
    rgb.reserve(rgba.size() / 4 * 3);
    for (size_t i = 0; i < rgba.size(); i += 4) rgb.insert(rgb.end(), {rgba[i], rgba[i + 1], rgba[i + 2]});
    return rgb;
}

ImageDiff compareRgb(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b, int w, int h,
                     int channels) {
    ImageDiff d;
    const size_t n = size_t(w) * size_t(h) * size_t(channels);
    d.sameSize = a.size() == n && b.size() == n;
    if (!d.sameSize) return d;
    double sum = 0, sq = 0;
    for (size_t i = 0; i < n; ++i) {
        const int delta = std::abs(int(a[i]) - int(b[i]));
        d.maxDelta = std::max(d.maxDelta, delta);
        sum += delta;
        sq += double(delta) * delta;
    }
    d.meanDelta = sum / double(n);
    const double mse = sq / double(n);
    d.psnr = mse == 0 ? INFINITY : 10.0 * std::log10(255.0 * 255.0 / mse);
    return d;
}

ImageDiff compareWithGolden(const std::string& name, const std::vector<std::uint8_t>& rgb, int w, int h, int maxTol,
                            double meanTol) {
    const std::filesystem::path golden = std::filesystem::path(SEASONVIEW_SOURCE_DIR) / "tests" / "golden" / (name + ".png");
    if (std::getenv("SEASONVIEW_UPDATE_GOLDEN")) {
        std::filesystem::create_directories(golden.parent_path());
        Status st = writeImageAtomic(golden, rgb.data(), w, h, 3);
        EXPECT_TRUE(st.ok()) << st.message();
    }
    ImageDiff d;
    auto expected = readImageU8(golden, 3);
    if (expected && expected->width == w && expected->height == h && expected->channels == 3)
        d = compareRgb(rgb, expected->pixels, w, h, 3);
    if (!d.sameSize || d.maxDelta > maxTol || d.meanDelta > meanTol) {
        const auto actual = outputDir() / (name + ".actual.png");
        (void)writeImageAtomic(actual, rgb.data(), w, h, 3);
        if (d.sameSize) {
            std::vector<std::uint8_t> diff(rgb.size());
            for (size_t i = 0; i < rgb.size(); ++i)
                diff[i] = std::uint8_t(std::min(255, 8 * std::abs(int(rgb[i]) - int(expected->pixels[i]))));
            (void)writeImageAtomic(outputDir() / (name + ".diff.png"), diff.data(), w, h, 3);
        }
        ADD_FAILURE() << "golden " << golden << (expected ? "" : " unreadable: " + expected.message())
                      << " mismatch: max " << d.maxDelta << " (tol " << maxTol << "), mean " << d.meanDelta
                      << " (tol " << meanTol << "); actual written to " << actual;
    }
    return d;
}

namespace {
std::string quote(const std::string& s) {
    std::string r = "'";
    for (char c : s) {
        if (c == '\'') r += "'\\''";
        else r += c;
    }
    return r + "'";
}
std::string slurp(const std::filesystem::path& p) {
    std::ifstream f(p);
    std::stringstream s;
    s << f.rdbuf();
    return s.str();
}
} // namespace

namespace {
CliResult runWithPrefix(const std::string& prefix, const std::vector<std::string>& args) {
    static int counter = 0;
    const auto base = outputDir() / ("cli-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
    std::string cmd = prefix + quote(SEASONVIEW_BINARY);
    for (const auto& a : args) cmd += " " + quote(a);
    cmd += " >" + quote(base.string() + ".out") + " 2>" + quote(base.string() + ".err") + " </dev/null";
    const int status = std::system(cmd.c_str());
    CliResult r;
    // system() runs sh -c; a child killed by a signal shows as 128+N from the shell.
    if (WIFEXITED(status)) r.exitCode = WEXITSTATUS(status);
    if (r.exitCode > 128) r.exitCode = -1;
    r.out = slurp(base.string() + ".out");
    r.err = slurp(base.string() + ".err");
    std::filesystem::remove(base.string() + ".out");
    std::filesystem::remove(base.string() + ".err");
    return r;
}
} // namespace

CliResult runCli(const std::vector<std::string>& args) { return runWithPrefix("", args); }

CliScene::CliScene(const std::string& name, const std::vector<std::string>& synthArgs, std::string size_,
                   std::string camera_)
    : dir(name), size(std::move(size_)), camera(std::move(camera_)) {
    std::vector<std::string> a = {"synth", "--out", (dir / "s").string()};
    a.insert(a.end(), synthArgs.begin(), synthArgs.end());
    const CliResult r = runCli(a);
    EXPECT_EQ(r.exitCode, 0) << r.err;
}

CliResult CliScene::render(const std::string& out, const std::vector<std::string>& extra) const {
    std::vector<std::string> a = {"render", (dir / "s/scene.json").string(), "--size", size, "--camera", camera,
                                  "--clip-size", "512", "--cache", (dir / "cache").string(), "--out", (dir / out).string()};
    a.insert(a.end(), extra.begin(), extra.end());
    return runCli(a);
}

Image<std::uint8_t> CliScene::image(const std::string& name) const {
    auto img = readImageU8(dir / name, 3);
    EXPECT_TRUE(img.ok()) << img.message();
    return img ? std::move(*img) : Image<std::uint8_t>{};
}

std::optional<CliResult> runCliWithDisplay(const std::vector<std::string>& args) {
    if (std::getenv("DISPLAY")) return runWithPrefix("", args);
    if (std::system("command -v xvfb-run >/dev/null 2>&1") != 0) return std::nullopt;
    return runWithPrefix("xvfb-run -a -s '-screen 0 1280x1024x24' ", args);
}

} // namespace seasonview::test
