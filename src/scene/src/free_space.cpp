#include "magvine/scene/free_space.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <sstream>

#include "magnet_entries.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/stopwatch.hpp"
#include "magvine/core/units.hpp"
#include "magvine/robot/elastica.hpp"
#include "magvine/robot/inflated_beam.hpp"
#include "robot_entries.hpp"
#include "yaml_reader.hpp"

namespace magvine::scene {
namespace {

constexpr int kDefaultNodes = 51;   // 50 edges: the rod's acceptance resolution (< 0.2 % of L against the elastica)
constexpr int kMaxNodes = 100001;
constexpr double kMaxNormalDot = 8.7e-3;  // sin(0.5°): base normal ⟂ direction within half a degree

}  // namespace

/// Pascals per one file pressure unit.
double pascals_per(const YamlMap& units) {
  if (!units.has("pressure")) return 1.0;
  const std::string u = units.text("pressure");
  if (u == "Pa") return 1.0;
  if (u == "kPa") return 1e3;
  if (u == "MPa") return 1e6;
  units.fail("pressure", "must be Pa, kPa or MPa (got '" + u + "')");
}

/// Rotation whose columns are (tangent, normal, tangent × normal) from the base entry.
Mat3 base_frame_of(const YamlMap& base) {
  const Vec3 t = base.nonzero_vec3("direction").normalized();
  Vec3 n = base.nonzero_vec3("normal").normalized();
  if (std::abs(t.dot(n)) > kMaxNormalDot) base.fail("normal", "must be perpendicular to direction (within 0.5°)");
  n = (n - t.dot(n) * t).normalized();
  Mat3 r;
  r.col(0) = t;
  r.col(1) = n;
  r.col(2) = t.cross(n);
  return r;
}

FileUnits file_units(const YamlMap& top) {
  const YamlMap units = top.map("units");
  units.allow_only({"length", "pressure"});
  const std::string length_unit = units.text("length");
  const auto lu = parse_length_unit(length_unit);
  if (!lu) units.fail("length", "must be mm, cm or m (got '" + length_unit + "')");
  return {*lu, metres_per(*lu), pascals_per(units)};
}

namespace {


int edges_of(const YamlMap& robot, double length, double unit) {
  if (robot.has("nodes") && robot.has("node_spacing")) robot.fail("node_spacing", "give either nodes or node_spacing");
  if (robot.has("node_spacing")) {
    const double spacing = robot.positive("node_spacing") * unit;
    const double edges = std::ceil(length / spacing - 1e-9);
    if (edges + 1 > kMaxNodes) robot.fail("node_spacing", "gives more than " + std::to_string(kMaxNodes) + " nodes");
    return std::max(1, static_cast<int>(edges));
  }
  if (!robot.has("nodes")) return kDefaultNodes - 1;
  const double nodes = robot.number("nodes");
  if (nodes != std::floor(nodes) || nodes < 2 || nodes > kMaxNodes) {
    robot.fail("nodes", "must be a whole number from 2 to " + std::to_string(kMaxNodes));
  }
  return static_cast<int>(nodes) - 1;
}

/// E from youngs_modulus or 3·shear_modulus (exactly one of them).
double youngs_of(const YamlMap& m, double stress_unit) {
  if (m.has("youngs_modulus") && m.has("shear_modulus")) {
    m.fail("shear_modulus", "give either youngs_modulus or shear_modulus (E = 3G), not both");
  }
  if (m.has("shear_modulus")) return 3.0 * m.positive("shear_modulus") * stress_unit;
  if (!m.has("youngs_modulus")) m.fail("youngs_modulus", "missing required key (or shear_modulus)");
  return m.positive("youngs_modulus") * stress_unit;
}

}  // namespace

double non_negative(const YamlMap& m, const std::string& key) {
  const double v = m.number(key);
  if (v < 0.0) m.fail(key, "must be >= 0 (got " + m.node(key).Scalar() + ")");
  return v;
}

namespace {

/// Per-edge moment per unit length [A·m] from the magnetisation sections.
std::vector<Vec3> magnetisation_of(const YamlMap& robot, double length, double unit, double area, int edges) {
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
    const double from = s.number("from") * unit;
    const double to = s.number("to") * unit;
    if (from < -slack || from >= to) s.fail("from", "must satisfy 0 <= from < to");
    if (to > length + slack) s.fail("to", "is beyond the robot's length");
    const double br = s.number("remanence");
    if (std::abs(br) > 3.0) s.fail("remanence", "is in tesla and must be within ±3 T");
    const Vec3 d = s.nonzero_vec3("direction").normalized();
    for (const Section& o : sections) {
      if (from < o.to - slack && o.from < to - slack) s.fail("from", "overlaps an earlier section");
    }
    sections.push_back({from, to, br / kMu0 * area * d});
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

robot::WallLayer layer_of(const YamlMap& m, double unit, double stress_unit) {
  robot::WallLayer l;
  l.thickness = m.positive("thickness") * unit;
  l.modulus = youngs_of(m, stress_unit);
  l.density = m.has("density") ? non_negative(m, "density") : 0.0;
  return l;
}

}  // namespace

robot::RodModel parse_rod(const YamlMap& robot, double unit, double stress_unit,
                          std::initializer_list<std::string_view> extra_keys, double* contact_radius) {
  std::vector<std::string_view> keys = {"kind",          "length", "section", "shear_modulus", "youngs_modulus",
                                        "density",       "magnetisation", "base", "nodes", "node_spacing"};
  keys.insert(keys.end(), extra_keys.begin(), extra_keys.end());
  robot.allow_only(keys);
  const double length = robot.positive("length") * unit;
  const int edges = edges_of(robot, length, unit);
  const double e = youngs_of(robot, stress_unit);
  const double density = non_negative(robot, "density");
  const YamlMap section = robot.map("section");
  const std::string shape = section.text("shape");
  robot::RodModel m;
  double area = 0.0;
  if (shape == "rectangle") {
    section.allow_only({"shape", "width", "thickness"});
    const double w = section.positive("width") * unit;
    const double t = section.positive("thickness") * unit;
    m = robot::rectangular_rod(length, w, t, e / 3.0, density, 0.0, Vec3::UnitX(), edges);
    area = w * t;
    if (contact_radius != nullptr) *contact_radius = 0.5 * std::hypot(w, t);
  } else if (shape == "circle") {
    section.allow_only({"shape", "diameter"});
    const double d = section.positive("diameter") * unit;
    m = robot::circular_rod(length, d, e / 3.0, density, edges);
    area = 0.25 * kPi * d * d;
    if (contact_radius != nullptr) *contact_radius = 0.5 * d;
  } else {
    section.fail("shape", "must be rectangle or circle (got '" + shape + "')");
  }
  if (robot.has("magnetisation")) m.moment_per_length = magnetisation_of(robot, length, unit, area, edges);
  return m;
}

robot::VineParameters parse_vine(const YamlMap& robot, double unit, double stress_unit) {
  robot.allow_only({"kind", "length", "diameter", "pressure", "wall", "skin", "fill", "base", "nodes", "node_spacing"});
  robot::VineParameters v;
  v.length = robot.positive("length") * unit;
  v.radius = 0.5 * robot.positive("diameter") * unit;
  v.pressure = non_negative(robot, "pressure") * stress_unit;
  v.edges = edges_of(robot, v.length, unit);
  const YamlMap wall = robot.map("wall");
  wall.allow_only({"thickness", "youngs_modulus", "shear_modulus", "density", "strength"});
  v.wall = layer_of(wall, unit, stress_unit);
  if (wall.has("strength")) v.wall_strength = wall.positive("strength") * stress_unit;
  if (robot.has("skin")) {
    const YamlMap skin = robot.map("skin");
    skin.allow_only({"thickness", "youngs_modulus", "shear_modulus", "density", "remanence", "direction"});
    v.skin = layer_of(skin, unit, stress_unit);
    v.skin_remanence = skin.has("remanence") ? skin.number("remanence") : 0.0;
    if (std::abs(v.skin_remanence) > 3.0) skin.fail("remanence", "is in tesla and must be within ±3 T");
    if (skin.has("direction")) {
      v.skin_direction = skin.nonzero_vec3("direction").normalized();
      if (std::abs(v.skin_direction.x()) > kMaxNormalDot) {
        skin.fail("direction", "must be perpendicular to the body axis x (axial skin magnetisation cancels on "
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
      v.volume_fraction = fill.number("volume_fraction");
      if (!(v.volume_fraction > 0.0 && v.volume_fraction < 0.74)) {
        fill.fail("volume_fraction", "must be in (0, 0.74) (0.74: close-packed spheres)");
      }
    }
    if (fill.has("law")) {
      const std::string law = fill.text("law");
      if (law == "bounded") {
        v.law = robot::FluidLaw::kBounded;
      } else if (law == "thesis") {
        v.law = robot::FluidLaw::kThesis;
      } else {
        fill.fail("law", "must be bounded or thesis (got '" + law + "')");
      }
    }
    if (fill.has("density")) v.fill_density = non_negative(fill, "density");
  }
  return v;
}

FreeSpaceScene parse_free_space_scene(const std::string& text, const std::string& file_label) {
  const YAML::Node root = parse_yaml(text, file_label);
  if (!root || root.IsNull()) throw InputError(file_label, 0, "", "empty scene file (expected units: and robot:)");
  const YamlMap top(root, file_label, "");
  top.allow_only({"units", "seed", "robot", "magnets", "simulation"});
  const FileUnits units = file_units(top);
  const double unit = units.metres;
  const double stress_unit = units.pascals;

  FreeSpaceScene scene;
  const YamlMap robot = top.map("robot");
  scene.kind = robot.text("kind");
  if (scene.kind == "rod") {
    scene.model = parse_rod(robot, unit, stress_unit, {}, nullptr);
  } else if (scene.kind == "vine") {
    scene.vine = parse_vine(robot, unit, stress_unit);
    try {
      scene.model = robot::vine_rod(*scene.vine);
    } catch (const robot::VineParameterError& e) {
      robot.fail(robot.has(e.parameter()) ? e.parameter() : "kind", e.what());
    }
  } else {
    robot.fail("kind", "must be rod or vine (got '" + scene.kind + "')");
  }
  const YamlMap base = robot.map("base");
  base.allow_only({"position", "direction", "normal"});
  scene.model.base_position = base.vec3("position") * unit;
  scene.model.base_frame = base_frame_of(base);

  if (top.has("magnets")) scene.magnets = parse_magnet_list(top, unit);
  if (top.has("simulation")) {
    const YamlMap sim = top.map("simulation");
    sim.allow_only({"gravity", "tolerance", "max_load_steps"});
    if (sim.has("gravity")) scene.model.gravity = sim.vec3("gravity");
    if (sim.has("tolerance")) scene.solver.tolerance = sim.positive("tolerance");
    if (sim.has("max_load_steps")) {
      const double steps = sim.number("max_load_steps");
      if (steps != std::floor(steps) || steps < 1 || steps > 1e6) {
        sim.fail("max_load_steps", "must be a whole number from 1 to 1000000");
      }
      scene.solver.max_load_steps = static_cast<int>(steps);
    }
  }
  return scene;
}

FreeSpaceScene load_free_space_scene(const std::filesystem::path& file) {
  return parse_free_space_scene(read_text_file(file.string(), "scene file"), file.string());
}

FreeSpaceResult solve_free_space(const FreeSpaceScene& scene) {
  FreeSpaceResult out;
  out.state = robot::straight_rod(scene.model);
  robot::RodField field;
  if (scene.magnets) field = robot::field_function(*scene.magnets, scene.magnets->rest_poses);
  const Stopwatch clock;
  out.report = robot::solve_rod_statics(scene.model, field, out.state, scene.solver);
  out.runtime_s = clock.seconds();
  return out;
}

void write_free_space_outputs(const FreeSpaceScene& scene, const FreeSpaceResult& result,
                              const std::filesystem::path& dir) {
  const robot::RodModel& m = scene.model;
  const robot::RodState& s = result.state;
  const auto vec = [](const Vec3& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); };
  const Vec3 tangent = s.tip_tangent();
  const double cosine = std::clamp(tangent.dot(m.base_frame.col(0)), -1.0, 1.0);
  const std::vector<double> moments = robot::joint_bending_moments(m, s);
  nlohmann::json j;
  j["kind"] = scene.kind;
  j["tip_position_m"] = vec(s.tip());
  j["tip_tangent"] = vec(tangent);
  j["bend_angle_deg"] = std::acos(cosine) / kDegToRad;
  j["converged"] = result.report.converged;
  j["iterations"] = result.report.iterations;
  j["load_steps"] = result.report.load_steps;
  j["runtime_s"] = result.runtime_s;
  j["nodes"] = m.edges + 1;
  j["gradient_norm"] = result.report.gradient_norm;
  j["failure"] = result.report.failure;
  j["max_bending_moment_Nm"] = *std::max_element(moments.begin(), moments.end());
  if (scene.vine) {
    const robot::VineParameters& v = *scene.vine;
    const robot::VineBendState bend = robot::vine_bend_state(m, s);
    j["pressure_Pa"] = v.pressure;
    j["axial_tension_N"] = robot::pressure_tip_force(v);
    j["wrinkling_moment_Nm"] = robot::wrinkling_moment(v.radius, v.pressure);
    j["collapse_moment_Nm"] = robot::collapse_moment(v.radius, v.pressure);
    j["wrinkled_length_m"] = bend.wrinkled_length;
    j["creased"] = bend.creased;
  }
  create_output_directory(dir);
  std::ostringstream csv;
  csv.precision(12);
  csv << "s_m,x,y,z\n";
  const double h = m.length / m.edges;
  for (std::size_t i = 0; i < s.x.size(); ++i) {
    csv << static_cast<double>(i) * h << ',' << s.x[i].x() << ',' << s.x[i].y() << ',' << s.x[i].z() << '\n';
  }
  write_file_atomically(dir / "shape.csv", csv.str());
  write_file_atomically(dir / "metrics.json", j.dump(2) + "\n");
}

}  // namespace magvine::scene
