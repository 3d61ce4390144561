// Crash safety: `synth`, `prepare`, `atlas build` and `segment` killed (SIGKILL) at random moments leave either the
// complete earlier result or none, never a file a later run accepts; the run after the kills gives byte-identical
// results to an uninterrupted one, and leftovers of the killed runs are cleaned away. A full disk (the file-size
// limit RLIMIT_FSIZE, which makes every write past it fail as a full disk does, at 0 and at 32 KiB) gives one line,
// exit 1, and no output or cache entry.
#include "TestUtil.h"

#include <gtest/gtest.h>

#include <cerrno>
#include <chrono>
#include <iostream>
#include <fcntl.h>
#include <functional>
#include <map>
#include <random>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

using namespace seasonview;
using namespace seasonview::test;

namespace {

namespace fs = std::filesystem;

/// Starts seasonview with `args` (stdout and stderr to `log`).
pid_t spawn(const std::vector<std::string>& args, const fs::path& log) {
    std::vector<std::string> all = {SEASONVIEW_BINARY};
    all.insert(all.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    const pid_t pid = ::fork();
    if (pid == 0) {
        const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        ::dup2(fd, 1);
        ::dup2(fd, 2);
        ::execv(argv[0], argv.data());
        ::_exit(127);
    }
    return pid;
}

/// Waits for `pid`: its exit code, or -signal when a signal ended it.
int waitFor(pid_t pid) {
    int status = 0;
    ::waitpid(pid, &status, 0);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
}

/// Runs seasonview with `args` under RLIMIT_FSIZE = `limit` bytes (SIGXFSZ ignored: every write past it fails with
/// EFBIG, as on a full disk; 0 fails every write). Its stdout and stderr come back through a pipe, which the limit
/// does not touch. Returns the exit code (or -signal) and what it printed.
std::pair<int, std::string> runWithFileSizeLimit(const std::vector<std::string>& args, rlim_t limit) {
    std::vector<std::string> all = {SEASONVIEW_BINARY};
    all.insert(all.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    int fds[2];
    if (::pipe(fds) != 0) return {-1, "pipe failed"};
    const pid_t pid = ::fork();
    if (pid == 0) {
        ::close(fds[0]);
        ::dup2(fds[1], 1);
        ::dup2(fds[1], 2);
        ::signal(SIGXFSZ, SIG_IGN);
        const rlimit r{limit, limit};
        ::setrlimit(RLIMIT_FSIZE, &r);
        ::execv(argv[0], argv.data());
        ::_exit(127);
    }
    ::close(fds[1]);
    std::string out;
    char buf[4096];
    for (ssize_t n; (n = ::read(fds[0], buf, sizeof buf)) != 0;)
        if (n > 0) out.append(buf, size_t(n));
        else if (errno != EINTR) break;
    ::close(fds[0]);
    return {waitFor(pid), out};
}

/// A file's size and a hash of its bytes, for comparisons whose failures print short.
std::string fingerprint(const fs::path& p) {
    const std::string bytes = readBytes(p);
    return std::to_string(bytes.size()) + " bytes, hash " + std::to_string(std::hash<std::string>{}(bytes));
}

/// Every file under `dir` (relative path → fingerprint), in-progress temporaries (".partial-") included.
std::map<std::string, std::string> snapshot(const fs::path& dir) {
    std::map<std::string, std::string> files;
    if (!fs::exists(dir)) return files;
    for (const auto& e : fs::recursive_directory_iterator(dir))
        if (e.is_regular_file()) files[fs::relative(e.path(), dir).string()] = fingerprint(e.path());
    return files;
}

bool isTemporary(const std::string& relative) { return relative.find(".partial-") != std::string::npos; }

/// The files of `after` that are not temporaries.
std::map<std::string, std::string> committed(const std::map<std::string, std::string>& after) {
    std::map<std::string, std::string> out;
    for (const auto& [k, v] : after)
        if (!isTemporary(k)) out[k] = v;
    return out;
}

struct CrashSafety : ::testing::Test {
    TempDir dir{"crash-safety"};
    std::mt19937 random{20261125};

    void SetUp() override {
        // A 2048² scene with a small city: each command takes from half a second (segment) to two (synth).
        CliResult r = runCli({"synth", "--size-m", "1024", "--gsd", "0.5", "--seed", "3", "--block-city", "6", "--out",
                              (dir / "scene").string()});
        ASSERT_EQ(r.exitCode, 0) << r.err;
    }

    /// Runs `args` once to completion: seconds taken (and the exit code checked).
    double runWhole(const std::vector<std::string>& args) {
        const auto t0 = std::chrono::steady_clock::now();
        const int rc = waitFor(spawn(args, dir / "log.txt"));
        EXPECT_EQ(rc, 0) << readBytes(dir / "log.txt");
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }

    /// Starts `args` and kills it at a random moment within `seconds` until `kills` runs were killed before they
    /// finished (at most 3 × `kills` runs: a run that resumes earlier work can finish before its moment comes); after
    /// each run `check` sees what is on disk. After a run that finished, `startOver` (when given) clears what it
    /// left, so that the next run has the whole work to do again instead of finding it done. Returns how many runs
    /// were killed before they finished.
    int killRepeatedly(const std::vector<std::string>& args, double seconds, int kills,
                       const std::function<void()>& check, const std::function<void()>& startOver = {}) {
        int killed = 0;
        std::uniform_real_distribution<double> when(0.02, 1.0);
        for (int run = 0; run < 3 * kills && killed < kills; ++run) {
            const pid_t pid = spawn(args, dir / "log.txt");
            std::this_thread::sleep_for(std::chrono::duration<double>(when(random) * seconds));
            ::kill(pid, SIGKILL);
            const bool wasKilled = waitFor(pid) == -SIGKILL;
            killed += wasKilled;
            check();
            if (!wasKilled && startOver) startOver();
        }
        return killed;
    }
};

} // namespace

TEST_F(CrashSafety, SynthKilledLeavesNoSceneThatReadsAsWhole) {
    const fs::path out = dir / "again";
    const std::vector<std::string> args = {"synth",        "--size-m", "1024", "--gsd", "0.5", "--seed", "3",
                                           "--block-city", "6",        "--out",  out.string()};
    const auto reference = committed(snapshot(dir / "scene"));
    const double seconds = runWhole(args);
    ASSERT_EQ(committed(snapshot(out)), reference) << "synth is not deterministic";
    fs::remove_all(out);
    const int killed = killRepeatedly(args, seconds, 6, [&] {
        // scene.json is written last: while it is there, every file it names is the complete one.
        if (fs::exists(out / "scene.json")) {
            for (const auto& [name, bytes] : committed(snapshot(out)))
                EXPECT_EQ(bytes, reference.at(name)) << name << " differs while scene.json says the scene is whole";
        }
        // A file under its final name is whole even without scene.json (written under a temporary name first).
        for (const auto& [name, bytes] : committed(snapshot(out)))
            if (reference.count(name)) {
                EXPECT_EQ(bytes, reference.at(name)) << name << " is not whole";
            }
    });
    std::cout << "[ kills    ] synth: " << killed << " runs killed before they finished (6 wanted)\n";
    EXPECT_GE(killed, 3) << "too few runs were killed before they finished to mean anything";
    runWhole(args);
    EXPECT_EQ(snapshot(out), reference) << "after the kills: not identical, or temporaries left behind";
}

TEST_F(CrashSafety, PrepareKilledLeavesOnlyValidPyramidsAndResumes) {
    const fs::path scene = dir / "scene/scene.json";
    const std::vector<std::string> args = {"prepare", scene.string(), "--cache", (dir / "cache").string()};
    const double seconds = runWhole(args);
    const auto reference = snapshot(dir / "cache");
    fs::remove_all(dir / "cache");
    // Every pyramid with an index, and every statistics file, is the complete one.
    const auto check = [&] {
        for (const auto& [name, bytes] : committed(snapshot(dir / "cache"))) {
            const fs::path folder = fs::path(name).parent_path();
            const bool indexed = fs::exists(dir / "cache" / folder / "pyramid.json") || folder.filename() == "pairstats" ||
                                 folder.empty();
            if (indexed) {
                EXPECT_EQ(bytes, reference.count(name) ? reference.at(name) : "(absent)") << name;
            }
        }
    };
    // A prepare that finished leaves every later one nothing to do: those start again from no cache.
    const int killed = killRepeatedly(args, seconds, 8, check, [&] { fs::remove_all(dir / "cache"); });
    std::cout << "[ kills    ] prepare: " << killed << " runs killed before they finished (8 wanted)\n";
    EXPECT_GE(killed, 4);
    runWhole(args);
    EXPECT_EQ(snapshot(dir / "cache"), reference) << "after the kills: not identical, or temporaries left behind";
}

TEST_F(CrashSafety, AtlasBuildAndSegmentKilledLeaveTheOldResultOrNone) {
    const fs::path model = dir / "scene/city/city.obj";
    ASSERT_TRUE(fs::exists(model));
    const std::vector<std::string> atlas = {"atlas", "build", model.string(), "--obj-local", "--atlas-size", "256",
                                            "--out", (dir / "city.atlas").string()};
    const std::vector<std::string> segment = {"segment", (dir / "scene/scene.json").string(), "--cache",
                                              (dir / "cache").string(), "--out", (dir / "mask.png").string(),
                                              "--overlay", (dir / "overlay.png").string(), "--trees",
                                              (dir / "trees.csv").string()};
    const std::vector<std::pair<const std::vector<std::string>*, std::vector<std::string>>> commands = {
        {&atlas, {"city.atlas"}}, {&segment, {"mask.png", "overlay.png", "trees.csv"}}};
    for (const auto& command : commands) {
        const std::vector<std::string>* args = command.first;
        const std::vector<std::string>& outputs = command.second;
        SCOPED_TRACE(args->front());
        const double seconds = runWhole(*args);
        const auto reference = committed(snapshot(dir.path()));
        // Outputs written by the whole run: each must stay byte-identical (the old result) or be absent.
        for (const auto& o : outputs) ASSERT_TRUE(reference.count(o)) << o;
        for (int round = 0; round < 2; ++round) { // with the old result in place, then with none
            if (round == 1)
                for (const auto& o : outputs) fs::remove(dir / o);
            const int killed = killRepeatedly(*args, seconds, 4, [&] {
                for (const auto& o : outputs)
                    if (fs::exists(dir / o)) {
                        EXPECT_EQ(fingerprint(dir / o), reference.at(o)) << o << " is not whole";
                    }
            });
            std::cout << "[ kills    ] " << args->front() << (round == 0 ? " (old result there)" : " (none there)")
                      << ": " << killed << " runs killed before they finished (4 wanted)\n";
            EXPECT_GE(killed, 2);
        }
        runWhole(*args);
        for (const auto& o : outputs) EXPECT_EQ(fingerprint(dir / o), reference.at(o)) << o;
        for (const auto& [name, bytes] : snapshot(dir.path()))
            EXPECT_FALSE(isTemporary(name) && fs::path(name).parent_path().empty()) << name << " left behind";
    }
}

TEST_F(CrashSafety, FullDiskIsOneLineAndLeavesNothing) {
    const std::string scene = (dir / "scene/scene.json").string();
    struct Case {
        std::vector<std::string> args;
        std::vector<std::string> outputs;
    };
    const std::vector<Case> cases = {
        {{"synth", "--size-m", "256", "--gsd", "0.5", "--block-city", "2", "--out", (dir / "full-synth").string()},
         {"full-synth/scene.json"}},
        {{"prepare", scene, "--cache", (dir / "full-cache").string()}, {}},
        {{"segment", scene, "--cache", (dir / "cache").string(), "--out", (dir / "full-mask.tif").string()},
         {"full-mask.tif"}},
        {{"atlas", "build", (dir / "scene/city/city.obj").string(), "--obj-local", "--atlas-size", "256", "--out",
          (dir / "full.atlas").string()},
         {"full.atlas"}},
        {{"render", scene, "--size", "1280x960", "--cache", (dir / "cache").string(), "--out",
          (dir / "full.png").string()},
         {"full.png"}},
    };
    // The segment and render cases need the pyramids prepared (their own writes are what fills the disk).
    ASSERT_EQ(runCli({"prepare", scene, "--cache", (dir / "cache").string()}).exitCode, 0);
    // 0: the first write fails, whatever its size (the small JSON files included); 32 KiB: writes fail part way.
    for (const rlim_t limit : {rlim_t(0), rlim_t(32 * 1024)}) {
        for (const Case& c : cases) {
            SCOPED_TRACE(c.args.front() + " with writes failing past " + std::to_string(limit) + " bytes");
            const auto [rc, log] = runWithFileSizeLimit(c.args, limit);
            EXPECT_EQ(rc, 1) << log;
            // One line: the error (progress bars and notes go to stdout, here the same pipe: look at the last line).
            const std::string last = log.substr(log.rfind('\n', log.size() - 2) + 1);
            EXPECT_NE(last.find("seasonview " + c.args.front()), std::string::npos) << log;
            for (const auto& o : c.outputs) EXPECT_FALSE(fs::exists(dir / o)) << o << " left after a failed write";
        }
        for (const auto& [name, bytes] : snapshot(dir.path()))
            EXPECT_FALSE(isTemporary(name)) << name << " left behind by a failed write";
    }
    // No pyramid of the full-disk prepare is accepted: a later prepare without the limit builds them all.
    CliResult again = runCli({"prepare", scene, "--cache", (dir / "full-cache").string()});
    EXPECT_EQ(again.exitCode, 0) << again.err;
    EXPECT_EQ(again.out.find("up to date"), std::string::npos) << again.out;
    for (const auto& [name, bytes] : snapshot(dir.path()))
        EXPECT_FALSE(isTemporary(name)) << name << " left behind by a failed write";
}
