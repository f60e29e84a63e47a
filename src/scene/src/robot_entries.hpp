#pragma once
// Robot entries shared by the free-space and experiment scene files. Private to the scene module.

#include <initializer_list>
#include <string_view>

#include "magvine/robot/vine.hpp"
#include "yaml_reader.hpp"

namespace magvine::scene {

/// Pascals per one pressure unit of `units:` (Pa default; kPa, MPa).
double pascals_per(const YamlMap& units);
/// The base entry's frame: columns tangent (direction), normal, tangent × normal.
Mat3 base_frame_of(const YamlMap& base);
/// A `robot: {kind: vine, ...}` entry (free_space.hpp), with `extra_keys` also allowed (read by the caller).
robot::VineParameters parse_vine(const YamlMap& robot, double unit, double stress_unit,
                                 std::initializer_list<std::string_view> extra_keys = {});

}  // namespace magvine::scene
