#pragma once
// The `anatomy:` entry of an experiment scene, for the other files that name an anatomy (a design's insertion path
// along an airway graph). Private to the scene module.

#include <filesystem>
#include <memory>

#include "magvine/scene/experiment_scene.hpp"
#include "robot_entries.hpp"
#include "yaml_reader.hpp"

namespace magvine::scene::detail {

/// Parses `anatomy:` exactly as an experiment scene does (a generated phantom or a mesh, its airway graph); relative
/// paths from `directory`; `cache` (optional) shares anatomies between loads.
std::shared_ptr<const SceneAnatomy> parse_anatomy_entry(const YamlMap& entry, const FileUnits& units,
                                                        const std::filesystem::path& directory, AnatomyCache* cache);

}  // namespace magvine::scene::detail
