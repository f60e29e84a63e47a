#pragma once
// Entries shared by the free-space and experiment scene files (units, the vine, its base). Private to the scene module.

#include <initializer_list>
#include <string>
#include <string_view>

#include "magvine/core/units.hpp"
#include "magvine/robot/rod.hpp"
#include "magvine/robot/vine.hpp"
#include "yaml_reader.hpp"

namespace magvine::scene {

/// The `units:` entry of a scene file.
struct FileUnits {
  LengthUnit length = LengthUnit::kMm;
  double metres = 1e-3;  ///< per file length unit
  double pascals = 1.0;  ///< per file pressure unit (Pa default; kPa, MPa)
};
/// `top`'s `units: {length, pressure}` (length required).
FileUnits file_units(const YamlMap& top);
/// Pascals per one pressure unit of `units:`.
double pascals_per(const YamlMap& units);
/// The base entry's frame: columns tangent (direction), normal, tangent × normal.
Mat3 base_frame_of(const YamlMap& base);
/// A `robot: {kind: vine, ...}` entry (free_space.hpp).
robot::VineParameters parse_vine(const YamlMap& robot, double unit, double stress_unit);
/// A `robot: {kind: rod, ...}` entry (free_space.hpp), also allowing `extra_keys`; `contact_radius`, if given,
/// receives the section's circumscribed radius [m].
robot::RodModel parse_rod(const YamlMap& robot, double unit, double stress_unit,
                          std::initializer_list<std::string_view> extra_keys, double* contact_radius);
/// The number at `key`, which must be ≥ 0 (else the one-line error naming it).
double non_negative(const YamlMap& m, const std::string& key);

}  // namespace magvine::scene
