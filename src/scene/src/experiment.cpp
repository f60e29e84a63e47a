#include "magvine/scene/experiment.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <initializer_list>
#include <limits>
#include <mutex>
#include <random>
#include <sstream>
#include <thread>

#include "magnet_entries.hpp"
#include "magvine/anatomy/centerline.hpp"
#include "magvine/anatomy/collision_world.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/mesh_report.hpp"
#include "magvine/anatomy/phantom.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/stopwatch.hpp"
#include "magvine/core/text.hpp"
#include "magvine/core/units.hpp"
#include "magvine/robot/elastica.hpp"
#include "magvine/config.hpp"
#include "robot_entries.hpp"
#include "yaml_reader.hpp"
#if MAGVINE_WITH_RENDER
#include "video_outputs.hpp"
#endif

namespace magvine::scene {
namespace {

constexpr double kMaxSteps = 1e7;  // duration / dt beyond this is a typo, not an experiment

/// `[[t, v], ...]` keyframes with increasing times; values times `scale`.
Schedule schedule_of(const YamlMap& parent, const std::string& key, double scale, bool non_negative) {
  const YAML::Node list = parent.node(key);
  const std::string path = parent.key_path(key);
  if (!list.IsSequence() || list.size() == 0) parent.fail(key, "must be a list of [time, value] keyframes");
  Schedule s;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const YAML::Node k = list[i];
    const std::string at = path + "[" + std::to_string(i) + "]";
    if (!k.IsSequence() || k.size() != 2) parent.fail_at(k, at, "must be [time, value]");
    double t = 0.0;
    double v = 0.0;
    try {
      t = k[0].as<double>();
      v = k[1].as<double>();
    } catch (const YAML::Exception&) {
      parent.fail_at(k, at, "must be two numbers [time, value]");
    }
    if (!std::isfinite(t) || !std::isfinite(v)) parent.fail_at(k, at, "must be finite");
    if (t < 0.0) parent.fail_at(k, at, "time must be >= 0");
    if (!s.times.empty() && !(t > s.times.back())) parent.fail_at(k, at, "times must increase");
    if (non_negative && v < 0.0) parent.fail_at(k, at, "value must be >= 0");
    s.times.push_back(t);
    s.values.push_back(v * scale);
  }
  return s;
}

anatomy::Phantom phantom_of(const YamlMap& entry) {
  entry.allow_only({"kind", "max_generation"});
  const std::string name = entry.text("kind");
  const auto kind = anatomy::parse_phantom_kind(name);
  if (!kind) {
    entry.fail("kind", "must be bronchial_tree, tube, y_bifurcation, s_bend or constriction (got '" + name + "')");
  }
  anatomy::PhantomParams params = anatomy::default_params(*kind);
  if (entry.has("max_generation")) {
    auto* tree = std::get_if<anatomy::BronchialTreeParams>(&params);
    if (tree == nullptr) entry.fail("max_generation", "only a bronchial_tree takes max_generation");
    const double g = entry.number("max_generation");
    if (g != std::floor(g) || g < 0 || g > 10) entry.fail("max_generation", "must be a whole number from 0 to 10");
    tree->max_generation = static_cast<int>(g);
  }
  try {
    return anatomy::make_phantom(params);
  } catch (const InputError& e) {
    entry.fail("kind", e.what());
  }
}

/// The rest pose turned so that its z axis is `axis` (the smallest rotation) and moved to `position`.
magnetics::Pose pose_at(const magnetics::Pose& rest, const Vec3& position, const Vec3& axis) {
  magnetics::Pose p = rest;
  p.position = position;
  p.rotation = Eigen::Quaterniond::FromTwoVectors(rest.rotation.col(2), axis).toRotationMatrix() * rest.rotation;
  return p;
}

/// Linear position, great-circle axis between the keyframes around `time`; held beyond the ends.
MagnetKeyframe interpolate(const std::vector<MagnetKeyframe>& keys, double time) {
  if (time <= keys.front().time) return keys.front();
  if (time >= keys.back().time) return keys.back();
  std::size_t i = 1;
  while (keys[i].time < time) ++i;
  const MagnetKeyframe& a = keys[i - 1];
  const MagnetKeyframe& b = keys[i];
  const double u = (time - a.time) / (b.time - a.time);
  MagnetKeyframe out;
  out.time = time;
  out.position = (1.0 - u) * a.position + u * b.position;
  const Eigen::Quaterniond full = Eigen::Quaterniond::FromTwoVectors(a.axis, b.axis);
  out.axis = (Eigen::Quaterniond::Identity().slerp(u, full) * a.axis).normalized();
  return out;
}

/// The nearest branch of `graph` to x (by distance to its polyline segments).
int nearest_branch(const anatomy::AirwayGraph& graph, const Vec3& x) {
  return anatomy::nearest_centreline_point(graph, x).branch;
}

/// The navigator's magnet pose for the tip at `tip`: on the line from the tip through the aim point.
/// The magnet body of source i for the placement checks: a cylinder's radius and half length [m]; none for a dipole
/// or a uniform field (points and fields do not collide).
struct MagnetBody {
  double radius = 0.0;
  double half_length = 0.0;
};
std::optional<MagnetBody> magnet_body(const magnetics::FieldModel& magnets, std::size_t i) {
  const auto* cylinder = std::get_if<magnetics::CylinderMagnet>(&magnets.sources[i]);
  if (cylinder == nullptr) return std::nullopt;
  return MagnetBody{cylinder->radius(), 0.5 * cylinder->length()};
}

constexpr double kMagnetClearance = 2e-3;  ///< the least gap between a magnet and the airway wall [m]

/// How many of the mesh's vertices lie inside the magnet's cylinder grown by kMagnetClearance (centre, unit axis), and
/// the deepest one's depth [m] (the mesh's edges are far shorter than a magnet, so its vertices stand for it).
std::size_t vertices_inside(const anatomy::TriangleMesh& mesh, const MagnetBody& body, const Vec3& centre,
                            const Vec3& axis, double* depth = nullptr) {
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

/// Why source i of `magnets` may not sit at (centre, axis) (it overlaps the anatomy), or empty.
std::string overlap_problem(const anatomy::TriangleMesh& mesh, const magnetics::FieldModel& magnets, std::size_t i,
                            const Vec3& centre, const Vec3& axis) {
  const std::optional<MagnetBody> body = magnet_body(magnets, i);
  if (!body) return {};
  double depth = 0.0;
  if (vertices_inside(mesh, *body, centre, axis.normalized(), &depth) == 0) return {};
  std::ostringstream why;
  why.precision(3);
  why << "the magnet would overlap the anatomy (the airway wall reaches " << 1e3 * depth
      << " mm into it, 2 mm clearance included): an EPM stays outside the patient";
  return why.str();
}

/// overlap_problem along the move from keyframe a to b (as interpolate moves it), sampled every 2 mm and 2°, the
/// end b included; the problem names where on the way.
std::string path_overlap_problem(const anatomy::TriangleMesh& mesh, const magnetics::FieldModel& magnets,
                                 std::size_t i, const MagnetKeyframe& a, const MagnetKeyframe& b) {
  if (!magnet_body(magnets, i)) return {};
  const double turn = std::acos(std::clamp(a.axis.normalized().dot(b.axis.normalized()), -1.0, 1.0));
  const int samples =
      std::max(1, static_cast<int>(std::ceil(std::max((b.position - a.position).norm() / 2e-3, turn / (2.0 * kDegToRad)))));
  for (int k = 1; k <= samples; ++k) {
    const double t = a.time + (b.time - a.time) * k / samples;
    const MagnetKeyframe at = interpolate({a, b}, t);
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

/// Arc length [m] along a polyline of its nearest point to x.
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

/// The planned path as one polyline: the centrelines of `plan`'s branches joined.
std::vector<Vec3> planned_path(const anatomy::AirwayGraph& graph, const std::vector<int>& plan) {
  std::vector<Vec3> path;
  for (const int b : plan) {
    const anatomy::AirwayBranch& branch = graph.branches[static_cast<std::size_t>(b)];
    for (std::size_t k = path.empty() ? 0 : 1; k < branch.nodes.size(); ++k) {
      path.push_back(graph.nodes[branch.nodes[k]].position);
    }
  }
  return path;
}

}  // namespace

MagnetKeyframe navigate(const Navigator& nav, const std::vector<Vec3>& path, const Vec3& tip, const Mat3& tip_frame,
                        const std::optional<Vec3>& skin, double time, const Vec3& offset, Vec3& line) {
  const double at = arc_length_of_nearest(path, tip);
  Vec3 aim = path.back();
  double left = at + nav.lead;
  for (std::size_t k = 0; k + 1 < path.size(); ++k) {
    const double l = (path[k + 1] - path[k]).norm();
    if (l >= left) {
      aim = path[k] + (left / l) * (path[k + 1] - path[k]);
      break;
    }
    left -= l;
  }
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
  MagnetKeyframe k;
  k.time = time;
  k.position = tip + std::clamp(nav.distance, nav.min_distance, nav.max_distance) * u + offset;
  k.axis = u;
  line = u;
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
    const Vec3 r = -u;
    const Vec3 axis = 1.5 * b.dot(r) * r - b;
    if (axis.norm() > 1e-9) k.axis = axis.normalized();
  }
  return k;
}

UnsettledSteps unsettled_steps(const ExperimentResult& result) {
  UnsettledSteps u;
  for (const ExperimentSample& s : result.samples) {
    if (!s.unsettled) continue;
    ++u.count;
    u.max_normal = std::max(u.max_normal, s.max_normal);
  }
  return u;
}

namespace {

/// control.navigator.recover (Navigator::Recovery): watches where the tip is and whether it grows, and takes the
/// pressure and the tether over while it backs the vine out of a wrong turn.
class WrongTurnRecovery {
 public:
  WrongTurnRecovery(const Navigator::Recovery& options, double retraction_pressure, double length)
      : m_options(options), m_retraction_pressure(retraction_pressure), m_shortest(length), m_on_path(length) {}

  /// One step at time t, before the growth advances: `length` is the everted length [m], `off_path` the branch the
  /// last sample's tip is in when that is off the planned path (else empty), `held_for` how long the tip has not
  /// grown with nothing but the wall holding it [s]. While retracting, control's pressure is at most the retraction
  /// pressure and its tether pulls back; `events` gets a "recover" event at each start and end.
  void step(double t, double length, const std::string& off_path, double held_for, robot::GrowthControl& control,
            std::vector<robot::GrowthEvent>& events) {
    if (m_retracting) {
      // Done at the length asked for, or once the last step's tether was there and the vine stopped shortening
      // (whole edges go).
      const double tether = std::max(m_to, m_from - m_options.speed * (t - m_since));
      const bool settled = m_last_tether <= m_to && length >= m_last;
      m_last = length;
      m_last_tether = tether;
      if (length <= m_to + 1e-9 || settled) {
        m_retracting = false;
        m_on_path = length;
        events.push_back(
            {t, length, "recover", printf_string("back at %.1f mm: the pressure is given back", 1e3 * length)});
      } else {
        control.pressure = std::min(control.pressure, m_retraction_pressure);
        control.tether_length = std::min(control.tether_length, tether);
        return;
      }
    }
    if (off_path.empty()) m_on_path = length;
    if (m_used >= m_options.retries) return;
    std::string why;
    double to = 0.0;
    if (!off_path.empty() && length - m_on_path >= m_options.past - 1e-9) {
      why = printf_string("the tip has grown %.1f mm into %s, off the path", 1e3 * (length - m_on_path),
                          off_path.c_str());
      to = m_on_path - m_options.back;
    } else if (held_for >= m_options.after - 1e-9) {
      why = printf_string("the tip has been held at %.1f mm for %.1f s", 1e3 * length, held_for);
      to = length - m_options.back;
    } else {
      return;
    }
    ++m_used;
    m_retracting = true;
    m_from = length;
    m_last = length;
    m_last_tether = length;
    m_to = std::max(m_shortest, to);
    m_since = t;
    events.push_back(
        {t, length, "recover",
         why + printf_string(": deflated to %.1f kPa, the tether pulls it back to %.1f mm (retry %d of %d)",
                             m_retraction_pressure / kKpaToPa, 1e3 * m_to, m_used, m_options.retries)});
    control.pressure = std::min(control.pressure, m_retraction_pressure);
  }

  bool retracting() const { return m_retracting; }
  int used() const { return m_used; }

 private:
  Navigator::Recovery m_options;
  double m_retraction_pressure;
  double m_shortest;  ///< the vine's starting length: no retraction goes below it [m]
  double m_on_path;   ///< the everted length at the last sample on the path [m]
  bool m_retracting = false;
  double m_from = 0.0;
  double m_to = 0.0;
  double m_since = 0.0;
  double m_last = 0.0;         ///< the everted length at the last step of the retraction [m]
  double m_last_tether = 0.0;  ///< and the tether it set then [m]
  int m_used = 0;
};

/// The navigator's pose kept clear of the anatomy: moved out along its line from the tip, 5 mm at a time up to
/// max_distance, while the magnet (body, if any) would overlap the airway mesh. Returns whether it is clear.
bool keep_clear(const Navigator& nav, const anatomy::TriangleMesh& mesh, const std::optional<MagnetBody>& body,
                const Vec3& tip, const Vec3& u, MagnetKeyframe& k) {
  if (!body) return true;
  double d = (k.position - tip).dot(u);
  while (vertices_inside(mesh, *body, k.position, k.axis) > 0) {
    if (d >= nav.max_distance) return false;
    const double next = std::min(nav.max_distance, d + 5e-3);
    k.position += (next - d) * u;
    d = next;
  }
  return true;
}

/// Refuses each of `keys` that `map` has, with `why` (a scene entry that does not apply: a pushed rod's pressure).
void refuse_keys(const YamlMap& map, std::initializer_list<const char*> keys, const std::string& why) {
  for (const char* key : keys) {
    if (map.has(key)) map.fail(key, why);
  }
}

constexpr const char* kRodHasNoPressure = "a pushed rod (robot.kind: rod) has no pressure";

/// control.commands, the gamepad script (experiment.hpp), turned into keyframes: each command ramps its channel
/// (a magnet's pose, the pressure, the tether) linearly from its value at `time` to the new one over `over` seconds.
void parse_commands(const YamlMap& control, ExperimentScene& scene, double unit, double stress_unit) {
  const YAML::Node list = control.node("commands");
  if (!list.IsSequence() || list.size() == 0) control.fail("commands", "must be a list of {time, ...} commands");
  const bool pressure_keys = !scene.pressure.times.empty();
  const bool tether_keys = scene.tether.has_value();
  Schedule pressure;
  pressure.times = {0.0};
  pressure.values = {scene.vine.pressure};
  Schedule tether;
  tether.times = {0.0};
  tether.values = {scene.vine.length};
  bool grows = false;
  std::vector<std::vector<MagnetKeyframe>> poses;
  if (scene.magnets) poses.resize(scene.magnets->size());
  double last_time = 0.0;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const YamlMap c(list[i], control.file(), control.key_path("commands[" + std::to_string(i) + "]"));
    c.allow_only({"time", "over", "magnet", "move", "rotate", "pressure", "grow"});
    const double t = c.number("time");
    if (t < 0.0) c.fail("time", "must be >= 0");
    if (t < last_time) c.fail("time", "commands must be in time order");
    last_time = t;
    const double over = c.has("over") ? c.positive("over") : 0.5;
    const int actions = static_cast<int>(c.has("move")) + static_cast<int>(c.has("rotate")) +
                        static_cast<int>(c.has("pressure")) + static_cast<int>(c.has("grow"));
    if (actions != 1) c.fail("time", "each command does exactly one of move, rotate, pressure, grow");
    // Appends the ramp (t, from) → (t + over, to) to a schedule; the channel must be idle by t.
    const auto ramp = [&](Schedule& sch, double to, const std::string& key) {
      if (t < sch.times.back()) c.fail(key, "starts before the previous command on this channel ends");
      const double from = sch.values.back();
      if (t > sch.times.back()) {
        sch.times.push_back(t);
        sch.values.push_back(from);
      }
      sch.times.push_back(t + over);
      sch.values.push_back(to);
    };
    if (c.has("pressure")) {
      if (pressure_keys) c.fail("pressure", "the pressure has keyframes in control.pressure already");
      if (scene.growth.rod) refuse_keys(c, {"pressure"}, kRodHasNoPressure);
      const double to = pressure.values.back() + c.number("pressure") * stress_unit;
      if (to < 0.0) c.fail("pressure", "would take the pressure below 0");
      ramp(pressure, to, "pressure");
      continue;
    }
    if (c.has("grow")) {
      if (tether_keys) c.fail("grow", "the tether has keyframes in control.tether already");
      const double to = tether.values.back() + c.number("grow") * unit;
      if (to < 0.0) c.fail("grow", "would pull the tether back beyond the base");
      ramp(tether, to, "grow");
      grows = true;
      continue;
    }
    // move or rotate a magnet
    if (!scene.magnets) c.fail(c.has("move") ? "move" : "rotate", "moves a magnet, but the scene has no magnets: list");
    const double index = c.has("magnet") ? c.number("magnet") : 0.0;
    if (index != std::floor(index) || index < 0 || index >= static_cast<double>(scene.magnets->size())) {
      c.fail("magnet", "must be the index of an entry of magnets:");
    }
    const auto m = static_cast<std::size_t>(index);
    if (!scene.magnet_keyframes[m].empty()) c.fail("magnet", "this magnet has keyframes in control.magnets already");
    auto& keys = poses[m];
    if (keys.empty()) {
      const magnetics::Pose& rest = scene.magnets->rest_poses[m];
      keys.push_back({0.0, rest.position, rest.rotation.col(2)});
    }
    const std::string key = c.has("move") ? "move" : "rotate";
    if (t < keys.back().time) c.fail(key, "starts before the previous command on this magnet ends");
    MagnetKeyframe next = keys.back();
    if (t > keys.back().time) {
      next.time = t;
      keys.push_back(next);
    }
    next.time = t + over;
    if (c.has("move")) {
      next.position += c.vec3("move") * unit;
    } else {
      const YamlMap r = c.map("rotate");
      r.allow_only({"axis", "angle"});
      const Vec3 axis = r.nonzero_vec3("axis").normalized();
      next.axis = Eigen::AngleAxisd(r.number("angle") * kDegToRad, axis) * next.axis;
    }
    const std::string why = path_overlap_problem(scene.mesh, *scene.magnets, m, keys.back(), next);
    if (!why.empty()) c.fail(key, why);
    keys.push_back(next);
  }
  if (pressure.times.size() > 1) scene.pressure = pressure;
  if (grows) scene.tether = tether;
  for (std::size_t m = 0; m < poses.size(); ++m) {
    if (!poses[m].empty()) scene.magnet_keyframes[m] = std::move(poses[m]);
  }
}

/// The whole-run figures of metrics.json, also the trials' outcomes.
struct RunFigures {
  double everted_length = 0.0;       ///< at the end [m]
  std::optional<double> final_error;  ///< tip to target at the end [m]; none without a target
  double path = 0.0;                 ///< tip path length [m]
  double max_normal = 0.0;           ///< largest wall normal force on a node [N], over the settled steps
  double mean_normal = 0.0;          ///< time average of the total [N]
  double max_shear = 0.0;            ///< largest total shear [N], over the settled steps
  UnsettledSteps unsettled;          ///< the steps left out of the maxima
  std::vector<std::string> branches; ///< graph branches the tip passed through, in order
  int generation = -1;               ///< the deepest generation among them (−1 without a graph)
  std::optional<double> centreline;       ///< tip to the nearest centreline at the end [m] (with a graph)
  std::optional<double> mean_centreline;  ///< its time average [m]
  std::optional<double> progress;    ///< how far along the navigator's planned path the tip got, 0–1
};

RunFigures figures_of(const ExperimentScene& scene, const ExperimentResult& result) {
  RunFigures f;
  f.unsettled = unsettled_steps(result);
  const Vec3 tip = result.final_state.tip();
  f.everted_length = result.samples.empty() ? scene.vine.length : result.samples.back().length;
  if (scene.target) f.final_error = (tip - *scene.target).norm();
  Vec3 last = result.samples.empty() ? tip : result.samples.front().tip;
  int last_branch = -1;
  for (const ExperimentSample& s : result.samples) {
    f.path += (s.tip - last).norm();
    last = s.tip;
    if (!s.unsettled) {
      f.max_normal = std::max(f.max_normal, s.max_normal);
      f.max_shear = std::max(f.max_shear, s.total_shear);
    }
    f.mean_normal += s.total_normal / static_cast<double>(result.samples.size());
    if (scene.graph && s.branch >= 0 && s.branch != last_branch) {
      f.branches.push_back(scene.graph->branches[static_cast<std::size_t>(s.branch)].name);
      f.generation = std::max(f.generation, scene.graph->branches[static_cast<std::size_t>(s.branch)].generation);
      last_branch = s.branch;
    }
  }
  if (scene.graph) {
    f.centreline = anatomy::nearest_centreline_point(*scene.graph, tip).distance;
    double sum = 0.0;
    for (const ExperimentSample& s : result.samples) sum += anatomy::nearest_centreline_point(*scene.graph, s.tip).distance;
    f.mean_centreline = result.samples.empty() ? *f.centreline : sum / static_cast<double>(result.samples.size());
  }
  if (scene.navigator && scene.target) {
    // Arc length along the planned path of the tip's and the target's nearest points on it.
    const std::vector<Vec3> path = planned_path(*scene.graph, anatomy::path_from_root(*scene.graph, scene.navigator->target_branch));
    const double goal = arc_length_of_nearest(path, *scene.target);
    f.progress = goal > 0.0 ? std::clamp(arc_length_of_nearest(path, tip) / goal, 0.0, 1.0) : 1.0;
  }
  return f;
}

/// Why a run did not reach its target, in one line: the last event that stopped the tip (stall, blocked, squeeze,
/// burst, solver), where the tip was, or that the time ran out while it was still moving.
std::string failure_reason(const ExperimentResult& result, const RunFigures& figures) {
  std::ostringstream why;
  why.precision(3);
  // The last event that stopped the tip since the navigator last backed it out of a wrong turn (which dealt with
  // the stops before it).
  const robot::GrowthEvent* last = nullptr;
  for (const robot::GrowthEvent& e : result.events) {
    if (e.kind == "recover") {
      last = nullptr;
    } else if (e.kind != "resume" && e.kind != "retract") {
      last = &e;
    }
  }
  const std::string branch =
      figures.branches.empty() ? std::string() : ", last in branch " + figures.branches.back();
  if (last != nullptr) {
    why << last->kind << " at " << last->time << " s, " << 1e3 * last->length << " mm everted: " << last->detail;
  } else {
    why << "the time ran out";
  }
  why << branch;
  if (figures.final_error) why << ", " << 1e3 * *figures.final_error << " mm from the target";
  if (result.recoveries > 0) {
    why << ", after " << result.recoveries << (result.recoveries == 1 ? " retraction" : " retractions")
        << " by the navigator";
  }
  return why.str();
}

/// Aims the scene's navigator at `branch`: the plan's last branch, and its end (within 1.5 lumen radii) the target.
void aim_at(ExperimentScene& scene, int branch) {
  const anatomy::AirwayBranch& b = scene.graph->branches[static_cast<std::size_t>(branch)];
  const anatomy::AirwayNode& end = scene.graph->nodes[b.nodes.back()];
  scene.navigator->target = b.name;
  scene.navigator->target_branch = branch;
  scene.target = end.position;
  scene.target_tolerance = 1.5 * end.radius;
}

}  // namespace

double Schedule::at(double time) const {
  if (time <= times.front()) return values.front();
  if (time >= times.back()) return values.back();
  const auto it = std::upper_bound(times.begin(), times.end(), time);
  const std::size_t i = static_cast<std::size_t>(it - times.begin());
  const double u = (time - times[i - 1]) / (times[i] - times[i - 1]);
  return (1.0 - u) * values[i - 1] + u * values[i];
}

bool is_experiment_scene(const std::filesystem::path& file) {
  const YAML::Node root = parse_yaml(read_text_file(file.string(), "scene file"), file.string());
  return root && root.IsMap() && static_cast<bool>(root["anatomy"]);
}

/// One outputs.video entry (experiment.hpp). `unit`: the file's length unit [m].
VideoOutput video_of(const YamlMap& v, double unit) {
  v.allow_only({"camera", "size", "fov", "lens", "fps", "speed", "frames", "depth", "depth_range", "noise", "from",
                "up"});
  VideoOutput out;
  const std::string camera = v.text("camera");
  if (camera == "overview") {
    out.view = VideoOutput::View::kOverview;
    out.width = 640;
    out.height = 480;
    out.fov = 40.0 * kDegToRad;
    out.fisheye = false;
  } else if (camera != "tip") {
    v.fail("camera", "must be tip or overview, not '" + camera + "'");
  }
  const auto flag = [&](const std::string& key) {
    const std::string t = v.text(key);
    if (t != "true" && t != "false") v.fail(key, "must be true or false");
    return t == "true";
  };
  if (v.has("size")) {
    const YAML::Node n = v.node("size");
    const auto whole = [&](const YAML::Node& e) {
      double x = 0.0;
      try {
        x = e.as<double>();
      } catch (const YAML::Exception&) {
        v.fail("size", "must be [width, height] in pixels");
      }
      if (!(x == std::floor(x) && x >= 16 && x <= 4096)) v.fail("size", "each side must be a whole 16 to 4096 px");
      return static_cast<int>(x);
    };
    if (!n.IsSequence() || n.size() != 2) v.fail("size", "must be [width, height] in pixels");
    out.width = whole(n[0]);
    out.height = whole(n[1]);
    if (out.width % 2 != 0 || out.height % 2 != 0) v.fail("size", "video codecs need even sides");
  }
  if (v.has("lens")) {
    const std::string lens = v.text("lens");
    if (lens != "fisheye" && lens != "pinhole") v.fail("lens", "must be fisheye or pinhole, not '" + lens + "'");
    out.fisheye = lens == "fisheye";
  }
  if (v.has("fov")) out.fov = v.positive("fov") * kDegToRad;
  if (out.fov >= (out.fisheye ? 2.0 * kPi : kPi) - 1e-9) {
    v.fail("fov", out.fisheye ? "a fisheye's field of view must be below 360 degrees"
                              : "a pinhole's field of view must be below 180 degrees");
  }
  if (v.has("fps")) out.fps = v.positive("fps");
  if (out.fps > 240.0) v.fail("fps", "at most 240 frames per second");
  if (v.has("speed")) out.speed = v.positive("speed");
  if (v.has("frames")) out.frames = flag("frames");
  if (v.has("depth")) {
    out.depth = flag("depth");
    if (out.depth && out.view != VideoOutput::View::kTip) v.fail("depth", "depth maps are the tip camera's");
  }
  if (v.has("depth_range")) out.depth_range = v.positive("depth_range") * unit;
  if (v.has("noise")) {
    out.noise = v.number("noise");
    if (!(out.noise >= 0.0 && out.noise <= 50.0)) v.fail("noise", "must lie in [0, 50] grey levels");
  }
  for (const char* key : {"from", "up"}) {
    if (!v.has(key)) continue;
    if (out.view != VideoOutput::View::kOverview) v.fail(key, "only the overview camera takes a viewing direction");
    (std::string(key) == "from" ? out.from : out.up) = v.nonzero_vec3(key).normalized();
  }
  if (out.from && out.up && out.from->cross(*out.up).norm() < 1e-6) v.fail("up", "must not be parallel to from");
  return out;
}

ExperimentScene parse_experiment_scene(const std::string& text, const std::string& file_label,
                                       const std::filesystem::path& directory) {
  const YAML::Node root = parse_yaml(text, file_label);
  if (!root || root.IsNull()) throw InputError(file_label, 0, "", "empty scene file");
  const YamlMap top(root, file_label, "");
  top.allow_only(
      {"units", "seed", "anatomy", "robot", "growth", "magnets", "control", "simulation", "target", "trials",
       "outputs"});
  const FileUnits units = file_units(top);
  const double unit = units.metres;
  const double stress_unit = units.pascals;

  ExperimentScene scene;
  scene.file = file_label;
  if (top.has("seed")) {
    const double seed = top.number("seed");
    if (seed != std::floor(seed) || seed < 0 || seed > 9.007e15) top.fail("seed", "must be a whole number >= 0");
    scene.seed = static_cast<std::uint64_t>(seed);
  }

  // Anatomy: a generated phantom or a mesh file.
  const YamlMap anatomy_entry = top.map("anatomy");
  anatomy_entry.allow_only({"phantom", "mesh", "mesh_units", "graph", "graph_root"});
  if (anatomy_entry.has("phantom") == anatomy_entry.has("mesh")) {
    anatomy_entry.fail("phantom", "give exactly one of phantom: {kind: ...} or mesh: FILE");
  }
  if (anatomy_entry.has("phantom")) {
    const YamlMap p = anatomy_entry.map("phantom");
    anatomy::Phantom ph = phantom_of(p);
    scene.anatomy_label = "phantom " + p.text("kind");
    scene.mesh = std::move(ph.mesh);
    scene.graph = std::move(ph.graph);
    scene.closed_anatomy = true;  // generated phantoms are closed by construction
  } else {
    if (anatomy_entry.has("mesh_units") && !parse_length_unit(anatomy_entry.text("mesh_units"))) {
      anatomy_entry.fail("mesh_units", "must be mm, cm or m (got '" + anatomy_entry.text("mesh_units") + "')");
    }
    const LengthUnit mesh_units =
        anatomy_entry.has("mesh_units") ? *parse_length_unit(anatomy_entry.text("mesh_units")) : units.length;
    const std::filesystem::path mesh = directory / anatomy_entry.text("mesh");
    scene.anatomy_label = mesh.string();
    try {
      scene.mesh = anatomy::import_mesh(mesh, {.units = mesh_units}).mesh;
      scene.closed_anatomy = anatomy::analyse_mesh(scene.mesh).watertight;
    } catch (const InputError& e) {
      anatomy_entry.fail("mesh", e.what());
    }
    // The airway graph of an imported mesh: extracted from it (anatomy/centerline.hpp), or read from a graph file.
    if (anatomy_entry.has("graph")) {
      const std::string g = anatomy_entry.text("graph");
      try {
        if (g == "extract") {
          anatomy::CenterlineOptions options;
          if (anatomy_entry.has("graph_root")) options.root = anatomy_entry.vec3("graph_root") * unit;
          scene.graph = anatomy::extract_airway_graph(scene.mesh, options);
        } else {
          scene.graph = anatomy::read_graph(directory / g);
        }
      } catch (const InputError& e) {
        anatomy_entry.fail("graph", e.what());
      }
    } else if (anatomy_entry.has("graph_root")) {
      anatomy_entry.fail("graph_root", "only with graph: extract");
    }
  }

  // The vine, or a rod pushed from the base (growth.mode pushed, set here).
  const YamlMap robot = top.map("robot");
  const std::string kind = robot.text("kind");
  std::optional<robot::PushedRod> pushed_rod;
  if (kind == "rod") {
    robot::PushedRod r;
    r.body = parse_rod(robot, unit, stress_unit, {"inserted", "insertion_speed"}, &r.radius);
    const double inserted =
        robot.has("inserted") ? robot.positive("inserted") * unit : std::min(r.body.length, 4.0 * r.radius);
    if (inserted > r.body.length) robot.fail("inserted", "must not exceed the rod's length");
    if (robot.has("insertion_speed")) r.insertion_speed = non_negative(robot, "insertion_speed") * unit;
    // The inserted length plays the vine's everted length (and its tether caps the insertion); no pressure.
    scene.vine = robot::VineParameters{};
    scene.vine.length = inserted;
    scene.vine.radius = r.radius;
    scene.vine.pressure = 0.0;
    pushed_rod = r;
  } else if (kind == "vine") {
    scene.vine = parse_vine(robot, unit, stress_unit);
    try {
      (void)robot::vine_rod(scene.vine);
    } catch (const robot::VineParameterError& e) {
      robot.fail(robot.has(e.parameter()) ? e.parameter() : "kind", e.what());
    }
  } else {
    robot.fail("kind", "an experiment grows a vine (kind: vine) or pushes a rod (kind: rod); got '" + kind + "'");
  }
  const YamlMap base = robot.map("base");
  base.allow_only({"position", "direction", "normal"});
  scene.base_position = base.vec3("position") * unit;
  scene.base_line = line_of(robot.node("base"));
  scene.base_frame = base_frame_of(base);

  if (top.has("growth")) {
    const YamlMap g = top.map("growth");
    g.allow_only({"mode", "yield_pressure", "length_yield", "turning_yield", "extensibility", "friction",
                  "edge_length", "catheter", "magnetorheology", "retraction_pressure", "max_incidence"});
    robot::GrowthOptions& o = scene.growth;
    if (g.has("mode")) {
      const std::string mode = g.text("mode");
      if (mode == "eversion") {
        o.mode = robot::InsertionMode::kEversion;
      } else if (mode == "pushed") {
        o.mode = robot::InsertionMode::kPushed;
      } else {
        g.fail("mode", "must be eversion or pushed (got '" + mode + "')");
      }
    }
    const auto non_negative = [&](const std::string& key) {
      const double v = g.number(key);
      if (v < 0.0) g.fail(key, "must be >= 0");
      return v;
    };
    if (g.has("yield_pressure")) o.law.yield_pressure = non_negative("yield_pressure") * stress_unit;
    if (g.has("length_yield")) o.law.length_yield = non_negative("length_yield") * stress_unit / unit;
    if (g.has("turning_yield")) o.law.turning_yield = non_negative("turning_yield") * stress_unit;
    if (g.has("extensibility")) o.law.extensibility = non_negative("extensibility") * 1e-6;
    if (g.has("friction")) o.friction = non_negative("friction");
    if (g.has("edge_length")) o.edge_length = g.positive("edge_length") * unit;
    if (g.has("max_incidence")) {
      const double degrees = g.number("max_incidence");
      if (!(degrees > 0.0 && degrees < 90.0)) g.fail("max_incidence", "must be an angle in degrees between 0 and 90");
      o.max_incidence = degrees * kDegToRad;
    }
    if (g.has("catheter")) {
      if (o.mode != robot::InsertionMode::kPushed) g.fail("catheter", "a catheter tube is pushed: set mode: pushed");
      const YamlMap c = g.map("catheter");
      c.allow_only({"outer_diameter", "inner_diameter", "youngs_modulus", "density"});
      robot::CatheterTube tube;
      tube.outer_diameter = c.positive("outer_diameter") * unit;
      tube.inner_diameter = c.number("inner_diameter") * unit;
      if (!(tube.inner_diameter >= 0.0 && tube.inner_diameter < tube.outer_diameter)) {
        c.fail("inner_diameter", "must satisfy 0 <= inner_diameter < outer_diameter");
      }
      tube.modulus = c.positive("youngs_modulus") * stress_unit;
      if (c.has("density")) tube.density = c.positive("density");
      o.catheter = tube;
    }
    if (g.has("magnetorheology")) {
      const std::string v = g.text("magnetorheology");
      if (v != "true" && v != "false") g.fail("magnetorheology", "must be true or false");
      o.magnetorheology = v == "true";
      if (o.magnetorheology && scene.vine.fill != robot::FillKind::kMagneticFluid) {
        g.fail("magnetorheology", "needs a magnetic-fluid fill (robot.fill.kind: magnetic_fluid)");
      }
    }
    if (g.has("retraction_pressure")) o.retraction_pressure = non_negative("retraction_pressure") * stress_unit;
    if (pushed_rod) {
      refuse_keys(g,
                  {"catheter", "magnetorheology", "retraction_pressure", "yield_pressure", "length_yield",
                   "turning_yield", "extensibility"},
                  std::string(kRodHasNoPressure) +
                      " or growth law: it is inserted at robot.insertion_speed up to the tether");
      if (o.mode != robot::InsertionMode::kPushed && g.has("mode")) g.fail("mode", "a rod is pushed (mode: pushed)");
    }
  }
  if (pushed_rod) {
    scene.growth.mode = robot::InsertionMode::kPushed;
    scene.growth.rod = *pushed_rod;
    scene.growth.max_length = pushed_rod->body.length;  // inserted up to its whole length
  }

  if (top.has("magnets")) {
    scene.magnets = parse_magnet_list(top, unit);
    const YAML::Node list = top.node("magnets");
    for (std::size_t i = 0; i < scene.magnets->size(); ++i) {
      const magnetics::Pose& pose = scene.magnets->rest_poses[i];
      const std::string why = overlap_problem(scene.mesh, *scene.magnets, i, pose.position, pose.rotation.col(2));
      if (!why.empty()) top.fail_at(list[i], "magnets[" + std::to_string(i) + "].position", why);
    }
  }

  if (top.has("outputs")) {
    const YamlMap o = top.map("outputs");
    o.allow_only({"shape_interval", "video"});
    if (o.has("shape_interval")) scene.shape_interval = o.positive("shape_interval");
    if (o.has("video")) {
      const YAML::Node list = o.node("video");
      if (list.IsSequence()) {
        for (std::size_t i = 0; i < list.size(); ++i) {
          scene.videos.push_back(video_of(YamlMap(list[i], o.file(), o.key_path("video") + "[" + std::to_string(i) + "]"), unit));
        }
      } else {
        scene.videos.push_back(video_of(o.map("video"), unit));
      }
      for (std::size_t i = 0; i < scene.videos.size(); ++i) {
        for (std::size_t k = 0; k < i; ++k) {
          if (scene.videos[k].view == scene.videos[i].view) {
            o.fail("video", "two " + scene.videos[i].name() + " videos would write the same file");
          }
        }
      }
    }
  }
  const YamlMap sim = top.map("simulation");
  sim.allow_only({"duration", "dt", "gravity", "stop_at_target"});
  if (sim.has("stop_at_target")) {
    const std::string v = sim.text("stop_at_target");
    if (v != "true" && v != "false") sim.fail("stop_at_target", "must be true or false");
    scene.stop_at_target = v == "true";
  }
  scene.duration = sim.positive("duration");
  if (sim.has("dt")) scene.dt = sim.positive("dt");
  if (scene.duration / scene.dt > kMaxSteps) sim.fail("dt", "gives more than 10 million steps");
  if (sim.has("gravity")) scene.growth.gravity = sim.vec3("gravity");

  const YamlMap control = top.map("control");
  control.allow_only({"pressure", "tether", "magnets", "navigator", "commands"});
  if (control.has("pressure")) {
    if (scene.growth.rod) refuse_keys(control, {"pressure"}, kRodHasNoPressure);
    scene.pressure = schedule_of(control, "pressure", stress_unit, true);
  }
  if (control.has("tether")) scene.tether = schedule_of(control, "tether", unit, true);
  if (scene.magnets) scene.magnet_keyframes.resize(scene.magnets->size());
  if (control.has("magnets")) {
    const YAML::Node list = control.node("magnets");
    if (!list.IsSequence()) control.fail("magnets", "must be a list of {magnet, keyframes}");
    if (!scene.magnets) control.fail("magnets", "keyframes for magnets, but the scene has no magnets: list");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const YamlMap entry(list[i], file_label, control.key_path("magnets[" + std::to_string(i) + "]"));
      entry.allow_only({"magnet", "keyframes"});
      const double index = entry.number("magnet");
      if (index != std::floor(index) || index < 0 || index >= static_cast<double>(scene.magnets->size())) {
        entry.fail("magnet", "must be the index of an entry of magnets: (0 to " +
                                 std::to_string(scene.magnets->size() - 1) + ")");
      }
      auto& keys = scene.magnet_keyframes[static_cast<std::size_t>(index)];
      if (!keys.empty()) entry.fail("magnet", "this magnet already has keyframes");
      const YAML::Node frames = entry.node("keyframes");
      if (!frames.IsSequence() || frames.size() == 0) entry.fail("keyframes", "must be a list of {time, position, axis}");
      for (std::size_t k = 0; k < frames.size(); ++k) {
        const YamlMap f(frames[k], file_label, entry.key_path("keyframes[" + std::to_string(k) + "]"));
        f.allow_only({"time", "position", "axis"});
        MagnetKeyframe key;
        key.time = f.number("time");
        if (key.time < 0.0) f.fail("time", "must be >= 0");
        if (!keys.empty() && !(key.time > keys.back().time)) f.fail("time", "times must increase");
        key.position = f.vec3("position") * unit;
        key.axis = f.nonzero_vec3("axis").normalized();
        const std::string why =
            keys.empty()
                ? overlap_problem(scene.mesh, *scene.magnets, static_cast<std::size_t>(index), key.position, key.axis)
                : path_overlap_problem(scene.mesh, *scene.magnets, static_cast<std::size_t>(index), keys.back(), key);
        if (!why.empty()) f.fail("position", why);
        keys.push_back(key);
      }
    }
  }

