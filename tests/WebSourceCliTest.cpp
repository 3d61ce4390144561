// Seasons and the DEM given as URLs (WebSource.h): read by HTTP range requests from a server on 127.0.0.1 that the
// test starts (HttpTestServer.h), drawn as the same files on disk draw, and every fault the server injects one line
// naming the URL, exit 1, no pyramid written.
#include "Crs.h"
#include "HttpTestServer.h"
#include "TestUtil.h"

#include <gdal.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <set>
#include <thread>

using namespace seasonview;
using namespace seasonview::test;

namespace {

namespace fs = std::filesystem;

/// A small synthetic scene (files on disk) served by a local server.
struct ServedScene {
    TempDir dir;
    fs::path scene;
    std::unique_ptr<HttpTestServer> server;
    explicit ServedScene(const std::string& name) : dir(name) {
        const CliResult synth = runCli({"synth", "--size-m", "256", "--gsd", "0.5", "--no-city", "--out",
                                        (dir / "s").string()});
        EXPECT_EQ(synth.exitCode, 0) << synth.err;
        scene = dir / "s";
        server = std::make_unique<HttpTestServer>(scene);
    }
    std::vector<std::string> urls() const {
        return {"--leafon", server->url() + "/leafon.tif", "--leafoff", server->url() + "/leafoff.tif", "--dem",
                server->url() + "/dem.tif"};
    }
    std::vector<std::string> files() const {
        return {"--leafon", (scene / "leafon.tif").string(), "--leafoff", (scene / "leafoff.tif").string(), "--dem",
                (scene / "dem.tif").string()};
    }
    CliResult run(std::vector<std::string> args, const std::vector<std::string>& inputs, const std::string& cache) const {
        args.insert(args.end(), inputs.begin(), inputs.end());
        args.insert(args.end(), {"--cache", (dir / cache).string()});
        return runCli(args);
    }
};

/// Bytes of `path` the server sent in answer to range requests.
long long rangeBytes(const std::vector<HttpTestServer::Request>& requests, const std::string& path = {}) {
    long long bytes = 0;
    for (const auto& r : requests) {
        if ((!path.empty() && r.path != path) || r.range.empty()) continue;
        bytes += std::atoll(r.range.c_str() + r.range.find('-') + 1) - std::atoll(r.range.c_str() + 6) + 1;
    }
    return bytes;
}

/// The picture drawn from the web as the one drawn from disk (PSNR >= 45 dB).
void expectSameRender(const fs::path& disk, const fs::path& web) {
    auto da = readImageU8(disk, 3), db = readImageU8(web, 3);
    ASSERT_TRUE(da.ok() && db.ok());
    const ImageDiff d = compareRgb(da->pixels, db->pixels, da->width, da->height, 3);
    ASSERT_TRUE(d.sameSize);
    EXPECT_GE(d.psnr, 45.0) << "max delta " << d.maxDelta;
}

void writeText(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

bool hasPyramid(const fs::path& cache) {
    std::error_code ec;
    for (fs::recursive_directory_iterator it(cache, ec), end; !ec && it != end; it.increment(ec))
        if (it->path().filename() == "pyramid.json") return true;
    return false;
}

} // namespace

TEST(WebSourceCliTest, SeasonsAndDemByUrlDrawAsTheFilesOnDisk) {
    ServedScene s("web-same");
    ASSERT_TRUE(fs::exists(s.scene / "leafon.tif"));
    const std::vector<std::string> render = {"render", "--camera", "0,-150,+120,20,-40", "--size", "320x240",
                                             "--view", "swipe"};
    std::vector<std::string> disk = render, web = render;
    disk.insert(disk.end(), {"--out", (s.dir / "disk.png").string()});
    web.insert(web.end(), {"--out", (s.dir / "web.png").string()});
    const CliResult a = s.run(disk, s.files(), "cache_disk");
    ASSERT_EQ(a.exitCode, 0) << a.err;
    const CliResult b = s.run(web, s.urls(), "cache_web");
    ASSERT_EQ(b.exitCode, 0) << b.err;
    expectSameRender(s.dir / "disk.png", s.dir / "web.png");

    // Range requests only, each naming seasonview; the file asked for by HEAD first.
    const auto requests = s.server->requests();
    ASSERT_FALSE(requests.empty());
    for (const auto& r : requests) {
        EXPECT_EQ(r.userAgent.rfind("seasonview/", 0), 0u) << r.method << " " << r.path << " " << r.userAgent;
        EXPECT_TRUE(r.method == "HEAD" || !r.range.empty()) << r.method << " " << r.path << " without a range";
    }
    EXPECT_TRUE(std::any_of(requests.begin(), requests.end(), [](const auto& r) { return r.method == "HEAD"; }));
    EXPECT_LE(s.server->maxConcurrent(), 4) << "connections open at once to one host";

    // The seasons' pyramids are cached: the same render again asks whether the files changed (HEAD) and reads their
    // headers and tile directories, not their tiles. (The DEM, like a DEM on disk, is read onto the scene's area
    // whenever the scene opens.)
    s.server->clearRequests();
    const CliResult c = s.run(web, s.urls(), "cache_web");
    ASSERT_EQ(c.exitCode, 0) << c.err;
    for (const std::string season : {"/leafon.tif", "/leafoff.tif"})
        EXPECT_LT(rangeBytes(s.server->requests(), season), (long long)fs::file_size(s.scene / season.substr(1)) / 4)
            << season;
}

TEST(WebSourceCliTest, ServerFaultsAreOneLineNamingTheUrl) {
    ServedScene s("web-faults");
    ASSERT_TRUE(fs::exists(s.scene / "leafon.tif"));
    const std::string leafon = s.server->url() + "/leafon.tif";
    struct Case {
        const char* what;
        HttpTestServer::Fault fault;
        std::string expect;
    };
    HttpTestServer::Fault notFound, serverError, html, reset, cut;
    notFound.status = 404;
    serverError.status = 500;
    html.html = true;
    reset.reset = true;
    cut.cutAt = 100;
    const std::vector<Case> cases = {
        {"404", notFound, leafon + ": HTTP 404"},
        {"500", serverError, leafon + ": HTTP 500"},
        {"an HTML page", html, leafon + ": the server answers with a web page (text/html), not a raster"},
        {"a connection reset", reset, leafon + ": no answer from the server"},
        {"bodies cut short", cut, leafon + ": not a readable image"},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.what);
        s.server->clearFaults();
        s.server->setFault("/leafon.tif", c.fault);
        const std::string cache = std::string("cache_") + c.what;
        const CliResult r = s.run({"prepare"}, s.urls(), cache);
        EXPECT_EQ(r.exitCode, 1) << r.out << r.err;
        EXPECT_NE(r.err.find(c.expect), std::string::npos) << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
        EXPECT_FALSE(hasPyramid(s.dir / cache)) << "a pyramid was written from a faulty answer";
    }
    // The same server healthy again, if slow (every answer after 300 ms): prepared.
    s.server->clearFaults();
    HttpTestServer::Fault slow;
    slow.latencyMs = 300;
    s.server->setFault("*", slow);
    const CliResult ok = s.run({"prepare"}, s.urls(), "cache_ok");
    EXPECT_EQ(ok.exitCode, 0) << ok.err;
    EXPECT_TRUE(hasPyramid(s.dir / "cache_ok"));
}

