#pragma once
// What `render`, `bench`, `view` and `prepare` share about a scene's city model: the `--city` flags and the
// atlas tree, built implicitly into the cache from the manifest's `buildings` model (as the imagery pyramids are)
// or given with `--city-tree`.
#include "CityRendererGL.h"
#include "Scene.h"

#include <CLI/CLI.hpp>

#include <filesystem>
#include <optional>
#include <string>

namespace seasonview::app {

struct CityArgs {
    std::string mode = "off"; // atlas | original | flat | off
    std::string tree;         // an atlas tree file; empty: the scene's buildings, built into the cache
    double capacityMb = 256.0;
    double tpp = 1.0;
    std::string upload = "auto"; // BC atlases: auto | compressed | decoded
    std::string occlusion = "on"; // atlas mode: occlusion culling on | off
    void addTo(CLI::App& cmd);
    /// The renderer settings, nullopt for `off`; errors name the flag.
    Result<std::optional<city::CitySettings>> settings() const;
};

/// The tree to draw: `explicitTree` when given, else the scene's `buildings` model's tree in
/// `cacheDir`/atlas/<hash>.svat, built (with the defaults of `atlas build`, a progress bar on a terminal, a line on
/// stdout) when missing or older than the model. Errors: no buildings in the scene, a model or build error.
Result<std::filesystem::path> prepareCityTree(const Scene& scene, const std::filesystem::path& cacheDir,
                                              const std::string& explicitTree);

} // namespace seasonview::app