  if (control.has("commands")) parse_commands(control, scene, unit, stress_unit);
  if (scene.pressure.times.empty()) {  // neither keyframes nor commands: held at robot.pressure
    scene.pressure.times = {0.0};
    scene.pressure.values = {scene.vine.pressure};
  }

  if (control.has("navigator")) {
    const YamlMap n = control.map("navigator");
    n.allow_only({"target", "magnet", "distance", "min_distance", "max_distance", "lead", "interval",
                  "deflate_pressure", "deflate_time", "junction_distance", "lateral", "mode", "boost_pressure",
                  "boost_after", "boost_length", "recover"});
    if (!scene.graph) {
      n.fail("target", "the navigator plans on an airway graph: a generated phantom's, or anatomy.graph (extract | "
                       "FILE.json) for a mesh");
    }
    if (!scene.magnets) n.fail("magnet", "the navigator moves a magnet, but the scene has no magnets: list");
    Navigator nav;
    if (n.node("target").IsSequence()) {
      // A point: snapped to the nearest centreline; success within 1.5 lumen radii of the snapped point.
      const anatomy::CentrelinePoint at = anatomy::nearest_centreline_point(*scene.graph, n.vec3("target") * unit);
      nav.target_branch = at.branch;
      nav.target = scene.graph->branches[static_cast<std::size_t>(at.branch)].name;
      scene.target = at.position;
      scene.target_tolerance = 1.5 * at.radius;
      scene.target_line = line_of(n.node("target"));
    } else {
      nav.target = n.text("target");
      const auto branch = anatomy::find_branch(*scene.graph, nav.target);
      if (!branch) n.fail("target", "no branch '" + nav.target + "' in the airway graph (names like 0-1-0)");
      nav.target_branch = *branch;
    }
    if (n.has("magnet")) {
      const double index = n.number("magnet");
      if (index != std::floor(index) || index < 0 || index >= static_cast<double>(scene.magnets->size())) {
        n.fail("magnet", "must be the index of an entry of magnets:");
      }
      nav.magnet = static_cast<int>(index);
    }
    if (!scene.magnet_keyframes[static_cast<std::size_t>(nav.magnet)].empty()) {
      n.fail("magnet", "this magnet is keyframed in control.magnets; the navigator moves it itself");
    }
    if (n.has("min_distance")) nav.min_distance = n.positive("min_distance") * unit;
    if (n.has("max_distance")) nav.max_distance = n.positive("max_distance") * unit;
    if (nav.max_distance < nav.min_distance) n.fail("max_distance", "must be >= min_distance");
    nav.distance = n.has("distance") ? n.positive("distance") * unit : nav.min_distance;
    if (n.has("lead")) nav.lead = n.positive("lead") * unit;
    if (n.has("interval")) nav.interval = n.positive("interval");
    if (n.has("lateral")) {
      nav.lateral = n.number("lateral");
      if (!(nav.lateral >= 0.0 && nav.lateral <= 1.0)) n.fail("lateral", "must be from 0 to 1");
    }
    if (n.has("mode")) {
      const std::string mode = n.text("mode");
      if (mode == "torque") {
        nav.skin_mode = Navigator::SkinMode::kTorque;
      } else if (mode != "gradient") {
        n.fail("mode", "must be gradient or torque");
      }
      if (!robot::has_magnetic_skin(scene.vine)) {
        n.fail("mode", "steers a magnetic skin (robot.skin); a fill or a rod follows the magnet's pull");
      }
    }
    if (n.has("deflate_pressure")) nav.deflate_pressure = n.positive("deflate_pressure") * stress_unit;
    if (n.has("deflate_time")) nav.deflate_time = n.positive("deflate_time");
    if (n.has("junction_distance")) nav.junction_distance = n.positive("junction_distance") * unit;
    if (scene.growth.rod) refuse_keys(n, {"boost_pressure", "deflate_pressure"}, kRodHasNoPressure);
    if (n.has("boost_pressure")) {
      nav.boost_pressure = n.positive("boost_pressure") * stress_unit;
      const double burst = robot::burst_pressure(scene.vine);
      if (!scene.growth.catheter && nav.boost_pressure >= burst) {
        char message[160];
        std::snprintf(message, sizeof message,
                      "must be below the vine's burst pressure, %.1f kPa (hoop stress P·R/t at the wall strength)",
                      burst / kKpaToPa);
        n.fail("boost_pressure", message);
      }
    }
    if (n.has("boost_after")) nav.boost_after = n.positive("boost_after");
    if (n.has("boost_length")) nav.boost_length = n.positive("boost_length") * unit;
    if (n.has("recover")) {
      const YamlMap r = n.map("recover");
      r.allow_only({"retries", "past", "after", "back", "speed"});
      Navigator::Recovery& rec = nav.recover;
      const double retries = r.number("retries");
      if (retries != std::floor(retries) || retries < 0 || retries > 100) {
        r.fail("retries", "must be a whole number from 0 to 100");
      }
      rec.retries = static_cast<int>(retries);
      if (r.has("past")) rec.past = r.positive("past") * unit;
      if (r.has("after")) rec.after = r.positive("after");
      if (r.has("back")) rec.back = r.positive("back") * unit;
      if (r.has("speed")) rec.speed = r.positive("speed") * unit;
      if (scene.growth.rod) r.fail("retries", "a pushed rod is withdrawn by its tether schedule, not by the navigator");
      if (rec.retries > 0 && scene.growth.retraction_pressure < 0.0) {
        r.fail("retries", "the navigator retracts a deflated vine: set growth.retraction_pressure (e.g. 5 kPa)");
      }
    }

    scene.navigator = nav;
  }

