// The module layout of docs/architecture.md, checked: every `#include "..."` of every source file in a module folder
// names a header of that module or of one the module may use. A module may use only those below it:
// shaders < core < {synth, clipmap} ; clipmap < terrain < {foliage, city} < app (synth: app only). Inside core, its
// sub-folders: base < {gl, camera, geo} ; geo < scene.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

const std::map<std::string, std::set<std::string>>& allowed() {
    static const std::map<std::string, std::set<std::string>> a = {
        {"shaders", {}},
        {"core", {"shaders"}},
        {"synth", {"core", "shaders"}},
        {"clipmap", {"core", "shaders"}},
        {"terrain", {"clipmap", "core", "shaders"}},
        {"foliage", {"terrain", "clipmap", "core", "shaders"}},
        {"city", {"terrain", "clipmap", "core", "shaders"}},
        {"app", {"city", "foliage", "terrain", "clipmap", "synth", "core", "shaders"}},
    };
    return a;
}

bool isSource(const fs::path& p) { return p.extension() == ".h" || p.extension() == ".cpp"; }

} // namespace

TEST(ModuleDependencyTest, IncludesPointOnlyToModulesBelow) {
    const fs::path root = SEASONVIEW_SOURCE_DIR;
    // Which module owns each header, by its path relative to the module folder ("gl/GlObjects.h" is core's).
    std::map<std::string, std::string> owner;
    for (const auto& [module, deps] : allowed()) {
        ASSERT_TRUE(fs::is_directory(root / module)) << module;
        for (const auto& e : fs::recursive_directory_iterator(root / module))
            if (e.is_regular_file() && e.path().extension() == ".h") {
                // Headers are included by their path in the module ("gl/GlObjects.h") or, from core's include
                // folders, by name ("Raster.h"): both must name one module.
                const std::string rel = fs::relative(e.path(), root / module).generic_string();
                for (const std::string& name : {rel, e.path().filename().string()}) {
                    const auto [it, fresh] = owner.emplace(name, module);
                    EXPECT_TRUE(fresh || it->second == module)
                        << name << " exists in both " << it->second << "/ and " << module << "/";
                }
            }
    }
    const std::regex include(R"re(^\s*#\s*include\s+"([^"]+)")re");
    int files = 0, includes = 0;
    for (const auto& [module, deps] : allowed()) {
        for (const auto& e : fs::recursive_directory_iterator(root / module)) {
            if (!e.is_regular_file() || !isSource(e.path())) continue;
            ++files;
            std::ifstream in(e.path());
            std::string line;
            while (std::getline(in, line)) {
                std::smatch m;
                if (!std::regex_search(line, m, include)) continue;
                ++includes;
                const std::string header = m[1].str();
                // A header beside the file (or in its sub-folder) is the module's own.
                if (fs::exists(e.path().parent_path() / header)) continue;
                const auto it = owner.find(header);
                if (it == owner.end()) continue; // a generated or third-party header
                EXPECT_TRUE(it->second == module || deps.count(it->second))
                    << fs::relative(e.path(), root).generic_string() << " includes " << header << " of " << it->second
                    << "/, which " << module << "/ may not use (docs/architecture.md)";
            }
        }
    }
    EXPECT_GT(files, 150);
    EXPECT_GT(includes, 300);
}

TEST(ModuleDependencyTest, CoreSubfoldersPointOnlyToThoseBelow) {
    const fs::path core = fs::path(SEASONVIEW_SOURCE_DIR) / "core";
    const std::map<std::string, std::set<std::string>> allowedIn = {
        {"base", {}}, {"gl", {"base"}}, {"camera", {"base"}}, {"geo", {"base"}}, {"scene", {"geo", "base"}}};
    std::map<std::string, std::string> owner; // header name -> sub-folder
    for (const auto& [folder, deps] : allowedIn)
        for (const auto& e : fs::directory_iterator(core / folder))
            if (e.path().extension() == ".h") owner[e.path().filename().string()] = folder;
    // Nothing of core lies outside its sub-folders.
    for (const auto& e : fs::directory_iterator(core))
        EXPECT_FALSE(e.is_regular_file() && isSource(e.path())) << e.path().filename() << " is in no sub-folder of core/";
    const std::regex include(R"re(^\s*#\s*include\s+"([^"]+)")re");
    int checked = 0;
    for (const auto& [folder, deps] : allowedIn)
        for (const auto& e : fs::directory_iterator(core / folder)) {
            if (!isSource(e.path())) continue;
            std::ifstream in(e.path());
            std::string line;
            while (std::getline(in, line)) {
                std::smatch m;
                if (!std::regex_search(line, m, include)) continue;
                const auto it = owner.find(fs::path(m[1].str()).filename().string());
                if (it == owner.end()) continue; // outside core (the embedded shaders)
                ++checked;
                EXPECT_TRUE(it->second == folder || deps.count(it->second))
                    << "core/" << folder << "/" << e.path().filename().string() << " includes " << m[1].str()
                    << " of core/" << it->second << "/, which core/" << folder << "/ may not use";
            }
        }
    EXPECT_GT(checked, 50);
}