TEST(WebSourceCliTest, TooManyRequestsWaitsAsTheServerSays) {
    // 429 with Retry-After: 3 to the first HEAD: asked again after the 3 s the server names (not the 1 s of the
    // default backoff), then read as usual.
    ServedScene s("web-429");
    HttpTestServer::Fault busy;
    busy.status = 429;
    busy.retryAfterS = 3;
    busy.times = 1;
    s.server->setFault("/leafon.tif", busy);
    const CliResult r = s.run({"render", "--size", "160x120", "--out", (s.dir / "web.png").string()}, s.urls(), "cache");
    ASSERT_EQ(r.exitCode, 0) << r.err;
    std::vector<std::chrono::steady_clock::time_point> heads;
    for (const auto& q : s.server->requests())
        if (q.path == "/leafon.tif" && q.method == "HEAD") heads.push_back(q.at);
    ASSERT_GE(heads.size(), 2u);
    EXPECT_GE(std::chrono::duration<double>(heads[1] - heads[0]).count(), 2.5) << "Retry-After not waited for";
}

TEST(WebSourceCliTest, RealSaclayCogByUrlDrawsAsTheFile) {
    const auto data = realDataDir();
    const fs::path s = data ? *data / "seasons/saclay_w_delivered" : fs::path();
    if (!data || !fs::exists(s / "leafon_3857_cog.tif"))
        GTEST_SKIP() << "real data not found (../shared/data/seasons/saclay_w_delivered)";
    TempDir dir("web-saclay-cog");
    HttpTestServer server(s);
    // The delivered leaf-on (an RGBA Web Mercator COG) from the server and from disk, the leaf-off Lambert-93 tiles
    // from disk, on the leaf-on's own grid.
    const auto render = [&](const std::string& leafon, const std::string& out) {
        return runCli({"render", "--leafon", leafon, "--leafoff", (s / "leafoff_L93_tiles").string(), "--view", "swipe",
                       "--size", "320x320", "--cache", (dir / ("cache_" + out)).string(), "--out",
                       (dir / (out + ".png")).string()});
    };
    const CliResult a = render((s / "leafon_3857_cog.tif").string(), "disk");
    ASSERT_EQ(a.exitCode, 0) << a.err;
    const CliResult b = render(server.url() + "/leafon_3857_cog.tif", "web");
    ASSERT_EQ(b.exitCode, 0) << b.err;
    expectSameRender(dir / "disk.png", dir / "web.png");
    std::printf("Saclay COG by URL: %zu requests, %lld bytes of %lld, at most %d at once\n", server.requests().size(),
                rangeBytes(server.requests()), (long long)fs::file_size(s / "leafon_3857_cog.tif"),
                server.maxConcurrent());
    EXPECT_LE(server.maxConcurrent(), 4) << "connections open at once to one host";
    // Each tile fetched once (its colour and alpha in one read).
    std::set<std::string> ranges;
    for (const auto& r : server.requests()) {
        if (!r.range.empty()) {
            EXPECT_TRUE(ranges.insert(r.range).second) << r.range << " fetched twice";
        }
    }
    EXPECT_LE(rangeBytes(server.requests()), (long long)fs::file_size(s / "leafon_3857_cog.tif"));
}

TEST(WebSourceCliTest, RealSaclayXyzTilesDrawAsTheSameTilesOnDisk) {
    // The delivered leaf-on as an XYZ pyramid (gdal2tiles, zoom 10-15) served, read over the Lambert-93 leaf-off's
    // footprint at its 8 m (zoom 14), against the zoom-14 tiles on disk, each georeferenced as its tile: a mosaic.
    const auto data = realDataDir();
    const fs::path s = data ? *data / "seasons/saclay_w_delivered" : fs::path();
    if (!data || !fs::exists(s / "leafon_xyz/14"))
        GTEST_SKIP() << "real data not found (../shared/data/seasons/saclay_w_delivered/leafon_xyz)";
    TempDir dir("web-saclay-xyz");
    const double half = 20037508.342789244, t = 2.0 * half / double(1 << 14);
    const auto num = [](double v) {
        char b[40];
        std::snprintf(b, sizeof b, "%.10f", v);
        return std::string(b);
    };
    int tiles = 0;
    for (const auto& e : fs::recursive_directory_iterator(s / "leafon_xyz/14")) {
        if (e.path().extension() != ".png") continue;
        const long long x = std::atoll(e.path().parent_path().filename().c_str()), y = std::atoll(e.path().stem().c_str());
        fs::create_directories(dir / "disk");
        gdalTranslate(e.path(), dir / "disk" / (std::to_string(x) + "_" + std::to_string(y) + ".tif"),
                      {"-a_srs", "EPSG:3857", "-a_ullr", num(-half + double(x) * t), num(half - double(y) * t),
                       num(-half + double(x + 1) * t), num(half - double(y + 1) * t)});
        ++tiles;
    }
    ASSERT_GT(tiles, 4);
    HttpTestServer server(s / "leafon_xyz");
    const auto render = [&](const std::string& leafon, const std::string& out) {
        return runCli({"render", "--leafon", leafon, "--leafoff", (s / "leafoff_L93_tiles").string(), "--extent-of",
                       "leafoff", "--view", "swipe", "--size", "320x320", "--cache", (dir / ("cache_" + out)).string(),
                       "--out", (dir / (out + ".png")).string()});
    };
    const CliResult a = render((dir / "disk").string(), "disk");
    ASSERT_EQ(a.exitCode, 0) << a.err;
    const CliResult b = render(server.url() + "/{z}/{x}/{y}.png", "web");
    ASSERT_EQ(b.exitCode, 0) << b.err;
    expectSameRender(dir / "disk.png", dir / "web.png");
    const auto requests = server.requests();
    EXPECT_TRUE(std::any_of(requests.begin(), requests.end(), [](const auto& r) { return r.path.rfind("/14/", 0) == 0; }));
    EXPECT_FALSE(std::any_of(requests.begin(), requests.end(), [](const auto& r) { return r.path.rfind("/15/", 0) == 0; }))
        << "zoom 15 is finer than the leaf-off's 8 m";
}

