#include <algorithm>
#include <cmath>
#include <memory>
#include <sstream>

#include "experiment_internal.hpp"
#include "magvine/core/units.hpp"

namespace magvine::scene::detail {

std::optional<MagnetBody> magnet_body(const magnetics::FieldModel& magnets, std::size_t i) {
  const auto* cylinder = std::get_if<magnetics::CylinderMagnet>(&magnets.sources[i]);
  if (cylinder == nullptr) return std::nullopt;
  return MagnetBody{cylinder->radius(), 0.5 * cylinder->length()};
}

std::size_t vertices_inside(const anatomy::TriangleMesh& mesh, const MagnetBody& body, const Vec3& centre,
                            const Vec3& axis, double* depth) {
  const double r = body.radius + kMagnetClearance;
  const double h = body.half_length + kMagnetClearance;
  std::size_t count = 0;
  double deepest = 0.0;
  for (const Vec3& v : mesh.vertices) {
    const Vec3 d = v - centre;
    const double a = std::abs(d.dot(axis));
    if (a > h) continue;
    const double rho = (d - d.dot(axis) * axis).norm();
    if (rho > r) continue;
    ++count;
    deepest = std::max(deepest, std::min(h - a, r - rho));
  }
  if (depth != nullptr) *depth = deepest;
  return count;
}

std::string overlap_problem(const anatomy::TriangleMesh& mesh, const magnetics::FieldModel& magnets, std::size_t i,
                            const Vec3& centre, const Vec3& axis) {
  const std::optional<MagnetBody> body = magnet_body(magnets, i);
  if (!body) return {};
  double depth = 0.0;
  if (vertices_inside(mesh, *body, centre, axis.normalized(), &depth) == 0) return {};
  std::ostringstream why;
  why.precision(3);
  why << "the magnet would overlap the anatomy (magnets[" << i << "]: the airway wall reaches " << 1e3 * depth
      << " mm into it, 2 mm clearance included): an EPM stays outside the patient";
  return why.str();
}

std::string path_overlap_problem(const anatomy::TriangleMesh& mesh, const magnetics::FieldModel& magnets, std::size_t i,
                                 const MagnetKeyframe& a, const MagnetKeyframe& b) {
  if (!magnet_body(magnets, i)) return {};
  const double turn = std::acos(std::clamp(a.axis.normalized().dot(b.axis.normalized()), -1.0, 1.0));
  const int samples = std::max(
      1, static_cast<int>(std::ceil(std::max((b.position - a.position).norm() / 2e-3, turn / (2.0 * kDegToRad)))));
  for (int k = 1; k <= samples; ++k) {
    const double t = a.time + (b.time - a.time) * k / samples;
    const MagnetKeyframe at = magnetics::interpolate({a, b}, t);
    std::string why = overlap_problem(mesh, magnets, i, at.position, at.axis);
    if (why.empty()) continue;
    if (k < samples) {
      std::ostringstream where;
      where.precision(4);
      where << "on its way there, at " << t << " s: ";
      why = where.str() + why;
    }
    return why;
  }
  return {};
}

void aim_at(ExperimentScene& scene, int branch) {
  const anatomy::AirwayBranch& b = scene.anatomy->graph->branches[static_cast<std::size_t>(branch)];
  const anatomy::AirwayNode& end = scene.anatomy->graph->nodes[b.nodes.back()];
  scene.navigator->target = b.name;
  scene.navigator->target_branch = branch;
  scene.target = end.position;
  scene.target_tolerance = 1.5 * end.radius;
  if (scene.platform) {
    auto platform = std::make_shared<platform::PlatformModel>(*scene.platform);
    platform::place_arms_for(*platform, end.position);
    scene.platform = std::move(platform);
  }
}

}  // namespace magvine::scene::detail
