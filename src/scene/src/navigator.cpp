#include "magvine/scene/navigator.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <limits>

#include "experiment_internal.hpp"
#include "magvine/anatomy/airway_graph.hpp"
#include "magvine/core/text.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/dipole.hpp"

namespace magvine::scene {

double arc_length_of_nearest(const std::vector<Vec3>& path, const Vec3& x) {
  double best = std::numeric_limits<double>::infinity();
  double at = 0.0;
  double run = 0.0;
  for (std::size_t k = 0; k + 1 < path.size(); ++k) {
    const Vec3 d = path[k + 1] - path[k];
    const double l = d.norm();
    const double f = l > 0.0 ? std::clamp((x - path[k]).dot(d) / (l * l), 0.0, 1.0) : 0.0;
    const double d2 = (path[k] + f * d - x).squaredNorm();
    if (d2 < best) {
      best = d2;
      at = run + f * l;
    }
    run += l;
  }
  return at;
}

std::vector<Vec3> planned_path(const anatomy::AirwayGraph& graph, int branch) {
  std::vector<Vec3> path;
  for (const int b : anatomy::path_from_root(graph, branch)) {
    const anatomy::AirwayBranch& br = graph.branches[static_cast<std::size_t>(b)];
    for (std::size_t k = path.empty() ? 0 : 1; k < br.nodes.size(); ++k)
      path.push_back(graph.nodes[br.nodes[k]].position);
  }
  return path;
}

Vec3 point_at_arc_length(const std::vector<Vec3>& path, double s) {
  double left = std::max(0.0, s);
  for (std::size_t k = 0; k + 1 < path.size(); ++k) {
    const double l = (path[k + 1] - path[k]).norm();
    if (l >= left) return path[k] + (l > 0.0 ? left / l : 0.0) * (path[k + 1] - path[k]);
    left -= l;
  }
  return path.back();
}

MagnetKeyframe pose_on_line(const Navigator& nav, const Vec3& tip, const Mat3& tip_frame,
                            const std::optional<Vec3>& skin, const Vec3& aim, const Vec3& u, double distance,
                            double time, const Vec3& offset) {
  MagnetKeyframe k;
  k.time = time;
  k.position = tip + distance * u + offset;
  k.axis = u;
  if (skin) {
    // Gradient mode for a magnetic skin (thesis 4.7.1): the field at the tip along the skin's moment m, so the skin
    // is pulled towards the magnet without a torque. A dipole's field at r̂ (magnet to tip) is ∝ (3r̂r̂ᵀ − I)m_e,
    // whose inverse gives m_e ∝ (3/2)(m·r̂)r̂ − m for a field along b.
    const Vec3 m = (tip_frame * *skin).normalized();
    Vec3 b = m;
    if (nav.skin_mode == Navigator::SkinMode::kTorque) {
      // Torque mode: the field along ω' × m, where ω = t × a turns the tangent t towards the aim's side a and ω' is
      // ω without its part along m (no torque turns the body about m): m × (ω' × m) = ω'.
      const Vec3 t = tip_frame.col(0);
      const Vec3 v = aim - tip;
      const Vec3 side = v - v.dot(t) * t;
      if (side.norm() > 0.1 * v.norm()) {
        const Vec3 omega = t.cross(side.normalized());
        const Vec3 reachable = omega - omega.dot(m) * m;
        if (reachable.norm() > 0.5 * omega.norm()) b = reachable.cross(m).normalized();
      }
    }
    const Vec3 axis = magnetics::dipole_moment_for_field(-u, b);  // -u: from the magnet to the tip
    if (axis.norm() > 1e-9) k.axis = axis.normalized();
  }
  return k;
}

Vec3 aim_point(const Navigator& nav, const std::vector<Vec3>& path, const Vec3& tip) {
  return point_at_arc_length(path, arc_length_of_nearest(path, tip) + nav.lead);
}

MagnetKeyframe navigate(const Navigator& nav, const std::vector<Vec3>& path, const Vec3& tip, const Mat3& tip_frame,
                        const std::optional<Vec3>& skin, double time, const Vec3& offset, Vec3& line) {
  const Vec3 aim = aim_point(nav, path, tip);
  Vec3 u = aim - tip;
  if (nav.lateral > 0.0) {
    // Only the pull across the tip bends it (growth carries it forward): take away that share of the component
    // along the tip's tangent, unless the aim lies nearly straight ahead.
    const Vec3 t = tip_frame.col(0);
    if ((u - u.dot(t) * t).norm() > 0.1 * u.norm()) u -= nav.lateral * u.dot(t) * t;
  }
  if (u.norm() < 1e-9) u = path.back() - tip;
  if (u.norm() < 1e-9) u = Vec3::UnitX();
  u.normalize();
  line = u;
  return pose_on_line(nav, tip, tip_frame, skin, aim, u, std::clamp(nav.distance, nav.min_distance, nav.max_distance),
                      time, offset);
}

NavigatorController::NavigatorController(const ExperimentScene& scene) : m_scene(scene), m_nav(*scene.navigator) {
  const anatomy::AirwayGraph& graph = *scene.anatomy->graph;
  m_plan = anatomy::path_from_root(graph, m_nav.target_branch);
  m_path = planned_path(graph, m_nav.target_branch);
  // A magnetic skin's moment direction in the body frame (the skin modes); none for a fill.
  if (robot::has_magnetic_skin(scene.vine)) {
    m_skin = std::copysign(1.0, scene.vine.skin_remanence) * scene.vine.skin_direction.normalized();
  }
  // The first pose from the straight body's tip, before the vine is built.
  const Vec3 tip0 = scene.base_position + scene.vine.length * scene.base_frame.col(0);
  m_pose = navigate(m_nav, m_path, tip0, scene.base_frame, m_skin, 0.0, scene.navigator_offset, m_line);
  keep_clear(tip0);
  m_next_placement = m_nav.interval;
  m_shortest = scene.vine.length;
  m_on_path = scene.vine.length;
}

void NavigatorController::use_platform(platform::PlatformRun* run, double t, const Vec3& tip, const Mat3& tip_frame,
                                       double length, std::vector<RunEvent>& events) {
  m_platform = run;
  m_arm = run->arm_of_magnet(m_nav.magnet);
  if (m_arm < 0) {
    m_platform = nullptr;
    return;
  }
  m_pose = navigate(m_nav, m_path, tip, tip_frame, m_skin, t, m_scene.navigator_offset, m_line);
  place_with_arm(t, tip, tip_frame, length, events);
}

void NavigatorController::place_with_arm(double t, const Vec3& tip, const Mat3& tip_frame, double length,
                                         std::vector<RunEvent>& events) {
  // The ideal line from the tip (m_line) is where the magnet pulls best, but with the patient round the airway its
  // distance puts it inside the body. Lines turned off it by θ (0–90°, six azimuths each) are each followed out
  // from the tip to the least distance d (≥ the navigator's) at which the magnet clears the skin. What steers is the
  // pull across the tip towards the aim's side s (the part of aim − tip normal to the tip's tangent): a line scores
  // max(0, line·s) · (distance/d)⁴ (the pull points at the magnet and falls with the fourth power of the distance
  // for a saturated fill), or cos θ · (distance/d)⁴ where the aim lies straight ahead.
  const Vec3 aim = aim_point(m_nav, m_path, tip);
  const Vec3 from = tip + m_scene.navigator_offset;
  const Vec3 u = m_line;
  const Vec3 tangent = tip_frame.col(0);
  Vec3 side = (aim - tip) - (aim - tip).dot(tangent) * tangent;
  const bool turning = side.norm() > 0.1 * (aim - tip).norm();
  if (turning) side.normalize();
  const Vec3 e1 = u.unitOrthogonal(), e2 = u.cross(e1);
  struct Candidate {
    double score;
    MagnetKeyframe pose;
  };
  std::vector<Candidate> candidates;
  constexpr int kAzimuths = 6;
  for (const double theta_deg : {0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0}) {
    const double theta = theta_deg * kDegToRad;
    for (int k = 0; k < (theta_deg == 0.0 ? 1 : kAzimuths); ++k) {
      const double phi = 2.0 * kPi * k / kAzimuths;
      const Vec3 line = std::cos(theta) * u + std::sin(theta) * (std::cos(phi) * e1 + std::sin(phi) * e2);
      const double aligned = turning ? line.dot(side) : std::cos(theta);
      if (aligned <= 0.0) continue;
      MagnetKeyframe pose = pose_on_line(m_nav, tip, tip_frame, m_skin, aim, line, m_nav.distance, t,
                                         m_scene.navigator_offset);
      const double d = m_platform->clear_distance(m_arm, from, line, pose.axis, m_nav.distance, m_nav.max_distance);
      if (!std::isfinite(d)) continue;
      pose.position = from + d * line;
      candidates.push_back({aligned * std::pow(m_nav.distance / d, 4), pose});
    }
  }
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const Candidate& a, const Candidate& b) { return a.score > b.score; });
  // The best few lines are tried with the joints near where the arm is (a small move), the best three also with a
  // new posture; the winner is the best score times exp(−T / 1 s), T the arm's travel time there at its joints'
  // speeds, so that a slightly better line does not cost a long swing of the arm while the vine grows, but a much
  // better one (the other side of the patient) is worth it.
  constexpr std::size_t kNearTries = 8, kFarTries = 3;
  constexpr double kTravelScale = 1.0;  // [s]
  double best_score = 0.0;
  std::optional<std::pair<platform::Placement, MagnetKeyframe>> best;
  for (std::size_t i = 0; i < std::min(kNearTries, candidates.size()); ++i) {
    const Candidate& c = candidates[i];
    for (const bool near : {true, false}) {
      if (!near && i >= kFarTries) break;
      platform::Placement p = m_platform->evaluate(m_arm, c.pose.position, c.pose.axis, near);
      if (!p.feasible) continue;
      const double score = c.score * std::exp(-m_platform->travel_time(m_arm, p.q) / kTravelScale);
      if (score > best_score) {
        best_score = score;
        best.emplace(std::move(p), c.pose);
      }
      break;  // a near solution needs no new posture
    }
  }
  if (best) {
    m_platform->set_goal(m_arm, best->first.q);
    m_pose = best->second;
    return;
  }
  // Nothing feasible: the arm keeps its goal (the last feasible placement).
  events.push_back({t, length, EventKind::kWorkspace,
                    "no placement of the navigator's magnet within 90 degrees of its line and max_distance is "
                    "reachable by the arm clear of the patient; it holds its last one"});
}

