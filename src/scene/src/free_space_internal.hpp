#pragma once
// The free-space scene parser from a YAML root, for the files that extend a free-space scene (DESIGN.yaml's
// `design:`, CALIBRATE.yaml's `calibrate:`). Private to the scene module.

#include <yaml-cpp/yaml.h>

#include <string>

#include "magvine/scene/free_space.hpp"

namespace magvine::scene::detail {

/// parse_free_space_scene on a parsed root; `section`, if given, is one more top-level key it accepts (`design`,
/// `calibrate`: read by the caller); `area`, if given, receives a rod's cross-section [m²].
FreeSpaceScene parse_free_space_root(const YAML::Node& root, const std::string& file_label, const char* section,
                                     double* area);

}  // namespace magvine::scene::detail