  if (top.has("target")) {
    const YamlMap t = top.map("target");
    t.allow_only({"position", "tolerance"});
    scene.target = t.vec3("position") * unit;
    scene.target_tolerance = t.positive("tolerance") * unit;
    scene.target_line = line_of(top.node("target"));
  }
  if (top.has("trials")) {
    const YamlMap t = top.map("trials");
    t.allow_only({"magnet_position_sd", "pressure_sd", "material_spread"});
    const auto non_negative = [&](const std::string& key) {
      const double v = t.number(key);
      if (v < 0.0) t.fail(key, "must be >= 0");
      return v;
    };
    if (t.has("magnet_position_sd")) scene.perturbation.magnet_position_sd = non_negative("magnet_position_sd") * unit;
    if (t.has("pressure_sd")) scene.perturbation.pressure_sd = non_negative("pressure_sd") * stress_unit;
    if (t.has("material_spread")) {
      scene.perturbation.material_spread = non_negative("material_spread");
      if (scene.perturbation.material_spread >= 0.3) t.fail("material_spread", "must be below 0.3 (relative)");
    }
  }
  if (scene.navigator && !scene.target) aim_at(scene, scene.navigator->target_branch);
  return scene;
}

ExperimentScene load_experiment_scene(const std::filesystem::path& file) {
  return parse_experiment_scene(read_text_file(file.string(), "scene file"), file.string(), file.parent_path());
}

