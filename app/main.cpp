// seasonview: two-season aerial imagery renderer. See README.md.
#include "Commands.h"

#include <cstdio>
#include <exception>
#include <map>

int main(int argc, char** argv) {
    CLI::App app{"seasonview: render, compare and segment leaf-on/leaf-off aerial imagery"};
    app.require_subcommand(1);
    app.set_version_flag("--version", "seasonview 0.1.0");
    std::map<CLI::App*, seasonview::app::Runner> runners;
    auto add = [&](seasonview::app::Runner (*fn)(CLI::App&)) {
        const size_t before = app.get_subcommands({}).size();
        seasonview::app::Runner r = fn(app);
        runners[app.get_subcommands({})[before]] = std::move(r);
    };
    add(seasonview::app::addSynthCommand);
    add(seasonview::app::addRenderCommand);
    add(seasonview::app::addDemoCommand);
    add(seasonview::app::addPrepareCommand);
    add(seasonview::app::addBenchCommand);
    add(seasonview::app::addSegmentCommand);
    add(seasonview::app::addViewCommand);
    add(seasonview::app::addAtlasCommand);
    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForVersion& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        std::fprintf(stderr, "seasonview: %s (see seasonview --help)\n", e.what());
        return 1;
    }
    try {
        for (CLI::App* sub : app.get_subcommands())
            if (auto it = runners.find(sub); it != runners.end()) return it->second();
    } catch (const std::exception& e) {
        std::fprintf(stderr, "seasonview: internal error: %s\n", e.what());
        return 1;
    }
    return 1;
}
