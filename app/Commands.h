#pragma once
// The seasonview subcommands. Each registers its CLI11 options and returns the process exit code when run:
// 0 success, 1 bad input or failure (one line on stderr naming the file and the problem).
#include "SyntheticScene.h"

#include <CLI/CLI.hpp>

#include <filesystem>
#include <functional>

namespace seasonview::app {

using Runner = std::function<int()>;

Runner addSynthCommand(CLI::App& app);
Runner addRenderCommand(CLI::App& app);
Runner addDemoCommand(CLI::App& app);
Runner addPrepareCommand(CLI::App& app);
Runner addBenchCommand(CLI::App& app);
Runner addSegmentCommand(CLI::App& app);
Runner addViewCommand(CLI::App& app);
Runner addAtlasCommand(CLI::App& app);

/// Reads a synthetic-scene preset (data/presets/*.json: size_m, gsd, seed).
Result<SynthOptions> loadSynthPreset(const std::filesystem::path& path);

/// A one-line progress bar on stderr when stderr is a terminal; nothing otherwise (logs stay clean).
ProgressFn terminalProgress(const char* what);

} // namespace seasonview::app