TEST(WebSourceCliTest, StreamedSeasonDrawsAsThePreparedOne) {
    // --stream: the Saclay leaf-on service read over the leaf-off's footprint at 2 m (4531x6286: levels 0 and 1 wider
    // than the 2048 texels prepared, so streamed block by block from the loader's thread, each at its own zoom), drawn
    // as the same season prepared whole.
    const auto data = realDataDir();
    const fs::path s = data ? *data / "seasons/saclay_w_delivered" : fs::path();
    if (!data || !fs::exists(s / "leafon_xyz/15"))
        GTEST_SKIP() << "real data not found (../shared/data/seasons/saclay_w_delivered/leafon_xyz)";
    TempDir dir("web-stream");
    HttpTestServer server(s / "leafon_xyz");
    const std::string service = server.url() + "/{z}/{x}/{y}.png";
    const auto render = [&](const std::string& out, const std::string& cache, std::vector<std::string> extra) {
        std::vector<std::string> args = {"render", "--leafon", service, "--leafoff", (s / "leafoff_L93_tiles").string(),
                                         "--extent-of", "leafoff", "--grid-res", "2", "--view", "leafon", "--size",
                                         "480x360", "--camera", "0,-2500,+1500,0,-35", "--cache",
                                         (dir.path() / cache).string(), "--out", (dir.path() / (out + ".png")).string()};
        args.insert(args.end(), extra.begin(), extra.end());
        return runCli(args);
    };
    const CliResult prepared = render("prepared", "cache_prepared", {});
    ASSERT_EQ(prepared.exitCode, 0) << prepared.err;
    server.clearRequests();
    const CliResult streamed = render("streamed", "cache_streamed", {"--stream"});
    ASSERT_EQ(streamed.exitCode, 0) << streamed.err;
    expectSameRender(dir.path() / "prepared.png", dir.path() / "streamed.png");
    EXPECT_FALSE(server.requests().empty());
    EXPECT_LE(server.maxConcurrent(), 4) << "connections open at once to one host";

    // What it fetched is cached: the same view again, and offline, asks for nothing.
    server.clearRequests();
    const CliResult again = render("again", "cache_streamed", {"--stream"});
    ASSERT_EQ(again.exitCode, 0) << again.err;
    EXPECT_TRUE(server.requests().empty()) << server.requests().size() << " requests, the first "
                                           << server.requests().front().path;
    const CliResult offline = render("offline", "cache_streamed", {"--stream", "--offline"});
    ASSERT_EQ(offline.exitCode, 0) << offline.err;
    EXPECT_TRUE(server.requests().empty()) << server.requests().size() << " requests";
    expectSameRender(dir.path() / "prepared.png", dir.path() / "offline.png");

    // A tile of a streamed level failing (the tile cache emptied at the start: --web-cache-mb bounds it; the prepared
    // coarse levels stay): the still is not written, and the one line names the tile's URL and status.
    HttpTestServer::Fault down, html, cut;
    down.status = 500;
    html.html = true;
    cut.cutAt = 100;
    const std::pair<HttpTestServer::Fault, std::string> faults[] = {
        {down, "HTTP 500"}, {html, "web page"}, {cut, ""}};
    for (const auto& [fault, expect] : faults) {
        SCOPED_TRACE(expect.empty() ? "bodies cut short" : expect);
        server.clearFaults();
        server.setFault("*", fault);
        const CliResult failed = render("failed", "cache_streamed", {"--stream", "--web-cache-mb", "0.001"});
        EXPECT_EQ(failed.exitCode, 1);
        EXPECT_NE(failed.err.find(server.url() + "/15/"), std::string::npos) << failed.err;
        EXPECT_NE(failed.err.find(expect), std::string::npos) << failed.err;
        EXPECT_EQ(std::count(failed.err.begin(), failed.err.end(), '\n'), 1) << failed.err;
        EXPECT_FALSE(fs::exists(dir.path() / "failed.png"));
    }
    server.clearFaults();

    // The bench draws the same path from both, interleaved, in one run: the figures of each, no stream error.
    const CliResult bench = runCli({"bench", "--leafon", service, "--leafoff", (s / "leafoff_L93_tiles").string(),
                                    "--extent-of", "leafoff", "--grid-res", "2", "--compare", "source=prepared,stream",
                                    "--size", "160x120", "--frames", "4", "--warmup", "1", "--cache",
                                    (dir.path() / "cache_bench").string(), "--out", (dir.path() / "bench").string()});
    ASSERT_EQ(bench.exitCode, 0) << bench.err;
    std::ifstream summaryFile(dir.path() / "bench/summary.json");
    const auto summary = nlohmann::json::parse(summaryFile, nullptr, false);
    ASSERT_TRUE(summary.is_object() && summary.contains("modes"));
    // The streamed tiles: those under the blocks read, their bytes in the disk cache, against what was fetched.
    const auto& stream = summary["stream"];
    ASSERT_TRUE(stream.is_object()) << summary.dump();
    EXPECT_GT(stream["tiles_needed"].get<long long>(), 0);
    EXPECT_GT(stream["bytes_needed"].get<long long>(), 0);
    long long cached = 0; // every tile file in the cache: the needed ones are among them
    for (const auto& e : fs::recursive_directory_iterator(dir.path() / "cache_bench/web/tiles"))
        if (e.is_regular_file()) cached += (long long)e.file_size();
    EXPECT_LE(stream["bytes_needed"].get<long long>(), cached);
    EXPECT_EQ(stream["tiles_needed_not_cached"].get<long long>(), 0) << "every tile under the blocks read is cached";
    // (The prepared mode fetched the same service's tiles first, so the run itself may fetch none.)
    ASSERT_TRUE(stream["bytes_fetched_over_needed"].is_number()) << stream.dump();
    EXPECT_DOUBLE_EQ(stream["bytes_fetched_over_needed"].get<double>(),
                     double(stream["bytes_fetched"].get<long long>()) / double(stream["bytes_needed"].get<long long>()));
    for (const char* mode : {"source=prepared", "source=stream"}) {
        ASSERT_TRUE(summary["modes"].contains(mode)) << mode;
        EXPECT_EQ(summary["modes"][mode]["totals"]["stream_errors"], 0) << mode;
        EXPECT_GT(summary["modes"][mode]["coverage_mean"].get<double>(), 0.5) << mode;
    }
    const CliResult noService = runCli({"bench", "--leafon", (s / "leafoff_L93_tiles").string(), "--leafoff",
                                        (s / "leafoff_L93_tiles").string(), "--compare", "source=prepared,stream",
                                        "--frames", "2", "--cache", (dir.path() / "cache_bench").string(), "--out",
                                        (dir.path() / "bench2").string()});
    EXPECT_EQ(noService.exitCode, 1);
    EXPECT_NE(noService.err.find("neither season is a tile service"), std::string::npos) << noService.err;

    // What reads every full-resolution texel refuses a streamed season, in one line.
    const CliResult segment = runCli({"segment", "--leafon", service, "--leafoff", (s / "leafoff_L93_tiles").string(),
                                      "--extent-of", "leafoff", "--stream", "--cache",
                                      (dir.path() / "cache_streamed").string(), "--out",
                                      (dir.path() / "mask.png").string()});
    EXPECT_EQ(segment.exitCode, 1);
    EXPECT_NE(segment.err.find("--stream"), std::string::npos) << segment.err;
    EXPECT_EQ(std::count(segment.err.begin(), segment.err.end(), '\n'), 1) << segment.err;

    // The server gone (connections refused), the streamed tiles not in the cache: one line naming a tile, no picture.
    server.stop();
    const CliResult gone = render("gone", "cache_streamed", {"--stream", "--web-cache-mb", "0.001"});
    EXPECT_EQ(gone.exitCode, 1);
    EXPECT_NE(gone.err.find(server.url() + "/15/"), std::string::npos) << gone.err;
    EXPECT_EQ(std::count(gone.err.begin(), gone.err.end(), '\n'), 1) << gone.err;
    EXPECT_FALSE(fs::exists(dir.path() / "gone.png"));
}

