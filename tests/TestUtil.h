#pragma once
// Shared test helpers: temp folders, small georeferenced test rasters, golden-image comparison, running the CLI,
// one headless GL context per test process.
#include "Raster.h"
#include "Scene.h"
#include "gl/GlContext.h"

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace seasonview::test {

/// build/tests/output: where tests write (actual and diff images on failure too).
std::filesystem::path outputDir();

/// A fresh folder under outputDir(), removed when the object dies (kept if SEASONVIEW_KEEP_TEST_FILES is set).
class TempDir {
public:
    explicit TempDir(const std::string& name);
    ~TempDir();
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;
    const std::filesystem::path& path() const { return m_path; }
    std::filesystem::path operator/(const std::string& f) const { return m_path / f; }

private:
    std::filesystem::path m_path;
};

/// A folder that the test processes of one build share, for a fixture that takes long to make and that the tests only
/// read (CTest runs each test in a process of its own, so a static fixture is made once per test): the first process
/// that asks makes outputDir()/shared/NAME by calling `make` on it while it holds a lock on NAME.lock, the others wait
/// for the lock and find it made. It is made again when seasonview or the test binary changed since (their sizes and
/// modification times are the stamp written last), or when an earlier `make` failed or was killed part way. `make`
/// returns whether it succeeded; on failure the folder is removed and nullopt returned.
std::optional<std::filesystem::path> sharedFixture(const std::string& name,
                                                   const std::function<bool(const std::filesystem::path&)>& make);

/// ../shared/data (or $SEASONVIEW_DATA) when present.
std::optional<std::filesystem::path> realDataDir();

/// A UTM 32N georef with `gsd` metres per pixel, top-left at (easting, northing).
Georef testGeoref(double gsd = 1.0, double easting = 405000.0, double northing = 5758000.0);

/// Writes a w×h RGB test image (8- or 16-bit) with a smooth pattern seeded by `seed`.
void writeTestImage(const std::filesystem::path& path, int w, int h, const Georef& g, bool sixteenBit = false,
                    int seed = 0);

/// How writeGdalRaster writes a fixture: any GDAL driver and creation options, georeferencing as a geotransform and
/// a CRS PROJ knows, and the ways real data marks pixels without data.
struct GdalRasterSpec {
    std::string driver = "GTiff";
    std::vector<std::string> creationOptions;    // e.g. "TILED=YES", "COMPRESS=JPEG", "PHOTOMETRIC=YCBCR"
    std::optional<std::array<double, 6>> geotransform; // GDAL order: x0, dx, 0, y0, 0, -dy
    std::string crs;                              // "EPSG:2154", WKT, ...; empty: none written
    std::optional<double> nodata;                 // every band's nodata value
    bool lastBandIsAlpha = false;                 // the last band's colour interpretation is alpha
    const std::uint8_t* mask = nullptr;           // w×h, 0 = no data: written as a per-dataset (internal) mask
};

/// Writes interleaved samples (w×h×bands of `type`) through GDAL (drivers without Create go through a MEM copy).
/// Fails the test on error.
void writeGdalRaster(const std::filesystem::path& path, const void* data, SampleType type, int w, int h, int bands,
                     const GdalRasterSpec& spec);

/// Runs GDAL's own utilities (gdal_utils.h) to make fixtures the way data providers make deliveries: gdalwarp,
/// gdal_translate and gdalbuildvrt with their command-line arguments (e.g. {"-t_srs", "EPSG:2154", "-tr", "0.5",
/// "0.5"}). Fail the test on error.
void gdalWarp(const std::filesystem::path& src, const std::filesystem::path& dst, const std::vector<std::string>& args);
void gdalTranslate(const std::filesystem::path& src, const std::filesystem::path& dst,
                   const std::vector<std::string>& args);
void gdalBuildVrt(const std::filesystem::path& dst, const std::vector<std::filesystem::path>& sources,
                  const std::vector<std::string>& args = {});

/// GDAL's geotransform of a georef (x0, dx, 0, y0, 0, -dy).
std::array<double, 6> geotransformOf(const Georef& g);

/// Writes on.tif and off.tif (w×h, `gsd` m/px, UTM 32N, seeds 1 and 2) into `dir` and loads them as a flat scene
/// (stretch cache in dir/cache).
Result<Scene> writeTestPair(const std::filesystem::path& dir, int w, int h, double gsd, bool sixteenBit = false);

/// A season pair delivered as tiles in dir/tiles, for manifests and flags that list tiles: makeTreePair(128, 96, 5) at
/// 0.5 m with testGeoref's corner (E 405000..405064, N 5757952..5758000, UTM 32N); the leaf-on as west and east halves
/// (on_w.tif, on_e.tif) with a geotransform but no CRS (they need --crs / "crs" EPSG:32632), the leaf-off as north and
/// south halves (off_n.tif, off_s.tif) in EPSG:32632. Fails the test on error.
void writeTiledTestPair(const std::filesystem::path& dir);

/// A hand-made season pair (8-bit RGB, row 0 on top) with its ground truth, for the segmentation tests. Leaf-on:
/// textured green crowns (lit and shaded sides, leaf clumps) on a meadow, and on the right a smooth crop field;
/// leaf-off: the crowns are grey-brown twigs, the meadow is still green, the crop field is bare brown soil (a
/// seasonal change that is no tree). `truth` is 255 on the crowns; `crowns` holds (centre x, centre y, radius) in
/// pixels, centres at pixel centres (x + 0.5).
struct TreePair {
    Image<std::uint8_t> on, off, truth;
    std::vector<std::array<double, 3>> crowns;
};
TreePair makeTreePair(int w, int h, int seed = 0);

/// The process's headless GL context, made current (nullptr, with a test failure, when EGL is unusable).
gl::GlContext* headlessContext();

/// The whole file as bytes ("" when unreadable).
std::string readBytes(const std::filesystem::path& p);

/// XORs the byte at offset `at` of a file with `mask`, in place (a bit flip on disk).
void flipByte(const std::filesystem::path& p, std::uint64_t at, std::uint8_t mask = 0x55);

/// `n` heights, uniform noise in [base, base + range) from `seed`: Zstandard stores such tiles mostly as raw literals.
std::vector<float> noiseHeights(std::size_t n, std::uint32_t seed, float base, float range);

/// RGBA rows -> RGB rows.
std::vector<std::uint8_t> rgbOf(const std::vector<std::uint8_t>& rgba);

struct ImageDiff {
    int maxDelta = 0;      // largest per-channel difference, 0..255
    double meanDelta = 0;  // mean per-channel difference
    double psnr = 0;       // dB (inf when identical)
    bool sameSize = false;
};
ImageDiff compareRgb(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b, int w, int h, int channels);

/// Compares an image with tests/golden/NAME.png. On mismatch (or when SEASONVIEW_UPDATE_GOLDEN is set, which
/// rewrites the golden) writes NAME.actual.png and NAME.diff.png into outputDir(). Returns the difference.
ImageDiff compareWithGolden(const std::string& name, const std::vector<std::uint8_t>& rgb, int w, int h, int maxTol,
                            double meanTol);

struct CliResult {
    int exitCode = -1; // -1: killed by a signal
    std::string out, err;
};
/// Runs the seasonview binary with `args` (shell-quoted here), capturing stdout and stderr.
CliResult runCli(const std::vector<std::string>& args);
/// A synthetic scene generated once (`synth` with `synthArgs`, into dir/s) that a CLI test renders at one size
/// and camera with per-call flags (`render`, cache in dir/cache, output dir/out).
struct CliScene {
    TempDir dir;
    std::string size, camera;
    CliScene(const std::string& name, const std::vector<std::string>& synthArgs, std::string size, std::string camera);
    CliResult render(const std::string& out, const std::vector<std::string>& extra) const;
    /// dir/name as RGB (a test failure, and an empty image, when unreadable).
    Image<std::uint8_t> image(const std::string& name) const;
};
/// The same with a display: directly when DISPLAY is set, else under `xvfb-run -a`; nothing when neither exists.
std::optional<CliResult> runCliWithDisplay(const std::vector<std::string>& args);

} // namespace seasonview::test
