#include "magvine/scene/navigator.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>

#include "experiment_internal.hpp"
#include "magvine/anatomy/airway_graph.hpp"
#include "magvine/core/text.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/dipole.hpp"
#include "magvine/magnetics/field_model.hpp"

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

namespace {

/// The graph's nodes along the planned path to `branch`: the branches from the root joined, each joint node once.
std::vector<std::uint32_t> plan_nodes(const anatomy::AirwayGraph& graph, int branch) {
  std::vector<std::uint32_t> nodes;
  for (const int b : anatomy::path_from_root(graph, branch)) {
    const anatomy::AirwayBranch& br = graph.branches[static_cast<std::size_t>(b)];
    for (std::size_t k = nodes.empty() ? 0 : 1; k < br.nodes.size(); ++k) nodes.push_back(br.nodes[k]);
  }
  return nodes;
}

}  // namespace

std::vector<Vec3> planned_path(const anatomy::AirwayGraph& graph, int branch) {
  std::vector<Vec3> path;
  for (const std::uint32_t n : plan_nodes(graph, branch)) path.push_back(graph.nodes[n].position);
  return path;
}

std::vector<double> planned_radii(const anatomy::AirwayGraph& graph, int branch) {
  std::vector<double> radii;
  for (const std::uint32_t n : plan_nodes(graph, branch)) radii.push_back(graph.nodes[n].radius);
  return radii;
}

std::vector<Vec3> taut_path(const std::vector<Vec3>& path, const std::vector<double>& clearance, int max_sweeps) {
  if (clearance.size() != path.size()) {
    throw std::invalid_argument("taut_path: " + std::to_string(clearance.size()) + " clearances for " +
                                std::to_string(path.size()) + " points");
  }
  std::vector<Vec3> p = path;
  if (p.size() < 3) return p;
  constexpr double kStill = 1e-6;  // [m]
  for (int sweep = 0; sweep < max_sweeps; ++sweep) {
    double moved = 0.0;
    for (std::size_t i = 1; i + 1 < p.size(); ++i) {
      const Vec3 off = 0.5 * (p[i - 1] + p[i + 1]) - path[i];
      const double r = std::max(0.0, clearance[i]);
      const Vec3 q = path[i] + (off.norm() > r ? Vec3(off * (r / off.norm())) : off);
      moved = std::max(moved, (q - p[i]).norm());
      p[i] = q;
    }
    if (moved < kStill) break;
  }
  return p;
}

double path_progress(const std::vector<Vec3>& path, const Vec3& target, const Vec3& tip) {
  const double goal = arc_length_of_nearest(path, target);
  return goal > 0.0 ? std::clamp(arc_length_of_nearest(path, tip) / goal, 0.0, 1.0) : 1.0;
}

