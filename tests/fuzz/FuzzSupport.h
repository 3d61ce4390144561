#pragma once
// What every fuzz target shares: the input written to a file of the name the loader expects (the loaders take
// paths, as the commands do), in a folder of this process's own under /dev/shm (or $TMPDIR), and GDAL and the
// loaders kept quiet. A loader under test may return an error for any input; it must not crash, hang, leak, read
// out of bounds, hit undefined behaviour or let an exception escape (libFuzzer reports an escaping exception).
#include <gdal.h>
#include <cpl_error.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <string>
#include <unistd.h>

// SEASONVIEW_FUZZ_TARGET(name) { body }: libFuzzer's entry point in the fuzz build; in the test build
// (SEASONVIEW_FUZZ_REGRESSION) a function registered under `name`, which tests/FuzzRegressionTest.cpp runs on every
// file of tests/fuzz/regressions/NAME/.
#ifdef SEASONVIEW_FUZZ_REGRESSION
#define SEASONVIEW_FUZZ_TARGET(name)                                                                                   \
    static int fuzzOne_##name(const std::uint8_t* data, std::size_t size);                                            \
    [[maybe_unused]] static const bool fuzzRegistered_##name = ::seasonview::fuzz::registerTarget(#name, fuzzOne_##name);               \
    static int fuzzOne_##name(const std::uint8_t* data, std::size_t size)
#else
#define SEASONVIEW_FUZZ_TARGET(name) extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
#endif

namespace seasonview::fuzz {

using TargetFn = int (*)(const std::uint8_t*, std::size_t);
/// The targets linked into this program (the test build), by name.
inline std::map<std::string, TargetFn>& targets() {
    static std::map<std::string, TargetFn> all;
    return all;
}
inline bool registerTarget(const char* name, TargetFn fn) {
    targets()[name] = fn;
    return true;
}

inline const std::filesystem::path& workDir() {
    static const std::filesystem::path dir = [] {
        std::filesystem::path base = std::filesystem::exists("/dev/shm") ? "/dev/shm" : std::filesystem::temp_directory_path();
        if (const char* t = std::getenv("SEASONVIEW_FUZZ_TMP")) base = t;
        auto d = base / ("seasonview-fuzz-" + std::to_string(::getpid()));
        std::filesystem::create_directories(d);
        CPLSetErrorHandler(CPLQuietErrorHandler);
        std::atexit([] {
            std::error_code ignored;
            std::filesystem::remove_all(workDir(), ignored);
        });
        return d;
    }();
    return dir;
}

/// Writes the input to workDir()/name and returns its path.
inline std::filesystem::path writeInput(const std::uint8_t* data, std::size_t size, const std::string& name) {
    const auto p = workDir() / name;
    std::ofstream f(p, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(data), std::streamsize(size));
    return p;
}

} // namespace seasonview::fuzz