bool NavigatorController::keep_clear(const Vec3& tip) {
  // Moved out along its line from the tip, 5 mm at a time up to max_distance, while the magnet (body, if any) would
  // overlap the airway mesh.
  const std::optional<detail::MagnetBody> body =
      detail::magnet_body(*m_scene.magnets, static_cast<std::size_t>(m_nav.magnet));
  if (!body) return true;
  const anatomy::TriangleMesh& mesh = m_scene.anatomy->mesh();
  double d = (m_pose.position - tip).dot(m_line);
  while (detail::vertices_inside(mesh, *body, m_pose.position, m_pose.axis) > 0) {
    if (d >= m_nav.max_distance) return false;
    const double next = std::min(m_nav.max_distance, d + 5e-3);
    m_pose.position += (next - d) * m_line;
    d = next;
  }
  return true;
}

void NavigatorController::place(double t, const Vec3& tip, const Mat3& tip_frame, double length,
                                std::vector<RunEvent>& events) {
  if (t < m_next_placement - 1e-12) return;
  m_pose = navigate(m_nav, m_path, tip, tip_frame, m_skin, t, m_scene.navigator_offset, m_line);
  if (m_platform != nullptr) {
    place_with_arm(t, tip, tip_frame, length, events);
  } else if (!keep_clear(tip) && !m_workspace_warned) {
    m_workspace_warned = true;
    events.push_back({t, length, EventKind::kWorkspace,
                      "the navigator's magnet overlaps the anatomy even at max_distance; placed there anyway"});
  }
  m_next_placement += m_nav.interval;
}