std::vector<Vec3> target_path(const ExperimentScene& scene) {
  if (!scene.anatomy->graph || !scene.target) return {};
  const int branch = scene.navigator ? scene.navigator->target_branch
                                     : anatomy::nearest_centreline_point(*scene.anatomy->graph, *scene.target).branch;
  return planned_path(*scene.anatomy->graph, branch);
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

namespace {

/// The magnet's line from the tip towards `towards` (not normalised): with `lateral`, only the pull across the tip
/// bends it (growth carries it forward), so that share of the component along the tip's tangent goes, unless the aim
/// lies nearly straight ahead. Unit; `fallback` where nothing is left.
Vec3 magnet_line(const Navigator& nav, Vec3 u, const Mat3& tip_frame, const Vec3& fallback) {
  if (nav.lateral > 0.0) {
    const Vec3 t = tip_frame.col(0);
    if ((u - u.dot(t) * t).norm() > 0.1 * u.norm()) u -= nav.lateral * u.dot(t) * t;
  }
  if (u.norm() < 1e-9) u = fallback;
  if (u.norm() < 1e-9) u = Vec3::UnitX();
  return u.normalized();
}

}  // namespace

MagnetKeyframe navigate(const Navigator& nav, const std::vector<Vec3>& path, const Vec3& tip, const Mat3& tip_frame,
                        const std::optional<Vec3>& skin, double time, const Vec3& offset, Vec3& line) {
  const Vec3 aim = aim_point(nav, path, tip);
  line = magnet_line(nav, aim - tip, tip_frame, path.back() - tip);
  return pose_on_line(nav, tip, tip_frame, skin, aim, line,
                      std::clamp(nav.distance, nav.min_distance, nav.max_distance), time, offset);
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
  // The arms it steers: the one holding its magnet first, then (dEPM) another arm whose magnet the scene does not
  // keyframe. With two, each keeps to its own side of the patient (the magnets would attract each other across).
  m_held.clear();
  const auto add = [&](int arm) {
    HeldMagnet h;
    h.arm = arm;
    h.magnet = run->model().arms[static_cast<std::size_t>(arm)].magnet;
    const auto i = static_cast<std::size_t>(h.magnet);
    h.own.add(m_scene.magnets->sources[i], m_scene.magnets->rest_poses[i]);
    m_held.push_back(std::move(h));
  };
  const int first = run->arm_of_magnet(m_nav.magnet);
  if (first < 0) return;
  add(first);
  for (std::size_t a = 0; a < run->model().arms.size(); ++a) {
    const int magnet = run->model().arms[a].magnet;
    if (static_cast<int>(a) != first && m_scene.magnet_keyframes[static_cast<std::size_t>(magnet)].empty()) {
      add(static_cast<int>(a));
    }
  }
  if (m_held.size() > 1) {
    for (HeldMagnet& h : m_held) h.side = run->arm_side(h.arm);
  }
  m_platform = run;
  m_pose = navigate(m_nav, m_path, tip, tip_frame, m_skin, t, m_scene.navigator_offset, m_line);
  for (HeldMagnet& h : m_held) {
    place_with_arm(h, t, tip, tip_frame, length, events);
    run->jump_to_goal(h.arm);  // there before the run starts, and before the next arm chooses
  }
  m_pose = m_held.front().placement;
}

bool NavigatorController::steers(int magnet) const {
  if (magnet == m_nav.magnet) return true;
  return std::any_of(m_held.begin(), m_held.end(), [&](const HeldMagnet& h) { return h.magnet == magnet; });
}

double NavigatorController::pull(const HeldMagnet& h, const MagnetKeyframe& pose, const Vec3& tip,
                                 const Vec3& towards) const {
  // The fill's force points up the gradient of |B| (a saturated fill: F = M_s V ∇|B|, PHYSICS.md §2), so its part
  // along `towards` is what bends the tip there: ∇|B| = Gᵀ B / |B| from the magnet's exact field.
  const magnetics::Pose p = magnetics::pose_at(h.own.rest_poses.front(), pose.position, pose.axis);
  const magnetics::FieldSample f = magnetics::field_gradient(h.own, std::span(&p, 1), tip);
  const double b = f.b.norm();
  return b > 0.0 ? (f.g.transpose() * f.b).dot(towards) / b : 0.0;
}

void NavigatorController::place_with_arm(HeldMagnet& h, double t, const Vec3& tip, const Mat3& tip_frame, double length,
                                         std::vector<RunEvent>& events) {
  // While the arm is still on its way to the last placement, it goes on; with two arms, one moves at a time (each
  // checks its way against the other's magnet where it is).
  for (const HeldMagnet& other : m_held) {
    if (h.placed && m_platform->remaining_time(other.arm) > m_nav.interval) return;
  }
  // With the patient round the airway the magnet can only be outside the body: on the shell round the torso at the
  // skin clearance (PlatformRun::shell_point), or stood off 10 cm further out. Candidates: every 15° round the
  // torso, at the tip's level and up to 6 cm above and 9 cm below it (3 cm apart), on the shell and stood off. A
  // candidate scores by what steers: for a fill, the pull ∇|B| at the tip along the aim's side s (the part of
  // aim − tip across the tip's tangent; along the aim where it lies straight ahead), from the magnet's exact field:
  // negative where it pulls away, so that for a side no placement pulls towards (the back of a supine patient,
  // where the table is) the magnet stands off where it pulls away least and gravity takes the tip; for a magnetic
  // skin, whose pull and torque both matter, max(0, line·s) · (distance/d)⁴ (the dipole's fall-off of the force at
  // distance d along the line to it), on the shell only.
  const Vec3 aim = aim_point(m_nav, m_path, tip);
  const Vec3 tangent = tip_frame.col(0);
  Vec3 side = (aim - tip) - (aim - tip).dot(tangent) * tangent;
  const bool turning = side.norm() > 0.1 * (aim - tip).norm();
  side = turning ? Vec3(side.normalized()) : Vec3((aim - tip).normalized());
  const Vec3 from = tip + m_scene.navigator_offset;
  // The pose at shell point (angle, level): a fill's magnet faces the skin (its axis along the shell's outward
  // direction: its pole towards the body); a skin's takes the axis its mode sets on the line from the tip (which
  // points nearly the same way), and the shell's distance for that axis.
  const auto pose_at_shell = [&](double angle, double level, double standoff) -> std::optional<MagnetKeyframe> {
    const Vec3 out = m_platform->shell_direction(angle);
    MagnetKeyframe k;
    k.time = t;
    k.axis = out;
    if (m_skin) {
      const std::optional<Vec3> guess = m_platform->shell_point(h.arm, angle, level, nullptr, standoff);
      if (!guess) return std::nullopt;
      k = pose_on_line(m_nav, tip, tip_frame, m_skin, aim, (*guess - from).normalized(), 0.0, t,
                       m_scene.navigator_offset);
    }
    std::optional<Vec3> p;
    if (m_skin) {
      p = m_platform->shell_point(h.arm, angle, level, &k.axis, standoff);
    } else {
      // A fill's shell point depends on the place alone (its axis is the outward normal): cached per place, to
      // 0.1 mm in level and 0.01° in angle (the slides' places are arbitrary, the candidates' on a grid).
      const auto key = std::make_tuple(std::lround(angle * 1e4), std::lround(level * 1e4), std::lround(standoff * 1e4));
      const auto it = h.shell_cache.find(key);
      if (it != h.shell_cache.end()) {
        p = it->second;
      } else {
        p = m_platform->shell_point(h.arm, angle, level, &k.axis, standoff);
        h.shell_cache.emplace(key, p);
      }
    }
    if (!p) return std::nullopt;
    k.position = *p;
    return k;
  };
  const auto score = [&](const MagnetKeyframe& pose) {
    if (!m_skin) return pull(h, pose, tip, side);
    const Vec3 line = pose.position - from;
    return std::max(0.0, line.normalized().dot(side)) * std::pow(m_nav.distance / line.norm(), 4);
  };
  struct Candidate {
    double score;
    std::array<double, 3> shell;  ///< angle, level, standoff
    MagnetKeyframe pose;
  };
  std::vector<Candidate> candidates;
  // The tip's level to the nearest centimetre (candidates on a fixed grid: their shell points are computed once).
  const double tip_level = 0.01 * std::round(100.0 * m_platform->shell_coordinates(tip).second);
  constexpr int kAngles = 24;
  std::vector<double> levels;
  for (const double dz : {-0.09, -0.06, -0.03, 0.0, 0.03, 0.06}) {
    const double level = m_platform->shell_level(h.arm, tip_level + dz);  // kept over the torso
    if (std::find(levels.begin(), levels.end(), level) == levels.end()) levels.push_back(level);
  }
  constexpr double kStandoff = 0.1;  // [m]
  for (const double standoff : {0.0, m_skin ? -1.0 : kStandoff}) {
    if (standoff < 0.0) continue;
    for (const double level : levels) {
      for (int k = 0; k < kAngles; ++k) {
        const double angle = 2.0 * kPi * k / kAngles;
        // Two arms: each within 60° of its own side, so that the magnets (which attract each other) stay apart.
        if (h.side.squaredNorm() > 0.0 && m_platform->shell_direction(angle).dot(h.side) < 0.5) continue;
        if (const std::optional<MagnetKeyframe> pose = pose_at_shell(angle, level, standoff)) {
          candidates.push_back({score(*pose), {angle, level, standoff}, *pose});
        }
      }
    }
  }
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const Candidate& a, const Candidate& b) { return a.score > b.score; });
  // The best placement the arm can take up from any posture (a new posture, the way there checked and backed out
  // round the patient if need be): the first one (the run starts with the arm there), and the way out when no
  // slide is possible.
  const auto jump = [&]() {
    for (std::size_t i = 0; i < std::min<std::size_t>(6, candidates.size()); ++i) {
      const platform::Placement p =
          m_platform->evaluate(h.arm, candidates[i].pose.position, candidates[i].pose.axis, false, !m_skin);
      if (!p.feasible) continue;
      m_platform->set_goal(h.arm, p);
      h.placement = candidates[i].pose;
      h.placement.axis = p.axis;
      h.shell = candidates[i].shell;
      h.placed = true;
      return true;
    }
    return false;
  };
  if (!h.placed) {
    if (jump()) return;
    if (!h.warned) {
      h.warned = true;
      events.push_back({t, length, EventKind::kWorkspace,
                        "the arm can hold the navigator's magnet at none of the best placements round the patient; "
                        "it waits at its home posture"});
    }
    return;
  }
  // Then the magnet slides over the shell towards the best candidate, at most kStep a placement (so the arm moves
  // smoothly and every move is a small one from where it is), unless the best is within 5 % of where it is (then
  // it follows the tip's level only). A step the arm cannot take (a collision on the way, out of reach) is halved,
  // then the next-best candidate's direction is tried; none: it holds.
  constexpr double kStep = 0.03;   // [m] per placement
  constexpr double kRadius = 0.2;  // [m] the shell's radius, for arc lengths
  const auto [angle0, level0, standoff0] = h.shell;
  const std::optional<MagnetKeyframe> here = pose_at_shell(angle0, level0, standoff0);
  const double current = here ? score(*here) : -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < std::min<std::size_t>(3, candidates.size()); ++i) {
    const Candidate& c = candidates[i];
    if (c.score <= current + 0.05 * std::abs(current)) break;
    const double d_angle = std::remainder(c.shell[0] - angle0, 2.0 * kPi);
    const double d_level = c.shell[1] - level0;
    const double d_standoff = c.shell[2] - standoff0;
    const double arc = std::sqrt(std::pow(kRadius * d_angle, 2) + d_level * d_level + d_standoff * d_standoff);
    for (double fraction = std::min(1.0, kStep / std::max(arc, 1e-12)); fraction > 0.1; fraction *= 0.5) {
      const std::array<double, 3> at{angle0 + fraction * d_angle, level0 + fraction * d_level,
                                     standoff0 + fraction * d_standoff};
      const std::optional<MagnetKeyframe> next = pose_at_shell(at[0], at[1], at[2]);
      if (!next) continue;
      const platform::Placement p = m_platform->evaluate(h.arm, next->position, next->axis, true, !m_skin);
      if (!p.feasible) continue;
      m_platform->set_goal(h.arm, p);
      h.placement = *next;
      h.placement.axis = p.axis;
      h.shell = at;
      return;
    }
  }
  // No slide towards a better placement: when the best is much better (twice the pull) than where it is, a new
  // posture is worth the arm's longer way.
  if (!candidates.empty() && candidates.front().score > current + std::abs(current)) jump();
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