namespace {

/// The synthetic leaf-on cut into 256² PNG tiles of Web Mercator at zoom 17 under dir/tiles/17/x/y.png (XYZ rows)
/// and dir/tms/17/x/y.png (TMS rows), next to the same pixels as one GeoTIFF (merc), and the leaf-off's footprint.
struct MercatorTiles {
    fs::path merc;
    long long x0 = 0, x1 = 0, y0 = 0, y1 = 0;
    std::string lonLat; // the leaf-off's footprint "W,S,E,N" in degrees
};

MercatorTiles makeTiles(const ServedScene& s) {
    MercatorTiles m;
    auto info = readRasterInfo(s.scene / "leafoff.tif");
    EXPECT_TRUE(info.ok() && info->georef) << info.message();
    if (!info.ok() || !info->georef) return m;
    const Georef& g = *info->georef;
    auto mercator = Crs::fromEpsg(3857);
    EXPECT_TRUE(mercator.ok());
    const glm::dvec2 lo(g.origin.x, g.origin.y - g.pixelSize.y * info->height);
    const glm::dvec2 hi(g.origin.x + g.pixelSize.x * info->width, g.origin.y);
    std::vector<glm::dvec2> pts;
    for (int i = 0; i <= 4; ++i)
        for (int k = 0; k <= 4; ++k) pts.push_back(lo + (hi - lo) * glm::dvec2(i / 4.0, k / 4.0));
    std::vector<glm::dvec2> deg = pts;
    convert(g.crs, *mercator, pts);
    convert(g.crs, Crs::geographic(), deg);
    const double half = 20037508.342789244, t = 2.0 * half / double(1 << 17);
    double minX = 1e300, maxX = -1e300, minY = 1e300, maxY = -1e300;
    for (const auto& p : pts) minX = std::min(minX, p.x), maxX = std::max(maxX, p.x), minY = std::min(minY, p.y), maxY = std::max(maxY, p.y);
    m.x0 = (long long)std::floor((minX + half) / t), m.x1 = (long long)std::floor((maxX + half) / t - 1e-9);
    m.y0 = (long long)std::floor((half - maxY) / t), m.y1 = (long long)std::floor((half - minY) / t - 1e-9);
    const auto num = [](double v) {
        char b[40];
        std::snprintf(b, sizeof b, "%.10f", v);
        return std::string(b);
    };
    double w = 1e300, e = -1e300, so = 1e300, n = -1e300;
    for (const auto& p : deg) w = std::min(w, p.x), e = std::max(e, p.x), so = std::min(so, p.y), n = std::max(n, p.y);
    m.lonLat = num(w) + "," + num(so) + "," + num(e) + "," + num(n);
    m.merc = s.dir / "leafon_3857.tif";
    gdalWarp(s.scene / "leafon.tif", m.merc,
             {"-t_srs", "EPSG:3857", "-tr", num(t / 256), num(t / 256), "-te", num(-half + double(m.x0) * t),
              num(half - double(m.y1 + 1) * t), num(-half + double(m.x1 + 1) * t), num(half - double(m.y0) * t), "-r",
              "bilinear", "-dstalpha", "-co", "TILED=YES"});
    for (long long x = m.x0; x <= m.x1; ++x)
        for (long long y = m.y0; y <= m.y1; ++y) {
            const fs::path tile = s.dir / "tiles/17" / std::to_string(x) / (std::to_string(y) + ".png");
            fs::create_directories(tile.parent_path());
            gdalTranslate(m.merc, tile,
                          {"-of", "PNG", "-srcwin", std::to_string((x - m.x0) * 256), std::to_string((y - m.y0) * 256),
                           "256", "256"});
            const fs::path tms = s.dir / "tms/17" / std::to_string(x) / (std::to_string((1LL << 17) - 1 - y) + ".png");
            fs::create_directories(tms.parent_path());
            fs::copy_file(tile, tms);
        }
    return m;
}

} // namespace

