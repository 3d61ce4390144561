// Seasons and the DEM given as URLs (WebSource.h): read by HTTP range requests from a server on 127.0.0.1 that the
// test starts (HttpTestServer.h), drawn as the same files on disk draw, and every fault the server injects one line
// naming the URL, exit 1, no pyramid written.
#include "HttpTestServer.h"
#include "TestUtil.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>

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
    auto da = readImageU8(s.dir / "disk.png", 3), db = readImageU8(s.dir / "web.png", 3);
    ASSERT_TRUE(da.ok() && db.ok());
    const ImageDiff d = compareRgb(da->pixels, db->pixels, da->width, da->height, 3);
    ASSERT_TRUE(d.sameSize);
    EXPECT_GE(d.psnr, 45.0) << "max delta " << d.maxDelta;

    // Range requests only, each naming seasonview; the file asked for by HEAD first.
    const auto requests = s.server->requests();
    ASSERT_FALSE(requests.empty());
    for (const auto& r : requests) {
        EXPECT_EQ(r.userAgent.rfind("seasonview/", 0), 0u) << r.method << " " << r.path << " " << r.userAgent;
        EXPECT_TRUE(r.method == "HEAD" || !r.range.empty()) << r.method << " " << r.path << " without a range";
    }
    EXPECT_TRUE(std::any_of(requests.begin(), requests.end(), [](const auto& r) { return r.method == "HEAD"; }));

    // The seasons' pyramids are cached: the same render again asks whether the files changed (HEAD) and reads their
    // headers and tile directories, not their tiles. (The DEM, like a DEM on disk, is read onto the scene's area
    // whenever the scene opens.)
    s.server->clearRequests();
    const CliResult c = s.run(web, s.urls(), "cache_web");
    ASSERT_EQ(c.exitCode, 0) << c.err;
    for (const std::string season : {"/leafon.tif", "/leafoff.tif"}) {
        long long bytes = 0;
        for (const auto& r : s.server->requests()) {
            if (r.path != season || r.range.empty()) continue;
            const auto dash = r.range.find('-');
            bytes += std::atoll(r.range.c_str() + dash + 1) - std::atoll(r.range.c_str() + 6) + 1;
        }
        EXPECT_LT(bytes, (long long)fs::file_size(s.scene / season.substr(1)) / 4) << season;
    }
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
    // The same server healthy again, if slow (every answer after 100 ms): prepared.
    s.server->clearFaults();
    HttpTestServer::Fault slow;
    slow.latencyMs = 100;
    s.server->setFault("*", slow);
    const CliResult ok = s.run({"prepare"}, s.urls(), "cache_ok");
    EXPECT_EQ(ok.exitCode, 0) << ok.err;
    EXPECT_TRUE(hasPyramid(s.dir / "cache_ok"));
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
    auto da = readImageU8(dir / "disk.png", 3), db = readImageU8(dir / "web.png", 3);
    ASSERT_TRUE(da.ok() && db.ok());
    const ImageDiff d = compareRgb(da->pixels, db->pixels, da->width, da->height, 3);
    ASSERT_TRUE(d.sameSize);
    EXPECT_GE(d.psnr, 45.0) << "max delta " << d.maxDelta;
    long long fetched = 0;
    for (const auto& r : server.requests())
        if (!r.range.empty())
            fetched += std::atoll(r.range.c_str() + r.range.find('-') + 1) - std::atoll(r.range.c_str() + 6) + 1;
    std::printf("Saclay COG by URL: %zu requests, %lld bytes of %lld\n", server.requests().size(), fetched,
                (long long)fs::file_size(s / "leafon_3857_cog.tif"));
}