void NavigatorController::regulate(double t, double length, int branch, bool reached, const Vec3& tip,
                                   robot::GrowthControl& control, std::vector<RunEvent>& events) {
  const anatomy::AirwayGraph& graph = *m_scene.anatomy->graph;
  // Held (the boost's and the recovery's test): the length has not changed since m_grown_at, and no tether or made
  // length caps it.
  if (length != m_grown_length || length >= std::min(control.tether_length, m_scene.growth.max_length) - 1e-9) {
    m_grown_length = length;
    m_grown_at = t;
  }
  if (m_nav.boost_pressure > 0.0) {
    // Pressure boost for a held tip: at least boost_pressure until it has grown boost_length further.
    if (m_boost_until >= 0.0 && length >= m_boost_until) m_boost_until = -1.0;
    if (m_boost_until < 0.0 && t - m_grown_at >= m_nav.boost_after - 1e-9) m_boost_until = length + m_nav.boost_length;
    if (m_boost_until >= 0.0) control.pressure = std::max(control.pressure, m_nav.boost_pressure);
  }
  if (m_nav.deflate_pressure > 0.0) {
    // Pressure regulation (thesis 4.7.3): once per junction on the path, deflate for deflate_time while the magnet
    // bends the body towards the next branch, then back to the schedule (the next branch's walls hold the turn).
    const int here = branch >= 0 ? branch : anatomy::nearest_centreline_point(graph, tip).branch;
    const auto at = std::find(m_plan.begin(), m_plan.end(), here);
    if (at != m_plan.end() && *at != m_plan.back() &&
        std::find(m_deflated_at.begin(), m_deflated_at.end(), here) == m_deflated_at.end() &&
        (tip - graph.nodes[graph.branches[static_cast<std::size_t>(here)].nodes.back()].position).norm() <=
            m_nav.junction_distance) {
      m_deflated_at.push_back(here);
      m_deflate_until = t + m_nav.deflate_time;
    }
    if (t < m_deflate_until) control.pressure = std::min(control.pressure, m_nav.deflate_pressure);
  }
  if (m_nav.recover.retries > 0 && !reached) {
    recover(t, length, branch, control, events);
    if (m_retracting) m_boost_until = -1.0;
  }
}