TEST(WebSourceCliTest, XyzTileServiceDrawsAsTheSamePixelsOnDisk) {
    // The synthetic leaf-on as a tile server serves it, next to the same pixels as one GeoTIFF. The service is read
    // over the leaf-off's footprint at the leaf-off's pixel size (0.5 m: zoom 18, which the server does not have,
    // so 17).
    ServedScene s("web-xyz");
    ASSERT_TRUE(fs::exists(s.scene / "leafon.tif"));
    const MercatorTiles m = makeTiles(s);
    ASSERT_FALSE(m.merc.empty());
    const fs::path merc = m.merc;
    const long long x0 = m.x0, y0 = m.y0;
    HttpTestServer tiles(s.dir / "tiles");
    const auto render = [&](const std::string& leafon, const std::string& name) {
        return runCli({"render", "--leafon", leafon, "--leafoff", (s.scene / "leafoff.tif").string(), "--dem",
                       (s.scene / "dem.tif").string(), "--camera", "0,-150,+120,20,-40", "--size", "320x240", "--view",
                       "swipe", "--cache", (s.dir / ("cache_" + name)).string(), "--out",
                       (s.dir / (name + ".png")).string()});
    };
    const CliResult a = render(merc.string(), "disk");
    ASSERT_EQ(a.exitCode, 0) << a.err;
    const CliResult b = render(tiles.url() + "/{z}/{x}/{y}.png", "web");
    ASSERT_EQ(b.exitCode, 0) << b.err;
    expectSameRender(s.dir / "disk.png", s.dir / "web.png");
    const auto first = tiles.requests();
    EXPECT_TRUE(std::any_of(first.begin(), first.end(), [](const auto& r) { return r.path.rfind("/18/", 0) == 0; }))
        << "zoom 18 asked for first";
    for (const auto& r : first) EXPECT_EQ(r.userAgent.rfind("seasonview/", 0), 0u) << r.path;
    EXPECT_LE(tiles.maxConcurrent(), 4) << "connections open at once to one host";

    // Tiles are cached: the same render again fetches none.
    tiles.clearRequests();
    const CliResult c = render(tiles.url() + "/{z}/{x}/{y}.png", "web");
    ASSERT_EQ(c.exitCode, 0) << c.err;
    EXPECT_TRUE(tiles.requests().empty()) << tiles.requests().size() << " requests, the first " << tiles.requests().front().path;

    // A service that fails: one line naming the tile's URL.
    HttpTestServer::Fault down;
    down.status = 500;
    tiles.setFault("*", down);
    const CliResult e = render(tiles.url() + "/{z}/{x}/{y}.png", "down");
    EXPECT_EQ(e.exitCode, 1);
    EXPECT_NE(e.err.find(tiles.url() + "/18/"), std::string::npos) << e.err;
    EXPECT_NE(e.err.find("HTTP 500"), std::string::npos) << e.err;
    EXPECT_EQ(std::count(e.err.begin(), e.err.end(), '\n'), 1) << e.err;

    // One tile failing while the season is read: one line naming the tile's URL and the status, and no picture.
    tiles.clearFaults();
    const std::string corner = "/17/" + std::to_string(x0) + "/" + std::to_string(y0) + ".png";
    tiles.setFault(corner, down);
    const CliResult f = render(tiles.url() + "/{z}/{x}/{y}.png", "tile");
    EXPECT_EQ(f.exitCode, 1);
    EXPECT_NE(f.err.find(tiles.url() + corner + ": HTTP 500"), std::string::npos) << f.err;
    EXPECT_EQ(std::count(f.err.begin(), f.err.end(), '\n'), 1) << f.err;
    EXPECT_FALSE(fs::exists(s.dir / "tile.png"));
    tiles.clearFaults();
    // A tile whose body is cut short (GDAL names only the rows it could not decode): the same, naming the tile.
    HttpTestServer::Fault cut;
    cut.cutAt = 100;
    tiles.setFault(corner, cut);
    const CliResult g = render(tiles.url() + "/{z}/{x}/{y}.png", "cut");
    EXPECT_EQ(g.exitCode, 1);
    EXPECT_NE(g.err.find(tiles.url() + corner + ": "), std::string::npos) << g.err;
    EXPECT_EQ(std::count(g.err.begin(), g.err.end(), '\n'), 1) << g.err;
    EXPECT_FALSE(fs::exists(s.dir / "cut.png"));
    tiles.clearFaults();
    // A busy server: 429 with Retry-After: 2 to GDAL's request for one tile and to the request asking why. GDAL fails
    // the block at once; the read is made again after the 2 s the server names, and draws as from disk.
    HttpTestServer::Fault busy;
    busy.status = 429;
    busy.retryAfterS = 2;
    busy.times = 2;
    tiles.clearRequests();
    tiles.setFault(corner, busy);
    const CliResult h = render(tiles.url() + "/{z}/{x}/{y}.png", "busy");
    ASSERT_EQ(h.exitCode, 0) << h.err;
    expectSameRender(s.dir / "disk.png", s.dir / "busy.png");
    std::vector<std::chrono::steady_clock::time_point> gets;
    for (const auto& q : tiles.requests())
        if (q.path == corner && q.method == "GET") gets.push_back(q.at);
    ASSERT_EQ(gets.size(), 3u) << "the tile, the question why, the tile again";
    EXPECT_GE(std::chrono::duration<double>(gets[2] - gets[1]).count(), 1.8) << "Retry-After not waited for";
    tiles.clearFaults();

    // Offline: the same render from the disk cache alone, no request; a cache that never saw the service is one line.
    tiles.clearRequests();
    const CliResult offline = runCli({"render", "--leafon", tiles.url() + "/{z}/{x}/{y}.png", "--leafoff",
                                      (s.scene / "leafoff.tif").string(), "--dem", (s.scene / "dem.tif").string(),
                                      "--camera", "0,-150,+120,20,-40", "--size", "320x240", "--view", "swipe",
                                      "--cache", (s.dir / "cache_web").string(), "--offline", "--out",
                                      (s.dir / "offline.png").string()});
    ASSERT_EQ(offline.exitCode, 0) << offline.err;
    EXPECT_TRUE(tiles.requests().empty()) << tiles.requests().size() << " requests";
    expectSameRender(s.dir / "disk.png", s.dir / "offline.png");
    const CliResult cold = runCli({"render", "--leafon", tiles.url() + "/{z}/{x}/{y}.png", "--leafoff",
                                   (s.scene / "leafoff.tif").string(), "--cache", (s.dir / "cache_cold").string(),
                                   "--offline", "--out", (s.dir / "cold.png").string()});
    EXPECT_EQ(cold.exitCode, 1);
    EXPECT_NE(cold.err.find("not in the cache (--offline)"), std::string::npos) << cold.err;
    EXPECT_EQ(std::count(cold.err.begin(), cold.err.end(), '\n'), 1) << cold.err;
    EXPECT_FALSE(fs::exists(s.dir / "cold.png"));
    EXPECT_TRUE(tiles.requests().empty()) << tiles.requests().size() << " requests";

    // The tile cache's bound (--web-cache-mb), kept from the start of a run: the pyramid made from the tiles stays.
    const auto tileBytes = [&] {
        long long bytes = 0;
        for (const auto& entry : fs::recursive_directory_iterator(s.dir / "cache_web/web/tiles"))
            if (entry.is_regular_file()) bytes += (long long)entry.file_size();
        return bytes;
    };
    const long long before = tileBytes();
    const CliResult bounded = runCli({"render", "--leafon", tiles.url() + "/{z}/{x}/{y}.png", "--leafoff",
                                      (s.scene / "leafoff.tif").string(), "--dem", (s.scene / "dem.tif").string(),
                                      "--camera", "0,-150,+120,20,-40", "--size", "320x240", "--view", "swipe",
                                      "--cache", (s.dir / "cache_web").string(), "--offline", "--web-cache-mb", "0.1",
                                      "--out", (s.dir / "bounded.png").string()});
    ASSERT_EQ(bounded.exitCode, 0) << bounded.err;
    expectSameRender(s.dir / "disk.png", s.dir / "bounded.png");
    EXPECT_GT(before, 104857) << "the tiles fetched fit the bound already: the check below proves nothing";
    EXPECT_LE(tileBytes(), 104857);
    EXPECT_GT(tileBytes(), 0);

    // Not readable without an area: one line.
    const CliResult both = runCli({"render", "--leafon", tiles.url() + "/{z}/{x}/{y}.png", "--leafoff",
                                   tiles.url() + "/{z}/{x}/{y}.png", "--cache", (s.dir / "cache_both").string(),
                                   "--out", (s.dir / "both.png").string()});
    EXPECT_EQ(both.exitCode, 1);
    EXPECT_NE(both.err.find("both seasons are tile services"), std::string::npos) << both.err;
    EXPECT_FALSE(fs::exists(s.dir / "both.png"));
}

