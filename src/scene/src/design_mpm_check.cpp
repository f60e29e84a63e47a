// The MPM check of a design (design_scene.hpp: design_mpm_scene_yaml, run_design_mpm_check).

#include <algorithm>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "magvine/config.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/scene/design_scene.hpp"
#include "yaml_reader.hpp"
#if MAGVINE_WITH_MPM
#include "magvine/scene/mpm_scene.hpp"
#endif

namespace magvine::scene {
namespace {

/// "[a, b, c]" in mm, 17 significant digits.
std::string mm(const Vec3& v) {
  std::ostringstream o;
  o.precision(17);
  o << '[' << v.x() * 1e3 << ", " << v.y() * 1e3 << ", " << v.z() * 1e3 << ']';
  return o.str();
}
std::string plain(const Vec3& v) {
  std::ostringstream o;
  o.precision(17);
  o << '[' << v.x() << ", " << v.y() << ", " << v.z() << ']';
  return o.str();
}

/// The rod's circular section and material, from its model: A = πr², EI = E πr⁴/4 with E = 3G, ρ = ρA/A
/// [m, Pa, kg/m³].
struct RodMaterial {
  double radius = 0.0;
  double shear_modulus = 0.0;
  double density = 0.0;
};
RodMaterial material_of(const DesignScene& scene) {
  if (!scene.circular_section) {
    throw InputError(scene.file, 0, "robot.section", "the MPM check takes a circular section (a catheter) only");
  }
  const robot::RodModel& m = scene.problem.model;
  RodMaterial out;
  out.radius = std::sqrt(scene.problem.area / kPi);
  out.shear_modulus = m.bending_stiffness_2 / (3.0 * 0.25 * kPi * std::pow(out.radius, 4));
  out.density = m.mass_per_length / scene.problem.area;
  return out;
}

}  // namespace

std::string design_mpm_scene_yaml(const DesignScene& scene, const design::Design& design, double cell,
                                  int particles_per_cell, double duration) {
  const design::DesignProblem& p = scene.problem;
  const robot::RodModel& rod = p.model;
  const Vec3 t = rod.base_frame.col(0);
  int axis = -1;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(std::abs(t[i]) - 1.0) < 1e-12) axis = i;
  }
  if (axis < 0) {
    throw InputError(scene.file, 0, "robot.base.direction",
                     "the MPM check slabs the sections along the base axis, which must be x, y or z");
  }
  const RodMaterial mat = material_of(scene);
  const double h = cell > 0.0 ? cell : 0.5 * mat.radius;
  // The field: the design's, or the scene's when it is uniform.
  Vec3 b = Vec3::Zero();
  if (!design.fields.empty()) {
    b = design.fields.back();
  } else if (scene.scene.magnets) {
    const magnetics::FieldModel& magnets = *scene.scene.magnets;
    if (magnets.has_gradient()) {
      throw InputError(scene.file, 0, "magnets", "the MPM check takes uniform fields only");
    }
    b = magnetics::field(magnets, magnets.rest_poses, rod.base_position);
  }
  // The domain: the straight rod and every point the design reaches, with room for the radius and three cells.
  const double clamp = 3.0 * h;
  Vec3 lo = rod.base_position - clamp * t;
  Vec3 hi = lo;
  const auto include = [&](const Vec3& x) {
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  };
  include(rod.base_position + rod.length * t);
  for (const Vec3& x : p.spec.target) include(x);
  const double margin = mat.radius + 4.0 * h + 0.1 * rod.length;
  lo -= Vec3::Constant(margin);
  hi += Vec3::Constant(margin);
  // The first bending mode of the clamped rod: ω = 1.875² √(EI/(ρA L⁴)); damping c ≈ 2ω.
  const double omega =
      1.875 * 1.875 * std::sqrt(rod.bending_stiffness_2 / (rod.mass_per_length * std::pow(rod.length, 4)));
  std::ostringstream y;
  y.precision(17);
  y << "# The MPM check of the design of " << scene.file << " (magvine design --mpm-check; docs/design.md).\n"
    << "units: {length: mm}\n"
    << "mpm:\n"
    << "  dimension: 3\n"
    << "  cell: " << h * 1e3 << "\n"
    << "  particles_per_cell: " << particles_per_cell << "\n"
    << "  duration: " << duration << "\n"
    << "  damping: " << 2.0 * omega << "\n";
  if (!rod.gravity.isZero()) y << "  gravity: " << plain(rod.gravity) << "\n";
  y << "  domain: {min: " << mm(lo) << ", max: " << mm(hi) << ", walls: slip}\n"
    << "  settle: {window: 0.05, tolerance: " << 1e-4 * rod.length * 1e3 << "}\n"
    << "bodies:\n"
    << "  - name: catheter\n"
    << "    shape: cylinder\n"
    << "    from: " << mm(rod.base_position - clamp * t) << "\n"
    << "    to: " << mm(rod.base_position + rod.length * t) << "\n"
    << "    radius: " << mat.radius * 1e3 << "\n"
    << "    material: {shear_modulus: " << mat.shear_modulus << ", density: " << mat.density << "}\n"
    << "    sections:\n";
  const char* axes[] = {"x", "y", "z"};
  const double sign = t[axis] > 0.0 ? 1.0 : -1.0;
  const double base = rod.base_position[axis];
  const std::vector<std::pair<double, double>> spans = design::DesignObjective(p).section_spans();
  for (std::size_t su = 0; su < spans.size(); ++su) {
    const double a = base + sign * spans[su].first;
    const double e = base + sign * spans[su].second;
    y << "      - {axis: " << axes[axis] << ", from: " << std::min(a, e) * 1e3 << ", to: " << std::max(a, e) * 1e3
      << ", remanence: " << design.remanences[su] << ", direction: " << plain(rod.base_frame * design.directions[su])
      << "}\n";
  }
  // The clamp holds the grid behind the base only: padded across the axis, not along it (padded along it too, it
  // held r + h of the free rod as well, 3 mm of 40, and the rod bent about a fifth less; found in review).
  const Vec3 side = (mat.radius + h) * (Vec3::Ones() - t.cwiseAbs());
  y << "clamps:\n"
    << "  - {min: " << mm((rod.base_position - (clamp + h) * t).cwiseMin(rod.base_position) - side)
    << ", max: " << mm((rod.base_position - (clamp + h) * t).cwiseMax(rod.base_position) + side) << "}\n"
    << "field: {b: " << plain(b) << "}\n"
    << "probes:\n";
  const std::size_t k_count = p.spec.target.size();
  for (std::size_t k = 1; k < k_count; ++k) {  // (the target's first point is the clamped base)
    const double s = rod.length * static_cast<double>(k) / static_cast<double>(k_count - 1);
    y << "  - {name: p" << k << ", at: " << mm(rod.base_position + s * t) << ", radius: " << 0.6 * mat.radius * 1e3
      << "}\n";
  }
  return y.str();
}