void NavigatorController::recover(double t, double length, int branch, robot::GrowthControl& control,
                                  std::vector<RunEvent>& events) {
  // control.navigator.recover (Navigator::Recovery): watches where the tip is and whether it grows, and takes the
  // pressure and the tether over while it backs the vine out of a wrong turn.
  const Navigator::Recovery& options = m_nav.recover;
  const double retraction_pressure = m_scene.growth.retraction_pressure;
  const anatomy::AirwayGraph& graph = *m_scene.anatomy->graph;
  const bool off_path = branch >= 0 && std::find(m_plan.begin(), m_plan.end(), branch) == m_plan.end();
  const double held_for = t - std::max(m_grown_at, m_deflate_until);  // a deflation holds it too
  if (m_retracting) {
    // Done at the length asked for, or once the last step's tether was there and the vine stopped shortening
    // (whole edges go).
    const double tether = std::max(m_to, m_from - options.speed * (t - m_since));
    const bool settled = m_last_tether <= m_to && length >= m_last;
    m_last = length;
    m_last_tether = tether;
    if (length <= m_to + 1e-9 || settled) {
      m_retracting = false;
      m_on_path = length;
      events.push_back(
          {t, length, EventKind::kRecover, printf_string("back at %.1f mm: the pressure is given back", 1e3 * length)});
    } else {
      control.pressure = std::min(control.pressure, retraction_pressure);
      control.tether_length = std::min(control.tether_length, tether);
      return;
    }
  }
  if (!off_path) m_on_path = length;
  if (m_recovery_used >= options.retries) return;
  std::string why;
  double to = 0.0;
  if (off_path && length - m_on_path >= options.past - 1e-9) {
    why = printf_string("the tip has grown %.1f mm into %s, off the path", 1e3 * (length - m_on_path),
                        graph.branches[static_cast<std::size_t>(branch)].name.c_str());
    to = m_on_path - options.back;
  } else if (held_for >= options.after - 1e-9) {
    why = printf_string("the tip has been held at %.1f mm for %.1f s", 1e3 * length, held_for);
    to = length - options.back;
  } else {
    return;
  }
  ++m_recovery_used;
  m_retracting = true;
  m_from = length;
  m_last = length;
  m_last_tether = length;
  m_to = std::max(m_shortest, to);
  m_since = t;
  events.push_back({t, length, EventKind::kRecover,
                    why + printf_string(": deflated to %.1f kPa, the tether pulls it back to %.1f mm (retry %d of %d)",
                                        retraction_pressure / kKpaToPa, 1e3 * m_to, m_recovery_used, options.retries)});
  control.pressure = std::min(control.pressure, retraction_pressure);
}

}  // namespace magvine::scene