TEST(WebSourceCliTest, TmsRowsAndAnExtentInDegreesDrawAsTheSamePixelsOnDisk) {
    // The same tiles numbered from the bottom (TMS, {-y}); then both seasons from the service, read over an extent
    // given in degrees at a pixel size given in the grid's CRS, drawn as the same pixels on disk on the same grid.
    ServedScene s("web-tms");
    const MercatorTiles m = makeTiles(s);
    ASSERT_FALSE(m.merc.empty());
    HttpTestServer tms(s.dir / "tms");
    HttpTestServer xyz(s.dir / "tiles");
    const auto render = [&](const std::vector<std::string>& inputs, const std::string& name) {
        std::vector<std::string> args = {"render", "--dem", (s.scene / "dem.tif").string(), "--camera",
                                         "0,-150,+120,20,-40", "--size", "320x240", "--view", "swipe", "--cache",
                                         (s.dir / ("cache_" + name)).string(), "--out", (s.dir / (name + ".png")).string()};
        args.insert(args.end(), inputs.begin(), inputs.end());
        return runCli(args);
    };
    const std::string leafoff = (s.scene / "leafoff.tif").string();
    const CliResult a = render({"--leafon", m.merc.string(), "--leafoff", leafoff}, "disk");
    ASSERT_EQ(a.exitCode, 0) << a.err;
    const CliResult b = render({"--leafon", tms.url() + "/{z}/{x}/{-y}.png", "--leafoff", leafoff}, "tms");
    ASSERT_EQ(b.exitCode, 0) << b.err;
    expectSameRender(s.dir / "disk.png", s.dir / "tms.png");
    const auto requests = tms.requests();
    ASSERT_FALSE(requests.empty());
    for (const auto& r : requests)
        if (r.path.rfind("/17/", 0) == 0) {
            EXPECT_TRUE(fs::exists(s.dir / "tms" / r.path.substr(1))) << r.path;
        }
    // A tile failing while read: one line naming it, its row counted from the bottom.
    const std::string corner = "/17/" + std::to_string(m.x1) + "/" + std::to_string((1LL << 17) - 1 - m.y1) + ".png";
    HttpTestServer::Fault down;
    down.status = 500;
    tms.setFault(corner, down);
    const CliResult bad = render({"--leafon", tms.url() + "/{z}/{x}/{-y}.png", "--leafoff", leafoff}, "tmsdown");
    EXPECT_EQ(bad.exitCode, 1);
    EXPECT_NE(bad.err.find(tms.url() + corner + ": HTTP 500"), std::string::npos) << bad.err;
    EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << bad.err;
    tms.clearFaults();

    // Both seasons from services: the area is --extent in degrees (the leaf-off's footprint), the pixel size
    // --grid-res in the grid's CRS (Web Mercator, the leaf-on's). The same on disk: the same pixels as GeoTIFFs.
    const std::vector<std::string> grid = {"--extent", m.lonLat, "--grid-res", "1.1"};
    std::vector<std::string> disk = {"--leafon", m.merc.string(), "--leafoff", m.merc.string()};
    disk.insert(disk.end(), grid.begin(), grid.end());
    const CliResult c = render(disk, "disk2");
    ASSERT_EQ(c.exitCode, 0) << c.err;
    std::vector<std::string> web = {"--leafon", xyz.url() + "/{z}/{x}/{y}.png", "--leafoff",
                                    tms.url() + "/{z}/{x}/{-y}.png"};
    web.insert(web.end(), grid.begin(), grid.end());
    const CliResult d = render(web, "both");
    ASSERT_EQ(d.exitCode, 0) << d.err;
    expectSameRender(s.dir / "disk2.png", s.dir / "both.png");

    // The same extent named by an input (--extent-of dem) reads the DEM's footprint; --extent-of a service and both
    // extents at once are one line each.
    std::vector<std::string> of = {"--leafon", xyz.url() + "/{z}/{x}/{y}.png", "--leafoff",
                                   tms.url() + "/{z}/{x}/{-y}.png", "--extent-of", "dem", "--grid-res", "1.1"};
    const CliResult e = render(of, "of");
    ASSERT_EQ(e.exitCode, 0) << e.err;
    of[5] = "leafon";
    const CliResult f = render(of, "ofservice");
    EXPECT_EQ(f.exitCode, 1);
    EXPECT_NE(f.err.find("--extent-of leafon: the leaf-on is a tile service"), std::string::npos) << f.err;
    EXPECT_EQ(std::count(f.err.begin(), f.err.end(), '\n'), 1) << f.err;
    of.insert(of.end(), {"--extent", m.lonLat});
    of[5] = "dem";
    const CliResult g = render(of, "twoextents");
    EXPECT_EQ(g.exitCode, 1);
    EXPECT_NE(g.err.find("--extent and --extent-of"), std::string::npos) << g.err;
}

TEST(WebSourceCliTest, WmtsLayerDrawsAsTheSamePixelsOnDisk) {
    // The same tiles served as a WMTS layer (RESTful, GoogleMapsCompatible, tile matrices 0 to 17): the capabilities
    // fetched once, tile matrix 17 chosen by its scale, drawn as the same pixels on disk; a second run asks nothing.
    // The scene's extent is the leaf-off's footprint (--extent-of), as the layer is read over it: the same grid.
    ServedScene s("web-wmts");
    const MercatorTiles m = makeTiles(s);
    ASSERT_FALSE(m.merc.empty());
    HttpTestServer server(s.dir.path());
    std::string caps = R"(<?xml version="1.0" encoding="UTF-8"?>
<Capabilities xmlns="http://www.opengis.net/wmts/1.0" xmlns:ows="http://www.opengis.net/ows/1.1" version="1.0.0">
  <Contents>
    <Layer><ows:Title>Leaf-on</ows:Title><ows:Identifier>leafon</ows:Identifier>
      <Style isDefault="true"><ows:Identifier>default</ows:Identifier></Style><Format>image/png</Format>
      <TileMatrixSetLink><TileMatrixSet>GoogleMapsCompatible</TileMatrixSet></TileMatrixSetLink>
      <ResourceURL format="image/png" resourceType="tile" template=")" + server.url() +
                       R"(/tiles/{TileMatrix}/{TileCol}/{TileRow}.png"/>
    </Layer>
    <TileMatrixSet><ows:Identifier>GoogleMapsCompatible</ows:Identifier>
      <ows:SupportedCRS>urn:ogc:def:crs:EPSG::3857</ows:SupportedCRS>
)";
    for (int z = 0; z <= 17; ++z) {
        char row[400];
        std::snprintf(row, sizeof row,
                      "      <TileMatrix><ows:Identifier>%d</ows:Identifier><ScaleDenominator>%.10f</ScaleDenominator>"
                      "<TopLeftCorner>-20037508.3427892 20037508.3427892</TopLeftCorner><TileWidth>256</TileWidth>"
                      "<TileHeight>256</TileHeight><MatrixWidth>%d</MatrixWidth><MatrixHeight>%d</MatrixHeight>"
                      "</TileMatrix>\n",
                      z, 559082264.0287178 / double(1 << z), 1 << z, 1 << z);
        caps += row;
    }
    caps += "    </TileMatrixSet>\n  </Contents>\n</Capabilities>\n";
    writeText(s.dir / "wmts.xml", caps);
    writeText(s.dir / "page.html", "<html><body>Service unavailable</body></html>");
    const auto render = [&](const std::string& leafon, const std::string& name, std::vector<std::string> more = {}) {
        std::vector<std::string> args = {"render", "--leafon", leafon, "--leafoff", (s.scene / "leafoff.tif").string(),
                                         "--dem", (s.scene / "dem.tif").string(), "--camera", "0,-150,+120,20,-40",
                                         "--size", "320x240", "--view", "swipe", "--extent-of", "leafoff", "--cache",
                                         (s.dir / ("cache_" + name)).string(), "--out", (s.dir / (name + ".png")).string()};
        args.insert(args.end(), more.begin(), more.end());
        return runCli(args);
    };
    const CliResult a = render(m.merc.string(), "disk");
    ASSERT_EQ(a.exitCode, 0) << a.err;
    const std::string wmts = server.url() + "/wmts.xml?layer=leafon&tilematrixset=GoogleMapsCompatible";
    const CliResult b = render(wmts, "wmts");
    ASSERT_EQ(b.exitCode, 0) << b.err;
    expectSameRender(s.dir / "disk.png", s.dir / "wmts.png");
    const auto first = server.requests();
    EXPECT_EQ(std::count_if(first.begin(), first.end(), [](const auto& r) { return r.path == "/wmts.xml"; }), 1);
    EXPECT_TRUE(std::any_of(first.begin(), first.end(), [](const auto& r) { return r.path.rfind("/tiles/17/", 0) == 0; }));
    for (const auto& r : first) EXPECT_EQ(r.userAgent.rfind("seasonview/", 0), 0u) << r.path;
    server.clearRequests();
    const CliResult c = render(wmts, "wmts");
    ASSERT_EQ(c.exitCode, 0) << c.err;
    EXPECT_TRUE(server.requests().empty()) << server.requests().size() << " requests";
    const CliResult d = render(wmts, "wmts", {"--offline"});
    ASSERT_EQ(d.exitCode, 0) << d.err;
    EXPECT_TRUE(server.requests().empty()) << server.requests().size() << " requests";

    // A tile failing while the layer is read: one line naming its URL and status.
    const std::string corner = "/tiles/17/" + std::to_string(m.x0) + "/" + std::to_string(m.y0) + ".png";
    HttpTestServer::Fault down;
    down.status = 500;
    server.setFault(corner, down);
    const CliResult t = render(wmts, "wmtsdown");
    EXPECT_EQ(t.exitCode, 1);
    EXPECT_NE(t.err.find(server.url() + corner + ": HTTP 500"), std::string::npos) << t.err;
    EXPECT_EQ(std::count(t.err.begin(), t.err.end(), '\n'), 1) << t.err;
    server.clearFaults();

    // Faults: one line naming the URL each, no picture.
    struct Case {
        std::string url, needle;
    } cases[] = {
        {server.url() + "/none/wmts.xml?layer=leafon", "HTTP 404"},
        {server.url() + "/page.html?service=wmts&layer=leafon", "not a WMTS capabilities document"},
        {server.url() + "/wmts.xml?layer=winter", "no layer 'winter' (it has: leafon)"},
        {server.url() + "/wmts.xml?layer=leafon&tilematrixset=LAMB93", "no tile matrix set 'LAMB93'"},
    };
    int i = 0;
    for (const Case& f : cases) {
        const std::string name = "fault" + std::to_string(i++);
        const CliResult r = render(f.url, name);
        EXPECT_EQ(r.exitCode, 1) << f.url;
        EXPECT_NE(r.err.find(f.needle), std::string::npos) << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
        EXPECT_FALSE(fs::exists(s.dir / (name + ".png")));
    }
}

