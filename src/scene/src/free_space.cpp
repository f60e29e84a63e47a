#include "magvine/scene/free_space.hpp"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>

#include "failed_run.hpp"
#include "free_space_internal.hpp"
#include "magnet_entries.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/stopwatch.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/magnetisation.hpp"
#include "magvine/robot/elastica.hpp"
#include "magvine/robot/inflated_beam.hpp"
#include "robot_entries.hpp"
#include "yaml_reader.hpp"

namespace magvine::scene {

FreeSpaceScene parse_free_space_scene(const std::string& text, const std::string& file_label) {
  const YAML::Node root = parse_yaml(text, file_label);
  return detail::parse_free_space_root(root, file_label, nullptr, nullptr);
}

namespace detail {

FreeSpaceScene parse_free_space_root(const YAML::Node& root, const std::string& file_label, const char* section,
                                     double* area) {
  if (!root || root.IsNull()) throw InputError(file_label, 0, "", "empty scene file (expected units: and robot:)");
  const YamlMap top(root, file_label, "");
  if (section != nullptr) {
    top.allow_only({"units", "seed", "robot", "magnets", "simulation", section});
  } else {
    top.allow_only({"units", "seed", "robot", "magnets", "simulation"});
  }
  const FileUnits units = file_units(top);
  (void)seed_of(top, 0);  // accepted (statics draws nothing)

  FreeSpaceScene scene;
  const YamlMap robot = top.map("robot");
  const std::string kind = robot.text("kind");
  if (kind == "rod") {
    scene.model = parse_rod(robot, units, {}, nullptr, area);
  } else if (kind == "vine") {
    scene.vine = parse_vine(robot, units);
    scene.model = robot::vine_rod(*scene.vine);  // checked by parse_vine
  } else {
    robot.fail("kind", "must be rod or vine (got '" + kind + "')");
  }
  const BasePose base = base_of(robot, units);
  scene.model.base_position = base.position;
  scene.model.base_frame = base.frame;

  if (top.has("magnets")) scene.magnets = parse_magnet_list(top, units.len);
  if (top.has("simulation")) {
    const YamlMap sim = top.map("simulation");
    sim.allow_only({"gravity", "tolerance", "max_load_steps"});
    if (sim.has("gravity")) scene.model.gravity = sim.vec3_quantity("gravity", kMetresPerS2, range::kGravity);
    if (sim.has("tolerance")) scene.solver.tolerance = sim.quantity("tolerance", kPlain, range::kSolverTolerance);
    if (sim.has("max_load_steps"))
      scene.solver.max_load_steps = static_cast<int>(sim.whole("max_load_steps", 1, 1000000));
  }
  return scene;
}

}  // namespace detail

FreeSpaceScene load_free_space_scene(const std::filesystem::path& file) {
  return parse_free_space_scene(read_text_file(file.string(), "scene file"), file.string());
}

FreeSpaceResult solve_free_space(const FreeSpaceScene& scene) {
  FreeSpaceResult out;
  out.state = robot::straight_rod(scene.model);
  robot::RodField field;
  if (scene.magnets) field = magnetics::field_function(*scene.magnets, scene.magnets->rest_poses);
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
  j["kind"] = scene.kind();
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
  j["failed"] = !result.report.converged;
  j["max_bending_moment_Nm"] = *std::max_element(moments.begin(), moments.end());
  if (scene.vine) {
    const robot::VineParameters& v = *scene.vine;
    const robot::VineBendState bend = robot::vine_bend_state(m, s);
    j["pressure_Pa"] = v.pressure;
    j["axial_tension_N"] = robot::pressure_tip_force(v);
    const double radius = robot::extended_radius(v, v.pressure);  // pressurised (the model's)
    j["pressure_radius_m"] = radius;
    j["wrinkling_moment_Nm"] = robot::wrinkling_moment(radius, v.pressure);
    j["collapse_moment_Nm"] = robot::collapse_moment(radius, v.pressure);
    j["wrinkled_length_m"] = bend.wrinkled_length;
    j["creased"] = bend.creased;
  }
  if (!result.report.converged) {  // a failed run leaves its metrics.json only (docs/cli.md: failed runs)
    detail::write_failed_run(dir, j);
    return;
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
