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

/// Blockmap mode (`settings.mode`) without a BlockMap file given (`settings.blockMaps` empty): the BlockMaps of the
/// tree `tree` as placed in `scene` (what CityRendererGL draws), in `cacheDir`/atlas/<hash>.svbm, keyed by the placed
/// triangles and the textures, built when missing (64² texels, 32 per wall column, 1 m leaf texels; a progress bar
/// on a terminal, a line on stdout); sets settings.blockMaps. Other modes: nothing.
Status prepareCityBlockMaps(const Scene& scene, const std::filesystem::path& tree, const std::filesystem::path& cacheDir,
                            city::CitySettings& settings);

/// When `message` names an atlas tree or BlockMap file that prepareCityTree or prepareCityBlockMaps built into
/// `cacheDir` (a block that did not read or decode), removes it, so that the next run builds it again from the model; returns whether it did.
bool removeDamagedCityTree(const std::string& message, const std::filesystem::path& cacheDir);

} // namespace seasonview::app