void NavigatorController::use_camera(std::function<std::vector<SeenLumen>()> look) {
  m_look = std::move(look);
  const anatomy::AirwayGraph& graph = *m_scene.anatomy->graph;
  // The dead reckoning's path: the plan drawn taut in its lumen, a vine's radius clear of the wall (the vine does
  // not follow the skeleton's wiggles inside a wide lumen; in the patients' graphs these make a branch's centreline
  // up to twice its chord).
  std::vector<double> clearance = planned_radii(graph, m_nav.target_branch);
  for (double& c : clearance) c = std::max(0.0, c - m_scene.vine.radius);
  m_reckon = taut_path(m_path, clearance);
  m_base_arc = arc_length_of_nearest(m_reckon, m_scene.base_position);
  if (m_scene.breathing) m_reckon_amplitudes = anatomy::breathing_amplitudes(*m_scene.breathing, m_reckon);
  airway_at(m_airway_time);
  // The plan's junctions, from the pre-operative graph: where each plan branch ends along the joined path, and the
  // points `lead` into the planned child and into its siblings.
  const auto into = [&](int branch) {
    const anatomy::AirwayBranch& b = graph.branches[static_cast<std::size_t>(branch)];
    std::vector<Vec3> line;
    for (const std::uint32_t n : b.nodes) line.push_back(graph.nodes[n].position);
    return std::array<Vec3, 2>{line.front(), point_at_arc_length(line, m_nav.lead)};
  };
  m_junctions.clear();
  m_branch_end.clear();
  for (std::size_t i = 0; i < m_plan.size(); ++i) {
    const anatomy::AirwayBranch& b = graph.branches[static_cast<std::size_t>(m_plan[i])];
    const double arc = anatomy::path_length(graph, m_plan[i]);
    m_branch_end.push_back(arc);
    if (i + 1 == m_plan.size()) break;
    Junction j;
    j.arc = arc;
    j.planned = into(m_plan[i + 1]);
    for (const int c : b.children) {
      if (c != m_plan[i + 1]) j.others.push_back(into(c));
    }
    m_junctions.push_back(std::move(j));
  }
}

