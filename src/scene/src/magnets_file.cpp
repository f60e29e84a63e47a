#include "magvine/scene/magnets_file.hpp"

#include <cmath>

#include "magnet_entries.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/magnetisation.hpp"
#include "ranges.hpp"
#include "robot_entries.hpp"
#include "yaml_reader.hpp"

namespace magvine::scene {

using magnetics::CylinderMagnet;
using magnetics::DipoleSource;
using magnetics::FieldModel;
using magnetics::Pose;
using magnetics::UniformSource;

namespace {

// A diametric direction must be perpendicular to the axis within this angle (0.5°); it is then
// orthogonalised exactly.
constexpr double kMaxAxisDot = 8.7e-3;  // sin(0.5°)

double polarisation_of(const YamlMap& m) {
  if (m.has("polarisation") && m.has("remanence"))
    m.fail("remanence", "give either polarisation or remanence, not both");
  if (!m.has("polarisation") && !m.has("remanence")) m.fail("polarisation", "missing required key (J in tesla)");
  const std::string key = m.has("polarisation") ? "polarisation" : "remanence";
  return m.quantity(key, kTesla, range::kPolarisation);  // no magnet material exceeds ~1.5 T
}

void add_cylinder(FieldModel& model, const YamlMap& m, const Unit& unit, const std::string& name) {
  m.allow_only({"kind", "name", "model", "diameter", "length", "polarisation", "remanence", "magnetisation", "position",
                "axis", "direction"});
  const double diameter = m.quantity("diameter", unit, range::kMagnetSize);
  const double length = m.quantity("length", unit, range::kMagnetSize);
  const double j = polarisation_of(m);
  const Vec3 position = m.vec3_quantity("position", unit, range::kCoordinate);
  const Vec3 axis = m.direction("axis");
  const std::string magnetisation = m.has("magnetisation") ? m.text("magnetisation") : "axial";
  const std::string field_model = m.has("model") ? m.text("model") : "exact";
  if (field_model != "exact" && field_model != "dipole")
    m.fail("model", "must be exact or dipole (got '" + field_model + "')");

  Pose pose;
  Vec3 j_local;
  if (magnetisation == "axial") {
    if (m.has("direction"))
      m.fail("direction", "only diametric magnets take a direction; an axial magnet is magnetised along its axis");
    pose = Pose::from_axis(position, axis);
    j_local = Vec3(0.0, 0.0, j);
  } else if (magnetisation == "diametric") {
    if (!m.has("direction"))
      m.fail("direction",
             "missing required key for a diametric magnet (magnetisation direction, perpendicular to axis)");
    const Vec3 direction = m.direction("direction");
    if (std::abs(direction.dot(axis)) > kMaxAxisDot) m.fail("direction", "must be perpendicular to axis (within 0.5°)");
    pose = Pose::from_axis_direction(position, axis, direction);
    j_local = Vec3(j, 0.0, 0.0);
  } else {
    m.fail("magnetisation", "must be axial or diametric (got '" + magnetisation + "')");
  }
  const CylinderMagnet cylinder(0.5 * diameter, length, j_local);
  if (field_model == "dipole") {
    model.add(DipoleSource{cylinder.dipole_moment()}, pose, name);
  } else {
    model.add(cylinder, pose, name);
  }
}

void add_dipole(FieldModel& model, const YamlMap& m, const Unit& unit, const std::string& name) {
  m.allow_only(
      {"kind", "name", "position", "moment", "polarisation", "remanence", "axis", "volume", "diameter", "length"});
  Pose pose;
  pose.position = m.vec3_quantity("position", unit, range::kCoordinate);
  Vec3 moment;
  if (m.has("moment")) {
    for (const char* k : {"polarisation", "remanence", "axis", "volume", "diameter", "length"}) {
      if (m.has(k)) m.fail(k, "give either moment or polarisation + axis + size, not both");
    }
    moment = m.vec3_quantity("moment", Unit{1.0, "A·m²"}, range::kMoment);
  } else {
    if (!m.has("polarisation") && !m.has("remanence")) {
      m.fail("moment", "missing required key (moment in A·m², or polarisation + axis + volume | diameter + length)");
    }
    const double j = polarisation_of(m);
    const Vec3 axis = m.direction("axis");
    double volume = 0.0;
    if (m.has("volume")) {
      if (m.has("diameter") || m.has("length")) m.fail("volume", "give either volume or diameter + length, not both");
      volume = m.quantity("volume", Unit{unit.si * unit.si * unit.si, unit.name + "³"}, range::kMagnetVolume);
    } else {
      const double d = m.quantity("diameter", unit, range::kMagnetSize);
      volume = kPi * 0.25 * d * d * m.quantity("length", unit, range::kMagnetSize);
    }
    moment = magnetics::hard_magnetic_moment<3>(Vec3(j * axis), volume);  // m = J·V/μ0
  }
  model.add(DipoleSource{moment}, pose, name);
}

void add_uniform(FieldModel& model, const YamlMap& m, const std::string& name) {
  m.allow_only({"kind", "name", "field"});
  model.add(UniformSource{m.vec3_quantity("field", kTesla, range::kField)}, Pose{}, name);
}

}  // namespace

FieldModel parse_magnets(const std::string& text, const std::string& file_label) {
  const YAML::Node root = parse_yaml(text, file_label);
  if (!root || root.IsNull()) throw InputError(file_label, 0, "", "empty file (expected units: and magnets:)");
  const YamlMap top(root, file_label, "");
  top.allow_only({"units", "magnets"});
  const YamlMap units = top.map("units");
  units.allow_only({"length"});
  return parse_magnet_list(top, unit_of(length_unit_of(units, "length")));
}

FieldModel parse_magnet_list(const YamlMap& parent, const Unit& unit) {
  const YAML::Node list = parent.node("magnets");
  if (!list.IsSequence()) parent.fail("magnets", "must be a list of sources (- kind: cylinder | dipole | uniform)");
  if (list.size() == 0) parent.fail("magnets", "is empty: give at least one source");
  const std::string& file_label = parent.file();

  FieldModel model;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const YamlMap m(list[i], file_label, parent.key_path("magnets[" + std::to_string(i) + "]"));
    const std::string kind = m.text("kind");
    const std::string name = m.has("name") ? m.text("name") : "magnets[" + std::to_string(i) + "] " + kind;
    if (kind == "cylinder") {
      add_cylinder(model, m, unit, name);
    } else if (kind == "dipole") {
      add_dipole(model, m, unit, name);
    } else if (kind == "uniform") {
      add_uniform(model, m, name);
    } else {
      m.fail("kind", "must be cylinder, dipole or uniform (got '" + kind + "')");
    }
  }
  return model;
}

FieldModel load_magnets_file(const std::filesystem::path& file) {
  return parse_magnets(read_text_file(file.string(), "magnets file"), file.string());
}

}  // namespace magvine::scene