ExperimentResult run_experiment(const ExperimentScene& scene, const std::function<void(double)>& progress) {
  const Stopwatch clock;
  ExperimentResult out;
  const anatomy::CollisionWorld world(scene.mesh);
  // Placements only the collision world can check (ray parity: closed anatomy only), before anything is written.
  if (scene.closed_anatomy) {
    const auto where = [](const Vec3& p) {
      std::ostringstream s;
      s.precision(4);
      s << "(" << 1e3 * p.x() << ", " << 1e3 * p.y() << ", " << 1e3 * p.z() << ") mm";
      return s.str();
    };
    if (!world.contains(scene.base_position)) {
      throw InputError(scene.file, scene.base_line, "robot.base.position",
                       where(scene.base_position) + " is outside the lumen of the " + scene.anatomy_label);
    }
    if (scene.target && !world.contains(*scene.target)) {
      throw InputError(scene.file, scene.target_line, "target.position",
                       where(*scene.target) + " is outside the lumen of the " + scene.anatomy_label);
    }
  }
  std::vector<int> plan;
  double next_navigation = 0.0;
  std::optional<MagnetKeyframe> steered;  // the navigator's current pose for its magnet
  Vec3 steered_line = Vec3::UnitX();      // and the line from the tip it was placed on
  if (scene.navigator) plan = anatomy::path_from_root(*scene.graph, scene.navigator->target_branch);
  const std::vector<Vec3> path = scene.navigator ? planned_path(*scene.graph, plan) : std::vector<Vec3>{};
  const std::optional<MagnetBody> steered_body =
      scene.navigator ? magnet_body(*scene.magnets, static_cast<std::size_t>(scene.navigator->magnet)) : std::nullopt;
  bool workspace_warned = false;
  // A magnetic skin's moment direction in the body frame (the navigator's skin modes); none for a fill.
  const std::optional<Vec3> skin = robot::has_magnetic_skin(scene.vine)
                                       ? std::optional<Vec3>(std::copysign(1.0, scene.vine.skin_remanence) *
                                                             scene.vine.skin_direction.normalized())
                                       : std::nullopt;
  std::vector<int> deflated_at;  // branches whose end junction the navigator has deflated the vine for
  double deflate_until = -1.0;
  double grown_at = 0.0;        // when the everted length last changed (the navigator's boost and recovery)
  double grown_length = -1.0;   // the everted length then [m]
  double boost_until = -1.0;    // boosting until the everted length reaches this [m] (< 0: not boosting)
  std::optional<WrongTurnRecovery> recovery;  // control.navigator.recover
  if (scene.navigator && scene.navigator->recover.retries > 0) {
    recovery.emplace(scene.navigator->recover, scene.growth.retraction_pressure, scene.vine.length);
  }
  double next_shape = 0.0;  // outputs.shape_interval
  double next_frame = 0.0;  // outputs.video: one record per frame of the most frequent video
  double frame_interval = std::numeric_limits<double>::infinity();
  for (const VideoOutput& v : scene.videos) frame_interval = std::min(frame_interval, v.speed / v.fps);
  std::vector<robot::GrowthEvent> workspace_events;  // the navigator's, merged with the growth's at the end
  std::vector<magnetics::Pose> poses;
  const auto poses_at = [&](double t) {
    std::vector<magnetics::Pose> p = scene.magnets->rest_poses;
    for (std::size_t i = 0; i < p.size(); ++i) {
      const auto& keys = scene.magnet_keyframes[i];
      if (keys.empty()) continue;
      const MagnetKeyframe k = interpolate(keys, t);
      p[i] = pose_at(scene.magnets->rest_poses[i], k.position, k.axis);
    }
    if (steered) {
      const auto i = static_cast<std::size_t>(scene.navigator->magnet);
      p[i] = pose_at(scene.magnets->rest_poses[i], steered->position, steered->axis);
    }
    return p;
  };
  const auto record_magnets = [&](double t) {
    for (std::size_t i = 0; i < poses.size(); ++i) {
      out.magnet_samples.push_back({t, static_cast<int>(i), poses[i].position, poses[i].rotation.col(2)});
    }
  };
  robot::RodField field;
  if (scene.navigator) {
    // The first pose from the straight body's tip, before the vine is built.
    const Vec3 tip0 = scene.base_position + scene.vine.length * scene.base_frame.col(0);
    steered = navigate(*scene.navigator, path, tip0, scene.base_frame, skin, 0.0, scene.navigator_offset, steered_line);
    keep_clear(*scene.navigator, scene.mesh, steered_body, tip0, steered_line, *steered);
    next_navigation = scene.navigator->interval;
  }
  if (scene.magnets) {
    poses = poses_at(0.0);
    field = robot::field_function(*scene.magnets, poses);
    record_magnets(0.0);
  }
  robot::VineParameters vine = scene.vine;
  vine.pressure = scene.pressure.at(0.0);
  std::optional<robot::VineGrowth> built;
  try {
    built.emplace(vine, scene.growth, &world, field, scene.base_position, scene.base_frame);
  } catch (const robot::VineParameterError& e) {
    // A starting pressure above burst (a perturbed trial): start at half of it; the first step then bursts the vine
    // (an event and an outcome, not an error).
    if (e.parameter() != "pressure") throw;
    vine.pressure *= 0.5;
    built.emplace(vine, scene.growth, &world, field, scene.base_position, scene.base_frame);
  }
  robot::VineGrowth& growth = *built;
  const auto record_frame = [&](double t) {
    if (scene.videos.empty() || t < next_frame - 1e-9) return;
    // One record per frame time passed (a step longer than a frame repeats the state: the video keeps time).
    FrameSample f;
    f.nodes = growth.state().x;
    f.tip_frame = growth.state().frames.back();
    for (const magnetics::Pose& pose : poses) {
      f.magnet_positions.push_back(pose.position);
      f.magnet_axes.push_back(pose.rotation.col(2));
    }
    while (next_frame <= t + 1e-9) {
      f.time = next_frame;
      out.frames.push_back(f);
      next_frame += frame_interval;
    }
  };
  record_frame(0.0);
  const auto steps = static_cast<long>(std::ceil(scene.duration / scene.dt - 1e-9));
  const bool moving = scene.navigator || std::any_of(scene.magnet_keyframes.begin(), scene.magnet_keyframes.end(),
                                                     [](const auto& k) { return k.size() > 1; });

  for (long k = 1; k <= steps; ++k) {
    const double t = std::min(scene.duration, static_cast<double>(k) * scene.dt);
    const double dt = t - growth.time();
    if (scene.navigator && t >= next_navigation - 1e-12) {
      steered = navigate(*scene.navigator, path, growth.state().tip(), growth.state().frames.back(), skin, t,
                         scene.navigator_offset, steered_line);
      if (!keep_clear(*scene.navigator, scene.mesh, steered_body, growth.state().tip(), steered_line, *steered) &&
          !workspace_warned) {
        workspace_warned = true;
        workspace_events.push_back({t, growth.length(), "workspace",
                              "the navigator's magnet overlaps the anatomy even at max_distance; placed there anyway"});
      }
      next_navigation += scene.navigator->interval;
    }
    if (scene.magnets && moving) {
      std::vector<magnetics::Pose> next = poses_at(t);
      bool changed = false;
      for (std::size_t i = 0; i < next.size(); ++i) {
        changed = changed || !next[i].position.isApprox(poses[i].position, 1e-12) ||
                  !next[i].rotation.isApprox(poses[i].rotation, 1e-12);
      }
      if (changed) {
        poses = std::move(next);
        growth.set_field(robot::field_function(*scene.magnets, poses));
        record_magnets(t);
      }
    }
    robot::GrowthControl control;
    control.pressure = scene.pressure.at(t);
    if (scene.tether) control.tether_length = scene.tether->at(t);
    const double length = growth.length();
    // Held (the boost's and the recovery's test): the length has not changed since grown_at, and no tether or made
    // length caps it.
    if (length != grown_length || length >= std::min(control.tether_length, scene.growth.max_length) - 1e-9) {
      grown_length = length;
      grown_at = t;
    }
    if (scene.navigator && scene.navigator->boost_pressure > 0.0) {
      if (boost_until >= 0.0 && length >= boost_until) boost_until = -1.0;
      if (boost_until < 0.0 && t - grown_at >= scene.navigator->boost_after - 1e-9) {
        boost_until = length + scene.navigator->boost_length;
      }
      if (boost_until >= 0.0) control.pressure = std::max(control.pressure, scene.navigator->boost_pressure);
    }
    if (scene.navigator && scene.navigator->deflate_pressure > 0.0) {
      // Pressure regulation (thesis 4.7.3): once per junction on the path, deflate for deflate_time while the magnet
      // bends the body towards the next branch, then back to the schedule (the next branch's walls hold the turn).
      const Vec3 tip = growth.state().tip();  // the last sample's, whose branch is known
      const int here = out.samples.empty() ? nearest_branch(*scene.graph, tip) : out.samples.back().branch;
      const auto at = std::find(plan.begin(), plan.end(), here);
      if (at != plan.end() && *at != plan.back() &&
          std::find(deflated_at.begin(), deflated_at.end(), here) == deflated_at.end() &&
          (tip - scene.graph->nodes[scene.graph->branches[static_cast<std::size_t>(here)].nodes.back()].position)
                  .norm() <= scene.navigator->junction_distance) {
        deflated_at.push_back(here);
        deflate_until = t + scene.navigator->deflate_time;
      }
      if (t < deflate_until) control.pressure = std::min(control.pressure, scene.navigator->deflate_pressure);
    }
    if (recovery && !out.success) {
      const int here = out.samples.empty() ? -1 : out.samples.back().branch;
      const bool off_path = here >= 0 && std::find(plan.begin(), plan.end(), here) == plan.end();
      const double held_for = t - std::max(grown_at, deflate_until);  // a deflation holds it too
      recovery->step(t, length, off_path ? scene.graph->branches[static_cast<std::size_t>(here)].name : "", held_for,
                     control, workspace_events);
      if (recovery->retracting()) boost_until = -1.0;
    }
    const robot::GrowthStepReport r = growth.advance(dt, control);
    out.converged = r.converged;
    if (!r.converged) {
      if (out.failed_steps++ == 0) out.failure = "at " + std::to_string(t) + " s: " + r.failure;
    }
    ExperimentSample s;
    s.time = t;
    s.tip = growth.state().tip();
    s.length = growth.length();
    s.pressure = control.pressure;
    s.max_normal = growth.wall_forces().max_normal;
    s.mean_normal = growth.wall_forces().mean_normal;
    s.total_normal = growth.wall_forces().total_normal;
    s.total_shear = growth.wall_forces().total_shear;
    s.unsettled = growth.wall_forces().unsettled;
    if (scene.graph) s.branch = nearest_branch(*scene.graph, s.tip);
    out.samples.push_back(s);
    record_frame(t);
    if (scene.shape_interval > 0.0 && t >= next_shape - 1e-9) {
      out.shapes.push_back({t, growth.state().x, growth.wall_forces().normal, growth.wall_forces().shear});
      next_shape += scene.shape_interval;
    }
    if (scene.target && out.time_to_target < 0.0 && (s.tip - *scene.target).norm() <= scene.target_tolerance) {
      out.time_to_target = t;
      out.success = true;
    }
    if (progress) progress(static_cast<double>(k) / static_cast<double>(steps));
    if (out.success && scene.stop_at_target) {
      if (progress) progress(1.0);
      break;
    }
  }
  if (recovery) out.recoveries = recovery->used();
  out.events = growth.events();
  out.events.insert(out.events.end(), workspace_events.begin(), workspace_events.end());
  std::stable_sort(out.events.begin(), out.events.end(),
                   [](const robot::GrowthEvent& a, const robot::GrowthEvent& b) { return a.time < b.time; });
  out.final_state = growth.state();
  out.final_forces = growth.wall_forces();
  out.runtime_s = clock.seconds();
  return out;
}

