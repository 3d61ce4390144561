#pragma once
// What `render`, `bench`, `view` and `prepare` share about a scene's city model (its options: CliOptions.h): the
// atlas tree, built implicitly into the cache from the manifest's `buildings` model (as the imagery pyramids are)
// or given with `--city-tree`.
#include "CityRendererGL.h"
#include "CliOptions.h"
#include "Scene.h"

#include <CLI/CLI.hpp>

#include <filesystem>
#include <optional>
#include <string>

namespace seasonview::app {

/// The tree to draw: `explicitTree` when given, else the scene's `buildings` model's tree in
/// `cacheDir`/atlas/<hash>.svat, built (with the defaults of `atlas build`, a progress bar on a terminal, a line on
/// stdout) when missing or older than the model. Errors: no buildings in the scene, a model or build error.
Result<std::filesystem::path> prepareCityTree(const Scene& scene, const std::filesystem::path& cacheDir,
                                              const std::string& explicitTree);

/// When `message` names an atlas tree that prepareCityTree built into `cacheDir` (a block that did not read or
/// decode), removes it, so that the next run builds it again from the model; returns whether it did.
bool removeDamagedCityTree(const std::string& message, const std::filesystem::path& cacheDir);

} // namespace seasonview::app
