#pragma once
// Entries shared by the free-space and experiment scene files (units, the vine, its base). Private to the scene module.

#include <cstdint>
#include <initializer_list>
#include <string>
#include <string_view>

#include "magvine/core/units.hpp"
#include "magvine/robot/rod.hpp"
#include "magvine/robot/vine.hpp"
#include "ranges.hpp"
#include "yaml_reader.hpp"

namespace magvine::scene {

/// The `units:` entry of a scene file.
struct FileUnits {
  LengthUnit length = LengthUnit::kMm;
  Unit len{1e-3, "mm"};  ///< the length unit, for range checks and messages
  Unit stress{1.0, "Pa"};  ///< the pressure unit (every stress: moduli, pressure, strength)
};
/// Units without a file unit: SI as it stands, named for messages.
inline const Unit kSeconds{1.0, "s"};
inline const Unit kTesla{1.0, "T"};
inline const Unit kKgPerM3{1.0, "kg/m³"};
inline const Unit kMetresPerS2{1.0, "m/s²"};
inline const Unit kPlain{1.0, ""};
inline const Unit kFramesPerSecond{1.0, "frames/s"};
/// `top`'s `units: {length, pressure}` (length required).
FileUnits file_units(const YamlMap& top);
/// The length unit at `key` of `m` (mm, cm or m).
LengthUnit length_unit_of(const YamlMap& m, const std::string& key);
/// A length unit for range checks and messages ("mm": 1e-3 m).
Unit unit_of(LengthUnit u);
/// The pressure unit of `units:` (Pa when absent).
Unit pressure_unit_of(const YamlMap& units);
/// The base entry's frame: columns tangent (direction), normal, tangent × normal.
Mat3 base_frame_of(const YamlMap& base);
/// `robot.base: {position, direction, normal}`: where the body is clamped.
struct BasePose {
  Vec3 position = Vec3::Zero();  ///< [m]
  Mat3 frame = Mat3::Identity();
};
BasePose base_of(const YamlMap& robot, const FileUnits& units);
/// `seed:` of a scene file (a whole number below 2^53), or `fallback` without one.
std::uint64_t seed_of(const YamlMap& top, std::uint64_t fallback);
/// A `robot: {kind: vine, ...}` entry (free_space.hpp).
robot::VineParameters parse_vine(const YamlMap& robot, const FileUnits& units);
/// A `robot: {kind: rod, ...}` entry (free_space.hpp), also allowing `extra_keys`; `contact_radius`, if given,
/// receives the section's circumscribed radius [m], `area` its cross-section [m²].
robot::RodModel parse_rod(const YamlMap& robot, const FileUnits& units,
                          std::initializer_list<std::string_view> extra_keys, double* contact_radius,
                          double* area = nullptr);
/// The vine's own derived checks (robot::vine_rod: burst, walls thinner than the radius, ...) as the error of the
/// robot key they concern.
void check_vine(const YamlMap& robot, const robot::VineParameters& vine);

}  // namespace magvine::scene