ExperimentScene with_target(const ExperimentScene& scene, const std::string& target) {
  if (!scene.navigator) {
    throw InputError(scene.file, 0, "control.navigator", "trials towards named targets need a navigator");
  }
  const auto branch = anatomy::find_branch(*scene.graph, target);
  if (!branch) throw InputError("--targets", 0, "", "no branch '" + target + "' in the phantom's graph of " + scene.file);
  ExperimentScene out = scene;
  aim_at(out, *branch);
  return out;
}

ExperimentScene perturbed(const ExperimentScene& scene, std::uint64_t seed) {
  ExperimentScene out = scene;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const TrialPerturbation& p = scene.perturbation;
  const Vec3 offset(p.magnet_position_sd * normal(rng), p.magnet_position_sd * normal(rng),
                    p.magnet_position_sd * normal(rng));
  const double pressure = p.pressure_sd * normal(rng);
  const double modulus = 1.0 + p.material_spread * normal(rng);
  const double yield = 1.0 + p.material_spread * normal(rng);
  if (out.magnets) {
    for (magnetics::Pose& pose : out.magnets->rest_poses) pose.position += offset;
    for (auto& keys : out.magnet_keyframes)
      for (MagnetKeyframe& k : keys) k.position += offset;
  }
  if (out.navigator) out.navigator_offset = offset;
  if (!out.growth.rod) {  // a pushed rod has no pressure
    for (double& v : out.pressure.values) v = std::max(0.0, v + pressure);
  }
  out.vine.wall.modulus *= modulus;
  if (out.growth.rod) {
    robot::RodModel& b = out.growth.rod->body;
    b.bending_stiffness_2 *= modulus;
    b.bending_stiffness_3 *= modulus;
    b.torsional_stiffness *= modulus;
    b.axial_stiffness *= modulus;
    b.shear_stiffness *= modulus;
  }
  out.growth.law.yield_pressure *= yield;
  out.seed = seed;
  return out;
}

