#pragma once
// The seasonview subcommands. Each registers its CLI11 options and returns the process exit code when run:
// 0 success, 1 bad input or failure (one line on stderr naming the file and the problem).
#include <CLI/CLI.hpp>

#include <functional>

namespace seasonview::app {

using Runner = std::function<int()>;

Runner addSynthCommand(CLI::App& app);
Runner addRenderCommand(CLI::App& app);
Runner addDemoCommand(CLI::App& app);

} // namespace seasonview::app