TEST(WebSourceCliTest, PrepareFetchesTheAreaOnceAndResumesAfterAFailure) {
    // `prepare` of a tile service stopped by a failing tile (one line naming it), then run again: it fetches what it
    // lacks, never a tile it has, and says how many tiles (of the area's) and bytes it fetched.
    ServedScene s("web-prepare");
    const MercatorTiles m = makeTiles(s);
    ASSERT_FALSE(m.merc.empty());
    HttpTestServer tiles(s.dir / "tiles");
    const std::vector<std::string> args = {"prepare", "--leafon", tiles.url() + "/{z}/{x}/{y}.png", "--leafoff",
                                           (s.scene / "leafoff.tif").string(), "--cache", (s.dir / "cache").string()};
    const std::string corner = "/17/" + std::to_string(m.x1) + "/" + std::to_string(m.y1) + ".png";
    HttpTestServer::Fault down;
    down.status = 500;
    tiles.setFault(corner, down);
    const CliResult a = runCli(args);
    EXPECT_EQ(a.exitCode, 1);
    EXPECT_NE(a.err.find(tiles.url() + corner + ": HTTP 500"), std::string::npos) << a.err;
    std::set<std::string> fetched;
    for (const auto& r : tiles.requests())
        if (r.path.rfind("/17/", 0) == 0 && r.path != corner) fetched.insert(r.path);
    tiles.clearFaults();
    tiles.clearRequests();
    const CliResult b = runCli(args);
    ASSERT_EQ(b.exitCode, 0) << b.err;
    int again = 0;
    bool cornerAsked = false;
    for (const auto& r : tiles.requests()) {
        EXPECT_EQ(fetched.count(r.path), 0u) << r.path << " fetched twice";
        cornerAsked = cornerAsked || r.path == corner;
        again += r.path.rfind("/17/", 0) == 0;
    }
    EXPECT_TRUE(cornerAsked);
    const long long area = (m.x1 - m.x0 + 1) * (m.y1 - m.y0 + 1);
    EXPECT_NE(b.out.find("fetched " + std::to_string(again) + " of " + std::to_string(area) + " tiles ("),
              std::string::npos)
        << b.out;
}

TEST(WebSourceCliTest, ServerStoppingMidFlightIsOneLineAndNoPyramid) {
    // `prepare` of a tile service whose server stops after a few tiles (the ones in flight are answered, then every
    // connection is refused): one line naming a tile's URL, exit 1, no pyramid; run again against a server that is
    // back, it completes.
    ServedScene s("web-stop");
    const MercatorTiles m = makeTiles(s);
    ASSERT_FALSE(m.merc.empty());
    auto tiles = std::make_unique<HttpTestServer>(s.dir / "tiles");
    const std::string url = tiles->url();
    const auto args = [&](const std::string& base) {
        return std::vector<std::string>{"prepare", "--leafon", base + "/{z}/{x}/{y}.png", "--leafoff",
                                        (s.scene / "leafoff.tif").string(), "--cache", (s.dir / "cache").string()};
    };
    HttpTestServer::Fault slow;
    slow.latencyMs = 50;
    tiles->setFault("*", slow);
    std::thread stopper([&] {
        // Bounded: at most 30 s of 10 ms polls for the fourth tile request, then the server stops.
        for (int i = 0; i < 3000; ++i) {
            int gets = 0;
            for (const auto& r : tiles->requests()) gets += r.path.rfind("/17/", 0) == 0;
            if (gets >= 4) break;
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
        }
        tiles->stop();
    });
    const CliResult a = runCli(args(url));
    stopper.join();
    EXPECT_EQ(a.exitCode, 1) << a.out;
    EXPECT_NE(a.err.find(url + "/17/"), std::string::npos) << a.err;
    EXPECT_EQ(std::count(a.err.begin(), a.err.end(), '\n'), 1) << a.err;
    EXPECT_FALSE(hasPyramid(s.dir / "cache")) << "a pyramid was written without the tiles";
    // A server back (on another port: the URL, and so the service, is another one) prepares it.
    HttpTestServer back(s.dir / "tiles");
    const CliResult b = runCli(args(back.url()));
    EXPECT_EQ(b.exitCode, 0) << b.err;
    EXPECT_TRUE(hasPyramid(s.dir / "cache"));
}

