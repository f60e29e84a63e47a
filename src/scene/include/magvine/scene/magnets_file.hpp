#pragma once
/// The magnets file (YAML): a list of field sources in file units, converted to SI here.
///
/// ```yaml
/// units: {length: mm}          # mm | cm | m; fields are always tesla, moments A·m²
/// magnets:
///   - kind: cylinder           # exact closed form (default) — `model: dipole` selects the point dipole
///     diameter: 101.6
///     length: 101.6
///     polarisation: 1.48       # J [T]; `remanence` is accepted as a synonym
///     magnetisation: axial     # axial (default) | diametric
///     position: [0, 0, 0]      # centre
///     axis: [0, 0, 1]          # cylinder axis (= magnetisation direction for axial magnets)
///     direction: [1, 0, 0]     # diametric only: magnetisation direction, perpendicular to the axis
///   - kind: dipole
///     position: [0, 0, 300]
///     moment: [0, 0, 970.1]    # A·m²; or polarisation + axis + (volume | diameter + length)
///   - kind: uniform
///     field: [0, 0.01, 0]      # T
/// ```
/// Every entry may carry `name:`. Errors: InputError naming file, line and key.

#include <filesystem>
#include <string>

#include "magvine/magnetics/field_model.hpp"

namespace magvine::scene {

/// Reads and validates a magnets file.
magnetics::FieldModel load_magnets_file(const std::filesystem::path& file);
/// Parses magnets YAML text; `file_label` names it in error messages.
magnetics::FieldModel parse_magnets(const std::string& text, const std::string& file_label);

}  // namespace magvine::scene
