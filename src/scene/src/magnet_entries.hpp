#pragma once
// The `magnets:` list shared by the magnets file and scene files. Private to the scene module.

#include "magvine/magnetics/field_model.hpp"
#include "yaml_reader.hpp"

namespace magvine::scene {

/// Parses `parent`'s `magnets:` list (entries as in docs/scenes.md: magnets), lengths in the file unit `length`.
magnetics::FieldModel parse_magnet_list(const YamlMap& parent, const Unit& length);

}  // namespace magvine::scene