TEST(WebSourceCliTest, DemFromATerrariumTileServiceDrawsAsTheHeightsOnDisk) {
    // The synthetic DEM warped onto Web Mercator at zoom 15 and served as Terrarium PNG tiles (heights in colour:
    // R·256 + G + B/256 − 32768 m), against the same heights as a float GeoTIFF on disk; without --dem-encoding the
    // service is one line asking for it.
    ServedScene s("web-dem");
    auto info = readRasterInfo(s.scene / "leafoff.tif");
    ASSERT_TRUE(info.ok() && info->georef) << info.message();
    const Georef& g = *info->georef;
    auto mercator = Crs::fromEpsg(3857);
    ASSERT_TRUE(mercator.ok());
    const glm::dvec2 lo(g.origin.x, g.origin.y - g.pixelSize.y * info->height);
    const glm::dvec2 hi(g.origin.x + g.pixelSize.x * info->width, g.origin.y);
    std::vector<glm::dvec2> pts = {lo - (hi - lo), hi + (hi - lo), glm::dvec2(lo.x - (hi.x - lo.x), hi.y + (hi.y - lo.y)),
                                   glm::dvec2(hi.x + (hi.x - lo.x), lo.y - (hi.y - lo.y))};
    convert(g.crs, *mercator, pts);
    const int z = 15;
    const double half = 20037508.342789244, t = 2.0 * half / double(1 << z);
    double minX = 1e300, maxX = -1e300, minY = 1e300, maxY = -1e300;
    for (const auto& p : pts) minX = std::min(minX, p.x), maxX = std::max(maxX, p.x), minY = std::min(minY, p.y), maxY = std::max(maxY, p.y);
    const long long x0 = (long long)std::floor((minX + half) / t), x1 = (long long)std::floor((maxX + half) / t);
    const long long y0 = (long long)std::floor((half - maxY) / t), y1 = (long long)std::floor((half - minY) / t);
    const auto num = [](double v) {
        char b[40];
        std::snprintf(b, sizeof b, "%.10f", v);
        return std::string(b);
    };
    const fs::path merc = s.dir / "dem_3857.tif";
    gdalWarp(s.scene / "dem.tif", merc,
             {"-t_srs", "EPSG:3857", "-tr", num(t / 256), num(t / 256), "-te", num(-half + double(x0) * t),
              num(half - double(y1 + 1) * t), num(-half + double(x1 + 1) * t), num(half - double(y0) * t), "-r",
              "bilinear", "-ot", "Float32", "-dstnodata", "-32768"});
    ASSERT_FALSE(HasFailure());
    GDALDatasetH src = GDALOpen(merc.c_str(), GA_ReadOnly);
    ASSERT_TRUE(src);
    std::vector<float> h(256 * 256);
    std::vector<std::uint8_t> rgb(256 * 256 * 3);
    for (long long x = x0; x <= x1; ++x)
        for (long long y = y0; y <= y1; ++y) {
            ASSERT_EQ(GDALRasterIO(GDALGetRasterBand(src, 1), GF_Read, int((x - x0) * 256), int((y - y0) * 256), 256,
                                   256, h.data(), 256, 256, GDT_Float32, 0, 0),
                      CE_None);
            for (size_t i = 0; i < h.size(); ++i) {
                const double v = double(h[i]) + 32768.0;
                rgb[3 * i] = std::uint8_t(std::floor(v / 256.0));
                rgb[3 * i + 1] = std::uint8_t(int(std::floor(v)) % 256);
                rgb[3 * i + 2] = std::uint8_t(std::floor((v - std::floor(v)) * 256.0));
            }
            GDALDatasetH mem = GDALCreate(GDALGetDriverByName("MEM"), "", 256, 256, 3, GDT_Byte, nullptr);
            ASSERT_EQ(GDALDatasetRasterIO(mem, GF_Write, 0, 0, 256, 256, rgb.data(), 256, 256, GDT_Byte, 3, nullptr, 3,
                                          256 * 3, 1),
                      CE_None);
            const fs::path tile = s.dir / "terrarium" / std::to_string(z) / std::to_string(x) / (std::to_string(y) + ".png");
            fs::create_directories(tile.parent_path());
            GDALClose(GDALCreateCopy(GDALGetDriverByName("PNG"), tile.c_str(), mem, FALSE, nullptr, nullptr, nullptr));
            GDALClose(mem);
        }
    GDALClose(src);
    HttpTestServer server(s.dir / "terrarium");
    const auto render = [&](std::vector<std::string> dem, const std::string& name) {
        std::vector<std::string> args = {"render", "--leafon", (s.scene / "leafon.tif").string(), "--leafoff",
                                         (s.scene / "leafoff.tif").string(), "--camera", "0,-100,+80,0,-35", "--size",
                                         "320x240", "--view", "relief", "--cache", (s.dir / ("cache_" + name)).string(),
                                         "--out", (s.dir / (name + ".png")).string()};
        args.insert(args.end(), dem.begin(), dem.end());
        return runCli(args);
    };
    const CliResult a = render({"--dem", merc.string()}, "disk");
    ASSERT_EQ(a.exitCode, 0) << a.err;
    const std::string url = server.url() + "/{z}/{x}/{y}.png";
    const CliResult b = render({"--dem", url, "--dem-encoding", "terrarium"}, "web");
    ASSERT_EQ(b.exitCode, 0) << b.err;
    expectSameRender(s.dir / "disk.png", s.dir / "web.png");
    const auto requests = server.requests();
    EXPECT_TRUE(std::any_of(requests.begin(), requests.end(),
                            [&](const auto& r) { return r.path.rfind("/" + std::to_string(z) + "/", 0) == 0; }));
    // The same tiles decoded as Mapbox's encoding are other heights (800 km: not valid, filled): another picture.
    const CliResult c = render({"--dem", url, "--dem-encoding", "mapbox"}, "mapbox");
    ASSERT_EQ(c.exitCode, 0) << c.err;
    auto da = readImageU8(s.dir / "disk.png", 3), dc = readImageU8(s.dir / "mapbox.png", 3);
    ASSERT_TRUE(da.ok() && dc.ok());
    const double psnr = compareRgb(da->pixels, dc->pixels, da->width, da->height, 3).psnr;
    std::printf("Terrarium tiles decoded as Mapbox's: PSNR %.1f dB against the heights\n", psnr);
    EXPECT_LT(psnr, 35.0) << "the encoding changed nothing";
    const CliResult d = render({"--dem", url}, "plain");
    EXPECT_EQ(d.exitCode, 1);
    EXPECT_NE(d.err.find("needs --dem-encoding terrarium|mapbox"), std::string::npos) << d.err;
    EXPECT_EQ(std::count(d.err.begin(), d.err.end(), '\n'), 1) << d.err;
}
