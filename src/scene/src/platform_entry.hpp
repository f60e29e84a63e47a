#pragma once
// The scene's `platform:` section (docs/platform.md): the patient's torso, the table and the arms that hold the EPMs.
// Private to the scene module.

#include <memory>

#include "magvine/platform/platform.hpp"
#include "magvine/scene/experiment_scene.hpp"
#include "robot_entries.hpp"
#include "yaml_reader.hpp"

namespace magvine::scene {

/// Reads `p` (the platform: map) for `scene`, whose anatomy, magnets, gravity and navigator are already read; every
/// value checked (InputError naming the key).
std::shared_ptr<const platform::PlatformModel> parse_platform(const YamlMap& p, const FileUnits& units,
                                                              const ExperimentScene& scene);

}  // namespace magvine::scene
