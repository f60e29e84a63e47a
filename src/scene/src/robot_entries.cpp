#include "robot_entries.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/magnetisation.hpp"

namespace magvine::scene {
namespace {

constexpr int kDefaultNodes = 51;  // 50 edges: the rod's acceptance resolution (< 0.2 % of L against the elastica)
constexpr int kMaxNodes = 100001;
constexpr double kMaxNormalDot = 8.7e-3;  // sin(0.5°): base normal ⟂ direction within half a degree

int edges_of(const YamlMap& robot, double length, const FileUnits& units) {
  if (robot.has("nodes") && robot.has("node_spacing")) robot.fail("node_spacing", "give either nodes or node_spacing");
  if (robot.has("node_spacing")) {
    const double spacing = robot.quantity("node_spacing", units.len, range::kSpacing);
    const double edges = std::ceil(length / spacing - 1e-9);
    if (edges + 1 > kMaxNodes) robot.fail("node_spacing", "gives more than " + std::to_string(kMaxNodes) + " nodes");
    return std::max(1, static_cast<int>(edges));
  }
  if (!robot.has("nodes")) return kDefaultNodes - 1;
  return static_cast<int>(robot.whole("nodes", 2, kMaxNodes)) - 1;
}

/// E from youngs_modulus or 3·shear_modulus (exactly one of them) [Pa].
double youngs_of(const YamlMap& m, const FileUnits& units) {
  if (m.has("youngs_modulus") && m.has("shear_modulus")) {
    m.fail("shear_modulus", "give either youngs_modulus or shear_modulus (E = 3G), not both");
  }
  if (m.has("shear_modulus")) return 3.0 * m.quantity("shear_modulus", units.stress, range::kModulus);
  if (!m.has("youngs_modulus")) m.fail("youngs_modulus", "missing required key (or shear_modulus)");
  return m.quantity("youngs_modulus", units.stress, range::kModulus);
}

/// Per-edge moment per unit length [A·m] from the magnetisation sections (the hard-magnetic law, Br·A/μ0).
std::vector<Vec3> magnetisation_of(const YamlMap& robot, double length, const FileUnits& units, double area,
                                   int edges) {
  const YAML::Node list = robot.node("magnetisation");
  if (!list.IsSequence()) robot.fail("magnetisation", "must be a list of sections {from, to, remanence, direction}");
  struct Section {
    double from, to;
    Vec3 moment;
  };
  std::vector<Section> sections;
  const double slack = 1e-9 * length;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const YamlMap s(list[i], robot.file(), robot.key_path("magnetisation[" + std::to_string(i) + "]"));
    s.allow_only({"from", "to", "remanence", "direction"});
    const double from = s.quantity("from", units.len, range::kCoordinate);
    const double to = s.quantity("to", units.len, range::kCoordinate);
    if (from < -slack || from >= to) s.fail("from", "must satisfy 0 <= from < " + s.key_path("to"));
    if (to > length + slack) s.fail("to", "is beyond the robot's length");
    const double br = s.quantity("remanence", kTesla, range::kRemanence);
    const Vec3 d = s.direction("direction");
    for (const Section& o : sections) {
      if (from < o.to - slack && o.from < to - slack) s.fail("from", "overlaps an earlier section");
    }
    sections.push_back({from, to, magnetics::hard_magnetic_moment<3>(Vec3(br * d), area)});  // Br·A/μ0 per length
  }
  std::vector<Vec3> out(static_cast<std::size_t>(edges), Vec3::Zero());
  const double h = length / edges;
  for (std::size_t i = 0; i < sections.size(); ++i) {
    int covered = 0;
    for (int j = 0; j < edges; ++j) {
      const double mid = (j + 0.5) * h;
      if (mid >= sections[i].from && mid < sections[i].to) {
        out[static_cast<std::size_t>(j)] = sections[i].moment;
        ++covered;
      }
    }
    if (covered == 0) {
      const YamlMap s(list[i], robot.file(), robot.key_path("magnetisation[" + std::to_string(i) + "]"));
      s.fail("to", "the section holds no edge midpoint at this node spacing: give more nodes");
    }
  }
  return out;
}

robot::WallLayer layer_of(const YamlMap& m, const FileUnits& units) {
  robot::WallLayer l;
  l.thickness = m.quantity("thickness", units.len, range::kLayerThickness);
  l.modulus = youngs_of(m, units);
  l.density = m.has("density") ? m.quantity("density", kKgPerM3, range::kDensity) : 0.0;
  return l;
}

}  // namespace