void check_design_mpm_scene(const DesignScene& scene, const design::Design& design, double cell,
                            int particles_per_cell) {
#if MAGVINE_WITH_MPM
  (void)parse_mpm_scene(design_mpm_scene_yaml(scene, design, cell, particles_per_cell), scene.file + " (MPM check)");
#else
  (void)scene;
  (void)design;
  (void)cell;
  (void)particles_per_cell;
  throw InputError("--mpm-check: this magvine was built without the MPM module (configure with -DMAGVINE_WITH_MPM=ON)");
#endif
}

DesignMpmCheck run_design_mpm_check(const DesignScene& scene, const design::DesignResult& result,
                                    const std::filesystem::path& dir, double cell, int particles_per_cell,
                                    const std::function<void(double)>& progress) {
#if MAGVINE_WITH_MPM
  const std::string text = design_mpm_scene_yaml(scene, result.design, cell, particles_per_cell);
  const std::filesystem::path file = dir / "mpm_check.yaml";
  const MpmScene mpm = parse_mpm_scene(text, file.string());
  create_output_directory(dir);
  write_file_atomically(file, text);
  const MpmResult run = run_mpm_scene(mpm, progress);
  write_mpm_outputs(mpm, run, dir / "mpm_check");
  DesignMpmCheck out;
  out.settled = run.settled;
  out.simulated_s = run.time;
  out.runtime_s = run.runtime_s;
  out.steps = run.steps;
  out.particles = static_cast<long>(mpm.positions.size());
  out.failure = run.failure;
  if (!run.ok || run.samples.empty()) return out;
  // Probe k − 1 follows target point k (k ≥ 1; point 0 is the clamped base in both models). A probe is the mean of
  // its particles, so it starts at an arc length of its own (the tip's, inside the rod's end): the rod is compared
  // at that arc length, read from the probe's first sample.
  const robot::RodModel& model = scene.problem.model;
  const robot::RodState& state = result.state;
  const auto rod_at = [&](double s) {
    const double u = std::clamp(s / model.length, 0.0, 1.0) * model.edges;
    const int i = std::min(static_cast<int>(std::floor(u)), model.edges - 1);
    const double w = u - i;
    return Vec3((1.0 - w) * state.x[static_cast<std::size_t>(i)] + w * state.x[static_cast<std::size_t>(i) + 1]);
  };
  const std::vector<Vec3>& first = run.samples.front().probes;
  const std::vector<Vec3>& last = run.samples.back().probes;
  double sum = 0.0;
  double target = 0.0;
  const std::size_t count = last.size();
  for (std::size_t q = 0; q < count; ++q) {
    const double s = (first[q] - model.base_position).dot(model.base_frame.col(0));
    const double d = (last[q] - rod_at(s)).norm();
    sum += d * d;
    out.max = std::max(out.max, d);
    target += (last[q] - scene.problem.spec.target[q + 1]).squaredNorm();
  }
  out.rms = std::sqrt(sum / static_cast<double>(count));
  out.target_rms = std::sqrt(target / static_cast<double>(count));
  return out;
#else
  (void)scene;
  (void)result;
  (void)dir;
  (void)cell;
  (void)particles_per_cell;
  (void)progress;
  throw InputError("--mpm-check: this magvine was built without the MPM module (configure with -DMAGVINE_WITH_MPM=ON)");
#endif
}

void add_mpm_check_to_design_json(const DesignMpmCheck& check, const std::filesystem::path& dir) {
  std::ifstream in(dir / "design.json");
  nlohmann::json j = nlohmann::json::parse(in);
  j["mpm_check"] = {{"rms_m", check.rms},
                    {"max_m", check.max},
                    {"target_rms_m", check.target_rms},
                    {"settled", check.settled},
                    {"simulated_s", check.simulated_s},
                    {"runtime_s", check.runtime_s},
                    {"steps", check.steps},
                    {"particles", check.particles},
                    {"failure", check.failure}};
  write_file_atomically(dir / "design.json", j.dump(2) + "\n");
}

}  // namespace magvine::scene