Vec3 NavigatorController::moved(const Vec3& x) const {
  return m_scene.breathing ? Vec3(x + anatomy::breathing_displacement(*m_scene.breathing, x, m_airway_time)) : x;
}

void NavigatorController::airway_at(double time) {
  m_airway_time = time;
  // The dead reckoning's path as the airway is now, once per time (estimated_arc reads it several times a step).
  if (!m_look || !m_scene.breathing) return;
  anatomy::breathing_vertices(*m_scene.breathing, m_reckon, m_reckon_amplitudes, m_airway_time, m_moved_reckon);
  m_moved_base_arc = arc_length_of_nearest(m_moved_reckon, m_scene.base_position);
}

double NavigatorController::estimated_arc(double length) const {
  // The everted length is measured from the base along the plan drawn taut in its lumen (m_reckon), and the point
  // there taken back to the plan's arc, segment by segment (the taut path's point i stands for the plan's point i).
  // Breathing stretches the airway between the fixed entry and the lobes (anatomy/breathing.hpp), and the vine lies
  // along it as it is now: the taut path moved by the breathing model (known before the procedure, with the phase
  // from a respiratory sensor).
  const std::vector<Vec3>& path = m_scene.breathing ? m_moved_reckon : m_reckon;
  const double s = (m_scene.breathing ? m_moved_base_arc : m_base_arc) + length;
  double along = 0.0;  // along the dead reckoning's path [m]
  double rest = 0.0;   // the same points' arc along the plan at rest [m]
  for (std::size_t i = 0; i + 1 < path.size(); ++i) {
    const double l_path = (path[i + 1] - path[i]).norm();
    const double l_rest = (m_path[i + 1] - m_path[i]).norm();
    if (along + l_path >= s) return rest + (l_path > 0.0 ? (s - along) / l_path * l_rest : 0.0);
    along += l_path;
    rest += l_rest;
  }
  return rest + (s - along);  // past the plan's end the excess counts one for one
}