LengthUnit length_unit_of(const YamlMap& m, const std::string& key) {
  const std::string name = m.text(key);
  const auto lu = parse_length_unit(name);
  if (!lu) m.fail(key, "must be mm, cm or m (got '" + name + "')");
  return *lu;
}

Unit unit_of(LengthUnit u) {
  return {metres_per(u), u == LengthUnit::kMm ? "mm" : (u == LengthUnit::kCm ? "cm" : "m")};
}

Unit pressure_unit_of(const YamlMap& units) {
  if (!units.has("pressure")) return {1.0, "Pa"};
  const std::string u = units.text("pressure");
  if (u == "Pa") return {1.0, "Pa"};
  if (u == "kPa") return {1e3, "kPa"};
  if (u == "MPa") return {1e6, "MPa"};
  units.fail("pressure", "must be Pa, kPa or MPa (got '" + u + "')");
}

Mat3 base_frame_of(const YamlMap& base) {
  const Vec3 t = base.direction("direction");
  Vec3 n = base.direction("normal");
  if (std::abs(t.dot(n)) > kMaxNormalDot) {
    base.fail("normal", "must be perpendicular to " + base.key_path("direction") + " (within 0.5°)");
  }
  n = (n - t.dot(n) * t).normalized();
  Mat3 r;
  r.col(0) = t;
  r.col(1) = n;
  r.col(2) = t.cross(n);
  return r;
}

BasePose base_of(const YamlMap& robot, const FileUnits& units) {
  const YamlMap base = robot.map("base");
  base.allow_only({"position", "direction", "normal"});
  return {base.vec3_quantity("position", units.len, range::kCoordinate), base_frame_of(base)};
}

std::uint64_t seed_of(const YamlMap& top, std::uint64_t fallback) {
  return top.has("seed") ? static_cast<std::uint64_t>(top.whole("seed", 0, 9007199254740991L)) : fallback;
}

FileUnits file_units(const YamlMap& top) {
  const YamlMap units = top.map("units");
  units.allow_only({"length", "pressure"});
  const LengthUnit length = length_unit_of(units, "length");
  return {length, unit_of(length), pressure_unit_of(units)};
}

robot::RodModel parse_rod(const YamlMap& robot, const FileUnits& units,
                          std::initializer_list<std::string_view> extra_keys, double* contact_radius,
                          double* area_out) {
  std::vector<std::string_view> keys = {"kind",    "length",        "section", "shear_modulus", "youngs_modulus",
                                        "density", "magnetisation", "base",    "nodes",         "node_spacing"};
  keys.insert(keys.end(), extra_keys.begin(), extra_keys.end());
  robot.allow_only(keys);
  const double length = robot.quantity("length", units.len, range::kBodyLength);
  const int edges = edges_of(robot, length, units);
  const double e = youngs_of(robot, units);
  const double density = robot.quantity("density", kKgPerM3, range::kDensity);
  const YamlMap section = robot.map("section");
  const std::string shape = section.text("shape");
  robot::RodModel m;
  double area = 0.0;
  if (shape == "rectangle") {
    section.allow_only({"shape", "width", "thickness"});
    const double w = section.quantity("width", units.len, range::kSectionSize);
    const double t = section.quantity("thickness", units.len, range::kSectionSize);
    m = robot::rectangular_rod(length, w, t, e / 3.0, density, 0.0, Vec3::UnitX(), edges);
    area = w * t;
    if (contact_radius != nullptr) *contact_radius = 0.5 * std::hypot(w, t);
  } else if (shape == "circle") {
    section.allow_only({"shape", "diameter"});
    const double d = section.quantity("diameter", units.len, range::kSectionSize);
    m = robot::circular_rod(length, d, e / 3.0, density, edges);
    area = 0.25 * kPi * d * d;
    if (contact_radius != nullptr) *contact_radius = 0.5 * d;
  } else {
    section.fail("shape", "must be rectangle or circle (got '" + shape + "')");
  }
  if (robot.has("magnetisation")) m.moment_per_length = magnetisation_of(robot, length, units, area, edges);
  if (area_out != nullptr) *area_out = area;
  // Derived: the stiffnesses the solver needs (robot::check_rod_model), named against the robot entry.
  try {
    robot::check_rod_model(m);
  } catch (const InputError& error) {
    robot.fail("section", error.what());
  }
  return m;
}

