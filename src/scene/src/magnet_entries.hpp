#pragma once
// The `magnets:` list shared by the magnets file and scene files. Private to the scene module.

#include "magvine/magnetics/field_model.hpp"
#include "yaml_reader.hpp"

namespace magvine::scene {

/// Parses `parent`'s `magnets:` list (entries as in magnets_file.hpp), lengths in `unit` metres.
magnetics::FieldModel parse_magnet_list(const YamlMap& parent, double unit);

}  // namespace magvine::scene