std::vector<TrialOutcome> run_trials(const ExperimentScene& scene, const std::vector<std::string>& targets,
                                     int repeats, int jobs, const std::function<void(int, int)>& progress,
                                     const std::filesystem::path& runs_dir) {
  if (repeats < 1) throw InputError("--repeats", 0, "", "must be >= 1");
  if (jobs < 1) throw InputError("--jobs", 0, "", "must be >= 1");
  std::vector<ExperimentScene> aimed;
  std::vector<std::string> names;
  if (targets.empty()) {
    aimed.push_back(scene);
    names.push_back(scene.navigator ? scene.navigator->target : std::string("target"));
  } else {
    for (const std::string& t : targets) {
      aimed.push_back(with_target(scene, t));
      names.push_back(t);
    }
  }
  const int total = static_cast<int>(aimed.size()) * repeats;
  if (!runs_dir.empty()) create_output_directory(runs_dir);  // before the threads create their folders in it
  std::vector<TrialOutcome> outcomes(static_cast<std::size_t>(total));
  std::atomic<int> next{0};
  std::atomic<int> done{0};
  std::mutex report;
  std::exception_ptr failure;
  const auto worker = [&] {
    for (int i = next++; i < total; i = next++) {
      try {
        const std::size_t t = static_cast<std::size_t>(i / repeats);
        const int r = i % repeats;
        // The seed: the scene's, the target's index and the repeat (std::hash of a string is not stable across
        // library versions; the index is).
        const std::uint64_t seed = scene.seed * 1000003ULL + t * 10007ULL + static_cast<std::uint64_t>(r);
        const ExperimentScene trial = perturbed(aimed[t], seed);
        const ExperimentResult res = run_experiment(trial);
        TrialOutcome& o = outcomes[static_cast<std::size_t>(i)];
        o.target = names[t];
        o.repeat = r;
        o.seed = seed;
        o.success = res.success;
        o.time_to_target = res.time_to_target;
        const RunFigures f = figures_of(trial, res);
        o.everted_length = f.everted_length;
        o.final_error = f.final_error.value_or(0.0);
        o.max_normal = f.max_normal;
        o.unsettled = f.unsettled;
        o.retractions = res.recoveries;
        for (const robot::GrowthEvent& e : res.events) o.burst = o.burst || e.kind == "burst";
        o.runtime_s = res.runtime_s;
        if (!o.success) o.reason = failure_reason(res, f);
        if (!runs_dir.empty()) {
          ExperimentScene kept = trial;
          kept.videos.clear();  // trials write no videos
          write_experiment_outputs(kept, res, runs_dir / (names[t] + "_r" + std::to_string(r)));
        }
      } catch (...) {
        const std::lock_guard lock(report);
        if (!failure) failure = std::current_exception();
      }
      const int d = ++done;
      if (progress) {
        const std::lock_guard lock(report);
        progress(d, total);
      }
    }
  };
  std::vector<std::thread> threads;
  for (int j = 1; j < std::min(jobs, total); ++j) threads.emplace_back(worker);
  worker();
  for (std::thread& t : threads) t.join();
  if (failure) std::rethrow_exception(failure);
  return outcomes;
}