robot::VineParameters parse_vine(const YamlMap& robot, const FileUnits& units) {
  robot.allow_only({"kind", "length", "diameter", "pressure", "wall", "skin", "fill", "base", "nodes", "node_spacing"});
  robot::VineParameters v;
  v.length = robot.quantity("length", units.len, range::kBodyLength);
  v.radius = 0.5 * robot.quantity("diameter", units.len, range::kSectionSize);
  v.pressure = robot.quantity("pressure", units.stress, range::kPressure);
  v.edges = edges_of(robot, v.length, units);
  const YamlMap wall = robot.map("wall");
  wall.allow_only({"thickness", "youngs_modulus", "shear_modulus", "density", "strength"});
  v.wall = layer_of(wall, units);
  if (wall.has("strength")) v.wall_strength = wall.quantity("strength", units.stress, range::kStrength);
  if (robot.has("skin")) {
    const YamlMap skin = robot.map("skin");
    skin.allow_only({"thickness", "youngs_modulus", "shear_modulus", "density", "remanence", "direction"});
    v.skin = layer_of(skin, units);
    v.skin_remanence = skin.has("remanence") ? skin.quantity("remanence", kTesla, range::kRemanence) : 0.0;
    if (skin.has("direction")) {
      v.skin_direction = skin.direction("direction");
      if (std::abs(v.skin_direction.x()) > kMaxNormalDot) {
        skin.fail("direction",
                  "must be perpendicular to the body axis x (axial skin magnetisation cancels on "
                  "eversion, thesis 4.4.2)");
      }
      v.skin_direction.x() = 0.0;
      v.skin_direction.normalize();
    }
  }
  if (robot.has("fill")) {
    const YamlMap fill = robot.map("fill");
    fill.allow_only({"kind", "volume_fraction", "law", "density"});
    const std::string kind = fill.text("kind");
    if (kind == "air") {
      v.fill = robot::FillKind::kAir;
    } else if (kind == "water") {
      v.fill = robot::FillKind::kWater;
    } else if (kind == "magnetic_fluid") {
      v.fill = robot::FillKind::kMagneticFluid;
    } else {
      fill.fail("kind", "must be air, water or magnetic_fluid (got '" + kind + "')");
    }
    if (fill.has("volume_fraction")) {
      v.volume_fraction = fill.quantity("volume_fraction", kPlain, Range{0.0, 0.74, true, true});
    }
    if (fill.has("law")) {
      v.law = fill.choice("law", std::pair{std::string_view("bounded"), robot::FluidLaw::kBounded},
                          std::pair{std::string_view("thesis"), robot::FluidLaw::kThesis});
    }
    if (fill.has("density")) v.fill_density = fill.quantity("density", kKgPerM3, range::kDensity);
  }
  check_vine(robot, v);
  return v;
}

void check_vine(const YamlMap& robot, const robot::VineParameters& vine) {
  try {
    (void)robot::vine_rod(vine);
  } catch (const robot::VineParameterError& e) {
    robot.fail(robot.has(e.parameter()) ? e.parameter() : "kind", e.what());
  }
}

}  // namespace magvine::scene