int NavigatorController::estimated_branch(double length) const {
  const double s = estimated_arc(length);
  for (std::size_t i = 0; i < m_branch_end.size(); ++i) {
    if (s <= m_branch_end[i]) return m_plan[i];
  }
  return m_plan.back();
}

Vec3 NavigatorController::oracle_line(const Vec3& tip, const Mat3& tip_frame) const {
  Vec3 line;
  (void)navigate(m_nav, m_path, tip, tip_frame, m_skin, 0.0, Vec3::Zero(), line);
  return line;
}

std::optional<Vec3> NavigatorController::estimated_tip(double length) const {
  if (!m_look) return std::nullopt;
  return point_at_arc_length(m_path, estimated_arc(length));
}

void NavigatorController::place_by_camera(double t, const Mat3& tip_frame, double length) {
  // Where the plan says the tip is (dead reckoning), and what the camera shows.
  const Navigator::Camera& cam = *m_nav.camera;
  GuidanceSample g;
  g.time = t;
  g.length = length;
  g.arc = estimated_arc(length);
  const Vec3 tip = point_at_arc_length(m_path, g.arc);
  const std::vector<SeenLumen> seen = m_look();
  g.lumens = static_cast<int>(seen.size());
  // The choice is about the first junction on the plan not yet passed by more than half the window (the tip may
  // still see both openings just past it), or by half the way to the plan's next junction where that is shorter (a
  // short branch: the junction at its end is the one the tip meets next); within the window before it, a lumen
  // scores by how much nearer its ray is to the planned child than to the nearest sibling (a common error of the
  // orientation cancels). Elsewhere, by its nearness to the plan's direction ahead.
  auto next = m_junctions.begin();
  for (; next != m_junctions.end(); ++next) {
    double keep = 0.5 * cam.junction_window;
    if (std::next(next) != m_junctions.end()) keep = std::min(keep, 0.5 * (std::next(next)->arc - next->arc));
    if (g.arc < next->arc + keep) break;
  }
  const bool at_junction = next != m_junctions.end() && next->arc - g.arc < cam.junction_window;
  // The plan's direction ahead; past the plan's end (the dead reckoning beyond it), its last segment's. Its
  // directions are the airway's as it is now (the lumens are seen in it), the plan's own at rest.
  Vec3 ahead = moved(point_at_arc_length(m_path, g.arc + m_nav.lead)) - moved(tip);
  if (ahead.norm() < 1e-9) ahead = moved(m_path.back()) - moved(m_path[m_path.size() - 2]);
  ahead.normalize();
  const Vec3 planned = at_junction ? moved_direction(next->planned) : Vec3::Zero();
  std::vector<Vec3> others;
  if (at_junction) {
    for (const std::array<Vec3, 2>& o : next->others) others.push_back(moved_direction(o));
  }
  const auto score = [&](const Vec3& d) {
    if (!at_junction) return d.dot(ahead);
    double other = -1.0;
    for (const Vec3& o : others) other = std::max(other, d.dot(o));
    return d.dot(planned) - other;
  };
  if (at_junction) g.junction = static_cast<int>(next - m_junctions.begin());
  double best = -std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < seen.size(); ++k) {
    const double sc = score(seen[k].direction);
    if (sc > best) {
      best = sc;
      g.chosen = static_cast<int>(k);
    }
  }
  // Every opening seen at a junction looks like a sibling's (one or several): the planned child is out of view, so
  // the magnet pulls the way the plan goes into it. The nearest of the sibling's openings would pull a tip that has
  // just entered the planned child, its lens still along the parent, back across the junction (traced in
  // docs/experiments.md, camera guidance). Nothing seen (the lens on the wall): along the plan ahead.
  Vec3 u = ahead;
  if (g.chosen >= 0 && !(at_junction && best < 0.0)) {
    u = seen[static_cast<std::size_t>(g.chosen)].direction;
  } else if (at_junction) {
    u = planned;
    g.chosen = -1;
  } else {
    g.chosen = -1;
  }
  g.line = magnet_line(m_nav, u, tip_frame, ahead);
  m_line = g.line;
  m_pose =
      pose_on_line(m_nav, tip, tip_frame, m_skin, tip + m_nav.lead * u, m_line,
                   std::clamp(m_nav.distance, m_nav.min_distance, m_nav.max_distance), t, m_scene.navigator_offset);
  m_guidance.push_back(std::move(g));
}