void write_trial_outputs(const std::vector<TrialOutcome>& outcomes, const std::filesystem::path& dir) {
  const auto quoted = [](const std::string& text) {
    std::string q = "\"";
    for (const char c : text) q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
  };
  std::ostringstream all;
  all.precision(10);
  all << "target,repeat,seed,success,burst,time_to_target_s,everted_length_m,final_error_m,max_normal_N,"
         "max_normal_unsettled_N,unsettled_steps,retractions,runtime_s,reason\n";
  for (const TrialOutcome& o : outcomes) {
    all << o.target << ',' << o.repeat << ',' << o.seed << ',' << (o.success ? 1 : 0) << ',' << (o.burst ? 1 : 0) << ','
        << (o.success ? std::to_string(o.time_to_target) : std::string()) << ',' << o.everted_length << ','
        << o.final_error << ',' << o.max_normal << ',' << o.unsettled.max_normal << ','
        << o.unsettled.count << ',' << o.retractions << ',' << o.runtime_s << ','
        << quoted(o.reason) << '\n';
  }
  std::ostringstream csv;
  std::ostringstream md;
  // A column for the navigator's retractions (Navigator::Recovery) where any trial had one.
  const bool retracted = std::any_of(outcomes.begin(), outcomes.end(), [](const TrialOutcome& o) {
    return o.retractions > 0;
  });
  csv << "target,path_length_mm,successes,trials,success_rate,mean_time_s,sd_time_s,retractions\n";
  md << "| target | path length [mm] | success | mean time [s] | SD [s] |" << (retracted ? " retractions |" : "")
     << "\n|---|---|---|---|---|" << (retracted ? "---|" : "") << "\n";
  std::vector<std::string> order;
  for (const TrialOutcome& o : outcomes) {
    if (std::find(order.begin(), order.end(), o.target) == order.end()) order.push_back(o.target);
  }
  char line[256];
  for (const std::string& target : order) {
    int n = 0;
    int ok = 0;
    double sum_t = 0.0;
    double sum_t2 = 0.0;
    double sum_l = 0.0;
    int retractions = 0;
    for (const TrialOutcome& o : outcomes) {
      if (o.target != target) continue;
      ++n;
      retractions += o.retractions;
      if (!o.success) continue;
      ++ok;
      sum_t += o.time_to_target;
      sum_t2 += o.time_to_target * o.time_to_target;
      sum_l += o.everted_length;
    }
    const double mean = ok > 0 ? sum_t / ok : std::nan("");
    const double sd = ok > 1 ? std::sqrt(std::max(0.0, (sum_t2 - ok * mean * mean) / (ok - 1))) : std::nan("");
    const double length = ok > 0 ? 1e3 * sum_l / ok : std::nan("");
    std::snprintf(line, sizeof line, "%s,%.1f,%d,%d,%.3f,%.2f,%.2f,%d\n", target.c_str(), length, ok, n,
                  static_cast<double>(ok) / n, mean, sd, retractions);
    csv << line;
    // A table cell with no value (no success, or one: no SD) reads as a dash, not "nan".
    const auto cell = [](double value, const char* format) {
      if (!std::isfinite(value)) return std::string("—");
      char text[32];
      std::snprintf(text, sizeof text, format, value);
      return std::string(text);
    };
    md << "| " << target << " | " << cell(length, "%.0f") << " | " << ok << '/' << n << " | " << cell(mean, "%.1f")
       << " | " << cell(sd, "%.1f") << " |";
    if (retracted) md << ' ' << retractions << " |";
    md << '\n';
  }
  bool failures = false;
  for (const TrialOutcome& o : outcomes) {
    if (o.success) continue;
    if (!failures) md << "\nFailures:\n\n";
    failures = true;
    md << "- " << o.target << ", repeat " << o.repeat << " (seed " << o.seed << "): " << o.reason << "\n";
  }
  create_output_directory(dir);
  write_file_atomically(dir / "trials.csv", all.str());
  write_file_atomically(dir / "summary.csv", csv.str());
  write_file_atomically(dir / "summary.md", md.str());
}

