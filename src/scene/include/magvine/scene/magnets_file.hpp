#pragma once
/// The magnets file (YAML): a list of field sources (exact cylinders, dipoles, uniform fields) in file units,
/// converted to SI here. The format is documented once, in docs/scenes.md (magnets); errors are InputError naming
/// the file, the line and the key, every number checked against its plausible range.

#include <filesystem>
#include <string>

#include "magvine/magnetics/field_model.hpp"

namespace magvine::scene {

/// Reads and validates a magnets file.
magnetics::FieldModel load_magnets_file(const std::filesystem::path& file);
/// Parses magnets YAML text; `file_label` names it in error messages.
magnetics::FieldModel parse_magnets(const std::string& text, const std::string& file_label);

}  // namespace magvine::scene