void NavigatorController::next_placement_after(double t) {
  // One interval on; after a pause (a gated run's closed window), the first interval boundary past t.
  do {
    m_next_placement += m_nav.interval;
  } while (m_next_placement <= t - 1e-12);
}

void NavigatorController::place(double t, const Vec3& tip, const Mat3& tip_frame, double length,
                                std::vector<RunEvent>& events) {
  if (t < m_next_placement - 1e-12) return;
  bool clear = true;
  if (m_look) {
    // Camera-guided: the tip's position is not read (its estimate along the plan stands in for it).
    place_by_camera(t, tip_frame, length);
    clear = keep_clear(point_at_arc_length(m_path, m_guidance.back().arc));
  } else {
    m_pose = navigate(m_nav, m_path, tip, tip_frame, m_skin, t, m_scene.navigator_offset, m_line);
    if (m_platform != nullptr) {
      for (HeldMagnet& h : m_held) place_with_arm(h, t, tip, tip_frame, length, events);
      m_pose = m_held.front().placement;
    } else {
      clear = keep_clear(tip);
    }
  }
  if (!clear && !m_workspace_warned) {
    m_workspace_warned = true;
    events.push_back({t, length, EventKind::kWorkspace,
                      "the navigator's magnet overlaps the anatomy even at max_distance; placed there anyway"});
  }
  next_placement_after(t);
}

void NavigatorController::pause(double t, double length) {
  m_grown_length = length;
  m_grown_at = t;
}

void NavigatorController::regulate(double t, double length, int branch, bool reached, const Vec3& tip_read,
                                   robot::GrowthControl& control, std::vector<RunEvent>& events) {
  const anatomy::AirwayGraph& graph = *m_scene.anatomy->graph;
  // Camera-guided: the branch, the tip and whether the target is reached are the dead reckoning's (a wrong turn is
  // not seen; a held tip is).
  if (m_look) {
    branch = estimated_branch(length);
    reached = estimated_arc(length) >= m_branch_end.back();
  }
  const Vec3 tip = m_look ? point_at_arc_length(m_path, estimated_arc(length)) : tip_read;
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