void write_experiment_outputs(const ExperimentScene& scene, const ExperimentResult& result,
                              const std::filesystem::path& dir) {
  const auto vec = [](const Vec3& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); };
  nlohmann::json j;
  const Vec3 tip = result.final_state.tip();
  j["scene"] = scene.file;
  j["anatomy"] = scene.anatomy_label;
  j["seed"] = scene.seed;
  j["success"] = result.success;
  j["time_to_target_s"] = result.time_to_target >= 0.0 ? nlohmann::json(result.time_to_target) : nlohmann::json();
  const RunFigures f = figures_of(scene, result);
  j["final_tip_error_m"] = f.final_error ? nlohmann::json(*f.final_error) : nlohmann::json();
  j["tip_position_m"] = vec(tip);
  j["everted_length_m"] = f.everted_length;
  j["tip_path_length_m"] = f.path;
  j["branches_reached"] = f.branches;
  const auto optional = [](const std::optional<double>& v) { return v ? nlohmann::json(*v) : nlohmann::json(); };
  j["generation_reached"] = f.generation >= 0 ? nlohmann::json(f.generation) : nlohmann::json();
  j["tip_to_centreline_m"] = optional(f.centreline);
  j["mean_tip_to_centreline_m"] = optional(f.mean_centreline);
  j["path_progress"] = optional(f.progress);
  j["max_wall_normal_N"] = f.max_normal;
  j["mean_wall_normal_N"] = f.mean_normal;
  j["max_wall_shear_N"] = f.max_shear;
  j["unsettled_steps"] = f.unsettled.count;
  j["max_wall_normal_unsettled_N"] = f.unsettled.max_normal;
  int stalls = 0;
  int blocked = 0;
  nlohmann::json events = nlohmann::json::array();
  for (const robot::GrowthEvent& e : result.events) {
    stalls += e.kind == "stall" || e.kind == "squeeze";
    blocked += e.kind == "blocked";
    events.push_back({{"time_s", e.time}, {"length_m", e.length}, {"kind", e.kind}, {"detail", e.detail}});
  }
  j["stalls"] = stalls;
  j["blocked"] = blocked;
  j["retractions"] = result.recoveries;  // the navigator's, out of wrong turns (control.navigator.recover)
  j["events"] = static_cast<int>(result.events.size());
  double travel = 0.0;
  std::vector<std::optional<Vec3>> previous(scene.magnets ? scene.magnets->size() : 0);
  for (const MagnetSample& m : result.magnet_samples) {
    auto& p = previous[static_cast<std::size_t>(m.magnet)];
    if (p) travel += (m.position - *p).norm();
    p = m.position;
  }
  j["magnet_travel_m"] = travel;
  const double simulated = result.samples.empty() ? 0.0 : result.samples.back().time;
  j["simulated_s"] = simulated;
  j["runtime_s"] = result.runtime_s;
  j["real_time_factor"] = result.runtime_s > 0.0 ? nlohmann::json(simulated / result.runtime_s) : nlohmann::json();
  j["converged"] = result.converged;
  j["failed_steps"] = result.failed_steps;
  j["failure"] = result.failure;

  std::ostringstream tips;
  tips.precision(10);
  tips << "t_s,x_m,y_m,z_m,length_m,pressure_Pa,max_normal_N,mean_normal_N,total_normal_N,total_shear_N,branch,"
          "unsettled\n";
  for (const ExperimentSample& s : result.samples) {
    tips << s.time << ',' << s.tip.x() << ',' << s.tip.y() << ',' << s.tip.z() << ',' << s.length << ','
         << s.pressure << ',' << s.max_normal << ',' << s.mean_normal << ',' << s.total_normal << ',' << s.total_shear
         << ','
         << (s.branch >= 0 ? scene.graph->branches[static_cast<std::size_t>(s.branch)].name : std::string()) << ','
         << (s.unsettled ? 1 : 0) << '\n';
  }
  std::ostringstream shape;
  shape.precision(10);
  // Per node: the position and the wall's forces on the tissue there (0 where a run's forces have fewer nodes).
  const auto node_row = [](std::ostream& o, const Vec3& x, const std::vector<double>& normal,
                           const std::vector<double>& shear, std::size_t i) {
    o << x.x() << ',' << x.y() << ',' << x.z() << ',' << (i < normal.size() ? normal[i] : 0.0) << ','
      << (i < shear.size() ? shear[i] : 0.0) << '\n';
  };
  shape << "x_m,y_m,z_m,normal_N,shear_N\n";
  for (std::size_t i = 0; i < result.final_state.x.size(); ++i) {
    node_row(shape, result.final_state.x[i], result.final_forces.normal, result.final_forces.shear, i);
  }

  create_output_directory(dir);
  write_file_atomically(dir / "tip_trajectory.csv", tips.str());
  write_file_atomically(dir / "shape.csv", shape.str());
  if (scene.shape_interval > 0.0) {
    std::ostringstream shapes;
    shapes.precision(10);
    shapes << "t_s,node,x_m,y_m,z_m,normal_N,shear_N\n";
    for (const ShapeSample& sample : result.shapes) {
      for (std::size_t i = 0; i < sample.nodes.size(); ++i) {
        shapes << sample.time << ',' << i << ',';
        node_row(shapes, sample.nodes[i], sample.normal, sample.shear, i);
      }
    }
    write_file_atomically(dir / "shapes.csv", shapes.str());
  }
  write_file_atomically(dir / "events.json", events.dump(2) + "\n");
  if (scene.graph) anatomy::write_graph(dir / "graph.json", *scene.graph);
  if (scene.magnets) {
    std::ostringstream mags;
    mags.precision(10);
    mags << "t_s,magnet,x_m,y_m,z_m,axis_x,axis_y,axis_z\n";
    for (const MagnetSample& m : result.magnet_samples) {
      mags << m.time << ',' << m.magnet << ',' << m.position.x() << ',' << m.position.y() << ',' << m.position.z()
           << ',' << m.axis.x() << ',' << m.axis.y() << ',' << m.axis.z() << '\n';
    }
    write_file_atomically(dir / "magnet_trajectory.csv", mags.str());
  }
#if MAGVINE_WITH_RENDER
  if (!scene.videos.empty()) {
    VideoInputs in;
    if (scene.navigator) {
      in.planned_path = planned_path(*scene.graph, anatomy::path_from_root(*scene.graph, scene.navigator->target_branch));
    }
    for (std::size_t i = 0; scene.magnets && i < scene.magnets->size(); ++i) {
      const std::optional<MagnetBody> body = magnet_body(*scene.magnets, i);
      in.magnet_diameters.push_back(body ? 2.0 * body->radius : 0.0);
      in.magnet_lengths.push_back(body ? 2.0 * body->half_length : 0.0);
    }
    j["videos"] = write_videos(scene, result, in, dir);
  }
#else
  if (!scene.videos.empty()) {
    j["videos"] = nlohmann::json::array();
    j["videos_skipped"] = "this magvine was built without the render module (cmake -DMAGVINE_WITH_RENDER=ON)";
  }
#endif
  write_file_atomically(dir / "metrics.json", j.dump(2) + "\n");
}

}  // namespace magvine::scene
