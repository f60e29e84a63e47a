#include "magvine/scene/experiment.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>

#include "magvine/anatomy/airway_graph.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/stopwatch.hpp"
#include "magvine/core/text.hpp"
#include "magvine/magnetics/field_function.hpp"
#include "magvine/magnetics/interaction.hpp"
#include "magvine/scene/navigator.hpp"
#include "magvine/scene/video_plugin.hpp"

namespace magvine::scene {

std::string_view event_name(EventKind kind) {
  switch (kind) {
    case EventKind::kRecover:
      return "recover";
    case EventKind::kWorkspace:
      return "workspace";
    case EventKind::kTorque:
      return "torque";
    default:
      return robot::growth_event_name(static_cast<robot::GrowthEventKind>(kind));
  }
}

EventKind event_kind(robot::GrowthEventKind kind) {
  return static_cast<EventKind>(kind);
}

RunEvent run_event(const robot::GrowthEvent& e) {
  return {e.time, e.length, event_kind(e.kind), e.detail};
}

namespace {

/// Whether the magnets move in this run (keyframes or the navigator).
bool magnets_move(const ExperimentScene& scene) {
  return scene.navigator || std::any_of(scene.magnet_keyframes.begin(), scene.magnet_keyframes.end(),
                                        [](const auto& k) { return k.size() > 1; });
}

/// The magnets' poses at time t: keyframed (magnetics::poses_at), with the navigator's magnet where it placed it.
std::vector<magnetics::Pose> poses_at(const ExperimentScene& scene, const NavigatorController* navigator, double t) {
  std::vector<magnetics::Pose> p = magnetics::poses_at(*scene.magnets, scene.magnet_keyframes, t);
  if (navigator != nullptr) {
    const auto i = static_cast<std::size_t>(navigator->magnet());
    p[i] = magnetics::pose_at(scene.magnets->rest_poses[i], navigator->pose().position, navigator->pose().axis);
  }
  return p;
}

/// The field the body reads at time t: the magnets' at their poses plus control.field's uniform field (no curvature:
/// a uniform field has none).
robot::RodField body_field(const ExperimentScene& scene, const std::vector<magnetics::Pose>& poses, double t) {
  robot::RodField magnets;
  if (scene.magnets) magnets = magnetics::field_function(*scene.magnets, poses);
  if (!scene.uniform_field) return magnets;
  const Vec3 b = scene.uniform_field->at(t);
  if (!magnets) {
    return robot::RodField([b](const Vec3&) { return magnetics::FieldSample{.b = b, .g = Mat3::Zero()}; },
                           [](const Vec3&, const Vec3&) { return Mat3::Zero(); });
  }
  return robot::RodField(
      [magnets, b](const Vec3& x) {
        magnetics::FieldSample f = magnets(x);
        f.b += b;
        return f;
      },
      magnets.curvature());
}

}  // namespace

struct Experiment::Impl {
  explicit Impl(const ExperimentScene& s);

  const ExperimentScene& scene;
  const SceneAnatomy& anatomy;
  Stopwatch clock;
  ExperimentResult out;
  std::optional<NavigatorController> navigator;
  // Camera guidance: the tip camera (the video plugin's) shows the navigator the lumens from where the tip is.
  std::unique_ptr<TipEye> eye;
  std::vector<RunEvent> navigator_events;  // merged with the growth's at the end
  std::vector<magnetics::Pose> poses;
  // The platform (platform:): the arms take the magnets' poses as requests and the field comes from where they
  // reach. A request an arm cannot serve is replaced by the nearest feasible pose (a workspace event).
  std::optional<platform::PlatformRun> arms;
  double platform_seconds = 0.0;      // computing spent on the arms and the navigator's placements through them
  std::vector<MagnetKeyframe> asked;  // the last pose asked of each arm-held magnet
  bool torque_logged = false;
  robot::RodField field;
  robot::VineParameters vine;
  // Breathing (scene.breathing): the run moves its own copy of the airway, refitted every step, from the rest shape
  // (the planning CT's, at full inspiration). The graph, the navigator's plan, the target and the nodule stay in the
  // rest frame; the tip is taken back to it (breathing_rest_point) to read them.
  std::optional<anatomy::CollisionWorld> breathing_world;
  std::vector<Vec3> rest_vertices;
  std::vector<double> amplitudes;  // each vertex's breathing amplitude (time-independent)
  std::vector<Vec3> moved_vertices;
  // The growth step function (growth.hpp): the model, the state (a checkpoint is a copy), the workspace.
  robot::GrowthModel model;
  robot::GrowthState state;
  robot::GrowthWorkspace workspace;
  std::vector<robot::GrowthEvent> growth_events;
  double next_shape = 0.0;  // outputs.shape_interval
  double next_frame = 0.0;  // outputs.video: one record per frame of the most frequent video
  double frame_interval = std::numeric_limits<double>::infinity();
  // A biopsy (ExperimentScene::biopsy): once the tip reaches the stop, the navigator's magnet aims the tip at the
  // nodule (the vine grows on towards it until the wall ahead blocks it) until aim_until; then the needle is pushed
  // with the tether held and the run ends.
  std::optional<double> aim_until;
  long scheduled = 0;         // ceil(duration / dt)
  long taken = 0;             // steps taken
  long grid = 0;              // the grid index k of the last step to k·dt (a driver's own dt leaves it)
  double pressure_now = 0.0;  // the pressure of the last step (at first the starting one) [Pa]
  bool moving = false;        // the magnets move (keyframes, the navigator, the arms, a driver)
  bool stopped = false;       // at the target with stop_at_target
  bool aimed = false;         // a biopsy's aiming done: the puncture follows
  bool finished = false;
  bool broken = false;  // a step threw midway (the state is half advanced: no step may follow)
  // A driver's settings (StepRequest), held from the step that set them.
  std::optional<double> held_pressure;
  std::optional<double> held_tether;
  std::vector<std::optional<MagnetKeyframe>> held_magnets;

  void record_magnets(double t) {
    for (std::size_t i = 0; i < poses.size(); ++i) {
      out.magnet_samples.push_back({t, static_cast<int>(i), poses[i].position, poses[i].rotation.col(2)});
    }
  }
  void ask_arms(double t, const std::vector<magnetics::Pose>& wanted, bool start) {
    for (std::size_t a = 0; a < scene.platform->arms.size(); ++a) {
      const int i = scene.platform->arms[a].magnet;
      if (navigator && navigator->steers(i)) continue;  // the navigator asks its arms itself
      const magnetics::Pose& w = wanted[static_cast<std::size_t>(i)];
      const Vec3 axis = w.rotation.col(2);
      MagnetKeyframe& last = asked[a];
      if (!start && last.position.isApprox(w.position, 1e-12) && last.axis.isApprox(axis, 1e-12)) continue;
      last = {t, w.position, axis};
      const platform::Placement p = arms->request(static_cast<int>(a), w.position, axis, start);
      if (!p.why.empty()) {
        navigator_events.push_back(
            {t, 0.0, EventKind::kWorkspace, printf_string("arm %zu (magnets[%d]): ", a, i) + p.why});
      }
    }
  }
  // The magnets' poses the arms have reached.
  void reached(std::vector<magnetics::Pose>& p) const {
    for (std::size_t a = 0; a < scene.platform->arms.size(); ++a) {
      const auto i = static_cast<std::size_t>(scene.platform->arms[a].magnet);
      const platform::Iso3 m = arms->magnet_pose(static_cast<int>(a));
      p[i] = magnetics::pose_at(scene.magnets->rest_poses[i], m.translation(), m.linear().col(2));
    }
  }
  // dEPM: the wrenches the two held magnets put on each other, with arm 0's magnet at ta and arm 1's at tb: on
  // magnet 1 (F₁, τ₁ about its centre) by the exact field of magnet 0 over it (magnetics/interaction.hpp); on
  // magnet 0 the reaction F₀ = −F₁ and, about its own centre, τ₀ = −τ₁ − (c₀ − c₁) × F₀.
  std::array<std::pair<Vec3, Vec3>, 2> pair_wrench(const platform::Iso3& ta, const platform::Iso3& tb) const {
    const auto i = static_cast<std::size_t>(scene.platform->arms[0].magnet);
    const auto j = static_cast<std::size_t>(scene.platform->arms[1].magnet);
    const magnetics::Pose pa = magnetics::pose_at(scene.magnets->rest_poses[i], ta.translation(), ta.linear().col(2));
    const magnetics::Pose pb = magnetics::pose_at(scene.magnets->rest_poses[j], tb.translation(), tb.linear().col(2));
    const magnetics::Wrench on_b =
        magnetics::magnet_magnet_wrench(std::get<magnetics::CylinderMagnet>(scene.magnets->sources[i]), pa,
                                        std::get<magnetics::CylinderMagnet>(scene.magnets->sources[j]), pb);
    const Vec3 f_a = -on_b.force;
    return {std::pair{f_a, Vec3(-on_b.torque - (pa.position - pb.position).cross(f_a))},
            std::pair{on_b.force, on_b.torque}};
  }
  void advance_arms(double t, double dt, std::vector<magnetics::Pose>& p) {
    const auto wrench = [&]() {
      std::vector<std::pair<Vec3, Vec3>> w(scene.platform->arms.size(), {Vec3::Zero(), Vec3::Zero()});
      if (w.size() == 2) {
        const auto both = pair_wrench(arms->magnet_pose(0), arms->magnet_pose(1));
        w = {both[0], both[1]};
      }
      return w;
    };
    arms->advance(t, dt, wrench);
    if (!torque_logged && arms->figures().max_torque_fraction > 1.0) {
      torque_logged = true;
      navigator_events.push_back({t, 0.0, EventKind::kTorque,
                                  printf_string("an arm needs %.0f %% of a joint's torque limit to hold its magnet",
                                                100.0 * arms->figures().max_torque_fraction)});
    }
    reached(p);
  }
  Vec3 displacement(const Vec3& x, double t) const {
    return scene.breathing ? anatomy::breathing_displacement(*scene.breathing, x, t) : Vec3::Zero();
  }
  Vec3 at_rest(const Vec3& x, double t) const {
    return scene.breathing ? anatomy::breathing_rest_point(*scene.breathing, x, t) : x;
  }
  // `needle`: during a biopsy's puncture, its increment (the needle drawn from the tip to its point).
  void record_frame(double t, const robot::PunctureStep* needle = nullptr) {
    if (scene.videos.empty() || t < next_frame - 1e-9) return;
    // One record per frame time passed (a step longer than a frame repeats the state: the video keeps time).
    FrameSample f;
    f.nodes = state.body.x;
    f.tip_frame = state.body.frames.back();
    for (const magnetics::Pose& pose : poses) {
      f.magnet_positions.push_back(pose.position);
      f.magnet_axes.push_back(pose.rotation.col(2));
    }
    if (arms) f.arm_links = arms->link_capsules();
    if (needle != nullptr) {
      f.needle_base = needle->tip;
      f.needle_tip = needle->needle_tip;
      f.needle_radius = 0.5 * scene.biopsy->needle.diameter;
    }
    while (next_frame <= t + 1e-9) {
      f.time = next_frame;
      out.frames.push_back(f);
      next_frame += frame_interval;
    }
  }
  // The sample of the state after a step at time t under `pressure`.
  ExperimentSample sample_at(double t, double pressure) const {
    ExperimentSample s;
    s.time = t;
    s.tip = state.body.tip();
    s.length = workspace.body.length;
    s.pressure = pressure;
    const robot::WallForces& forces = state.forces;
    s.max_normal = forces.max_normal;
    s.max_line_load = forces.max_line_load;
    s.mean_normal = forces.mean_normal;
    s.total_normal = forces.total_normal;
    s.total_shear = forces.total_shear;
    s.max_pressure = forces.max_pressure;
    s.imbalance = forces.largest_load > 0.0 ? forces.imbalance.norm() / forces.largest_load : 0.0;
    if (scene.breathing) s.inspiration = anatomy::inspiration(*scene.breathing, t);
    if (anatomy.graph) {
      const anatomy::CentrelinePoint near = anatomy::nearest_centreline_point(*anatomy.graph, at_rest(s.tip, t));
      s.branch = near.branch;
      s.centreline = near.distance;
    }
    return s;
  }
  void puncture() {
    const Biopsy& b = *scene.biopsy;
    const Vec3 tip = state.body.tip();
    // The nodule where breathing has it now (the puncture itself is quick: the airway is held there during it).
    const Vec3 nodule = b.nodule + displacement(b.nodule, state.time);
    const Vec3 to_nodule = (nodule - tip).normalized();
    out.aim_angle = std::acos(std::clamp(state.body.frames.back().col(0).dot(to_nodule), -1.0, 1.0));
    out.puncture = robot::push_needle(model, field, b.needle, nodule, b.radius,
                                      held_pressure.value_or(scene.pressure.at(state.time)), state, workspace,
                                      [&](const robot::PunctureStep& p, const robot::GrowthState& st) {
                                        out.samples.push_back(sample_at(p.time, st.pressure));
                                        record_frame(p.time, &p);
                                      });
  }
  void check(const StepRequest& request) const;
  bool step(const StepRequest& request);
};

Experiment::Impl::Impl(const ExperimentScene& s) : scene(s), anatomy(*s.anatomy) {
  if (scene.navigator) navigator.emplace(scene);
  if (scene.magnets) {
    held_magnets.resize(scene.magnets->size());
    poses = poses_at(scene, navigator ? &*navigator : nullptr, 0.0);
    if (scene.platform) {
      arms.emplace(*scene.platform);
      if (scene.platform->arms.size() == 2) {
        // dEPM: the two magnets pull on each other (hundreds of newtons within 20 cm); no pose may ask either arm for
        // more than its joints' torque limits to hold that (and its weight).
        arms->set_pose_check([this](int arm, const platform::JointVector& q) -> std::string {
          const int other = 1 - arm;
          const platform::Iso3 here =
              platform::magnet_pose(scene.platform->arm, scene.platform->arms[static_cast<std::size_t>(arm)], q);
          const auto w = arm == 0 ? pair_wrench(here, arms->magnet_pose(1)) : pair_wrench(arms->magnet_pose(0), here);
          const platform::JointVector& limit = scene.platform->arm.tau_max;
          const auto beyond = [&](const platform::JointVector& tau) {
            return (tau.cwiseAbs().array() > limit.array()).any();
          };
          const auto& mine = w[static_cast<std::size_t>(arm)];
          const auto& theirs = w[static_cast<std::size_t>(other)];
          if (beyond(arms->holding_torques_at(arm, q, mine.first, mine.second))) {
            return "the other arm's magnet would pull it beyond a joint's torque limit";
          }
          if (beyond(arms->holding_torques_at(other, arms->joints(other), theirs.first, theirs.second))) {
            return "its magnet would pull the other arm beyond a joint's torque limit";
          }
          return {};
        });
      }
      asked.resize(scene.platform->arms.size());
      if (navigator) {
        navigator->use_platform(&*arms, 0.0, scene.base_position + scene.vine.length * scene.base_frame.col(0),
                                scene.base_frame, scene.vine.length, navigator_events);
      }
      ask_arms(0.0, poses, true);
      advance_arms(0.0, 0.0, poses);
    }
    record_magnets(0.0);
  }
  field = body_field(scene, poses, 0.0);
  vine = scene.vine;
  vine.pressure = scene.pressure.at(0.0);
  // A starting pressure above burst (a perturbed trial): start at half of it; the first step then bursts the vine
  // (an event and an outcome, not an error). A pushed rod or catheter has no film to burst.
  const bool solid = scene.growth.catheter || scene.growth.rod;
  if (!solid && robot::bursts(vine, vine.pressure)) vine.pressure *= 0.5;
  if (scene.breathing) {
    breathing_world.emplace(anatomy.mesh(), anatomy.world.options());
    rest_vertices = anatomy.mesh().vertices;
    amplitudes = anatomy::breathing_amplitudes(*scene.breathing, rest_vertices);
    moved_vertices = rest_vertices;
  }
  const anatomy::CollisionWorld& world = breathing_world ? *breathing_world : anatomy.world;
  model = robot::make_growth_model(vine, scene.growth, &world, scene.base_position, scene.base_frame);
  growth_events = robot::start_growth(model, field, vine.length, vine.pressure, state, workspace).events;
  pressure_now = vine.pressure;
  if (navigator && scene.navigator->camera) {
    eye = video_plugin("control.navigator.guidance").tip_eye(scene);
    navigator->use_camera([this]() {
      if (breathing_world) eye->move(moved_vertices);  // the airway as it is now (its shape at state.time)
      return eye->look(state.body.tip(), state.body.frames.back());
    });
  }
  for (const VideoOutput& v : scene.videos) frame_interval = std::min(frame_interval, v.speed / v.fps);
  record_frame(0.0);
  scheduled = static_cast<long>(std::ceil(scene.duration / scene.dt - 1e-9));
  moving = magnets_move(scene) || scene.platform != nullptr;  // arms report every step
}

void Experiment::Impl::check(const StepRequest& r) const {
  const auto finite = [](const char* key, double v, bool positive) {
    if (!std::isfinite(v) || (positive && v <= 0.0) || v < 0.0) {
      throw InputError("step", 0, key, printf_string("must be finite and %s (got %g)", positive ? "> 0" : ">= 0", v));
    }
  };
  if (r.dt) finite("dt", *r.dt, true);
  if (r.pressure) finite("pressure", *r.pressure, false);
  if (r.tether) finite("tether", *r.tether, false);
  for (const StepRequest::Magnet& m : r.magnets) {
    if (m.magnet < 0 || static_cast<std::size_t>(m.magnet) >= held_magnets.size()) {
      throw InputError("step", 0, "magnet_pose",
                       printf_string("magnet %d: the scene has %zu magnets", m.magnet, held_magnets.size()));
    }
    if (navigator && navigator->steers(m.magnet)) {
      throw InputError("step", 0, "magnet_pose", printf_string("magnet %d is steered by control.navigator", m.magnet));
    }
    if (!m.position.allFinite() || !m.axis.allFinite() || m.axis.norm() < 1e-12) {
      throw InputError("step", 0, "magnet_pose",
                       printf_string("magnet %d: the position and a non-zero axis must be finite", m.magnet));
    }
  }
}

bool Experiment::Impl::step(const StepRequest& request) {
  if (request.pressure) held_pressure = request.pressure;
  if (request.tether) held_tether = request.tether;
  for (const StepRequest::Magnet& m : request.magnets) {
    held_magnets[static_cast<std::size_t>(m.magnet)] = MagnetKeyframe{0.0, m.position, m.axis.normalized()};
    moving = true;
  }
  const long k = taken + 1;
  // The next multiple of dt (as `magvine run` steps: k·dt, clipped at the duration), or the driver's step.
  double t = 0.0;
  if (request.dt) {
    t = state.time + *request.dt;
  } else {
    grid = static_cast<long>(std::floor(state.time / scene.dt + 1e-6)) + 1;
    t = static_cast<double>(grid) * scene.dt;
    if (state.time < scene.duration) t = std::min(scene.duration, t);
  }
  const double dt = t - state.time;
  taken = k;
  // Gating (Navigator::Gate): outside the phase window the navigator neither places its magnet nor regulates, and
  // the tether holds the vine.
  const bool open = !(scene.navigator && scene.navigator->gate) ||
                    scene.navigator->gate->open(anatomy::inspiration(*scene.breathing, t));
  // The body and the airway it lies in are at state.time until the step (the navigator's camera sees them there).
  if (navigator) navigator->airway_at(state.time);
  // The tip in the rest frame (the plan's), read by the navigator only (its placing and regulation, the guidance
  // report's truth, the magnet's carry): an iterative solve under breathing, skipped without one. The body does
  // not move until the step below.
  const Vec3 tip_at_rest = navigator ? at_rest(state.body.tip(), state.time) : Vec3(state.body.tip());
  if (navigator && !aim_until && open) {
    const Stopwatch placing;
    const std::size_t looked = navigator->guidance().size();
    navigator->place(t, tip_at_rest, state.body.frames.back(), workspace.body.length, navigator_events);
    if (arms) platform_seconds += placing.seconds();
    if (navigator->guidance().size() > looked) {
      // The truth beside a camera-guided placement, for the report.
      GuidanceSample& g = navigator->guidance().back();
      const Vec3& tip = tip_at_rest;  // in the plan's (rest) frame, as the oracle reads it
      g.true_arc = arc_length_of_nearest(navigator->path(), tip);
      const Vec3 oracle = navigator->oracle_line(tip, state.body.frames.back());
      g.line_error = std::acos(std::clamp(oracle.dot(g.line), -1.0, 1.0));
      if (scene.navigator->camera->frames && g.lumens > 1) g.picture = eye->picture(g.chosen);
    }
  }
  if (scene.magnets && moving) {
    std::vector<magnetics::Pose> next = poses_at(scene, navigator ? &*navigator : nullptr, t);
    for (std::size_t i = 0; i < held_magnets.size(); ++i) {
      if (held_magnets[i]) {
        next[i] = magnetics::pose_at(scene.magnets->rest_poses[i], held_magnets[i]->position, held_magnets[i]->axis);
      }
    }
    if (navigator && scene.breathing && !aim_until && !arms) {
      // The navigator placed its magnet from the tip taken back to the rest frame: carried with the tip. Camera
      // guidance does not read the tip: it carries the magnet by the breathing model where its dead reckoning has
      // the tip (a respiratory motion model known before the procedure).
      const std::optional<Vec3> estimated = navigator->estimated_tip(workspace.body.length);
      next[static_cast<std::size_t>(navigator->magnet())].position +=
          displacement(estimated ? *estimated : tip_at_rest, state.time);
    }
    if (aim_until && !arms) {
      // Aiming: the navigator's magnet on the line from the tip to the nodule, its distance away, axis along it
      // (a fill is pulled towards it).
      const auto i = static_cast<std::size_t>(navigator->magnet());
      const Vec3 nodule = scene.biopsy->nodule + displacement(scene.biopsy->nodule, state.time);
      const Vec3 d = (nodule - state.body.tip()).normalized();
      next[i] = magnetics::pose_at(scene.magnets->rest_poses[i],
                                   state.body.tip() + scene.navigator->distance * d + scene.navigator_offset, d);
    }
    if (arms) {
      const Stopwatch arm_clock;
      ask_arms(t, next, false);
      advance_arms(t, dt, next);
      platform_seconds += arm_clock.seconds();
    }
    bool changed = false;
    for (std::size_t i = 0; i < next.size(); ++i) {
      changed = changed || !next[i].position.isApprox(poses[i].position, 1e-12) ||
                !next[i].rotation.isApprox(poses[i].rotation, 1e-12);
    }
    if (changed) {
      poses = std::move(next);
      field = body_field(scene, poses, t);
      record_magnets(t);
    }
  }
  if (scene.uniform_field) field = body_field(scene, poses, t);
  robot::GrowthControl control;
  control.pressure = scene.pressure.at(t);
  if (scene.tether) control.tether_length = scene.tether->at(t);
  if (!open) control.tether_length = std::min(control.tether_length, workspace.body.length);
  if (navigator && !aim_until && open) {
    const int branch = out.samples.empty() ? -1 : out.samples.back().branch;
    navigator->regulate(t, workspace.body.length, branch, out.success, tip_at_rest, control, navigator_events);
  } else if (navigator && !aim_until) {
    navigator->pause(t, workspace.body.length);  // gated: no boost, deflation or recovery while the tether holds
  }
  if (held_pressure) control.pressure = *held_pressure;
  if (held_tether) control.tether_length = *held_tether;
  if (!open) control.tether_length = std::min(control.tether_length, workspace.body.length);  // the gate holds
  // The airway moves to its shape at `to`, and carries the body and the material laid on its wall with it from
  // state.time (the displacement's change where each point is; the clamp, at the fixed entry, stays).
  const auto breathe_to = [&](double to) {
    anatomy::breathing_vertices(*scene.breathing, rest_vertices, amplitudes, to, moved_vertices);
    breathing_world->refit(moved_vertices);
    // The phases once a move, and each point's amplitude once (the same law as displacement(), evaluated apart).
    const anatomy::BreathingParams& b = *scene.breathing;
    const double before = anatomy::inspiration(b, state.time);
    const double after = anatomy::inspiration(b, to);
    const auto carry = [&](Vec3& x) {
      if (!x.allFinite()) return;
      const double amplitude = anatomy::breathing_amplitude(b, at_rest(x, state.time));
      x += anatomy::breathing_displacement(b, amplitude, after) - anatomy::breathing_displacement(b, amplitude, before);
    };
    for (std::size_t i = 1; i < state.body.x.size(); ++i) {
      carry(state.body.x[i]);
      carry(state.nodes[i].reference);
      carry(state.nodes[i].radius_at);
    }
  };
  robot::GrowthStatus r;
  if (!breathing_world) {
    r = robot::grow_step(model, field, control, state, workspace, dt);
  } else {
    // The wall's motion is a load of the step, which grow_step's own retries (halves of the growth) do not cut: a
    // step that fails is taken again from where it began as 2, then 4 steps, the airway moved a piece each (a
    // blocked tip's step is the same problem in every half of its growth; measured: a generation-4 trial whose lag
    // did not settle at 9.26 s in any of grow_step's halves settled as 2 moves of the airway).
    const double from = state.time;
    r = robot::grow_step_in_pieces(model, field, control, state, workspace, dt, {1, 2, 4},
                                   [&](int j, int pieces) { breathe_to(j == pieces ? t : from + dt * j / pieces); });
    if (!r.converged) r.failure += " (also with the airway's motion in the step taken as 2 and 4 moves)";
  }
  pressure_now = control.pressure;
  growth_events.insert(growth_events.end(), r.events.begin(), r.events.end());
  out.converged = r.converged;
  if (!r.converged) {
    // A failed step was retried in halves already: one that still fails ends the run (docs/cli.md: failed runs,
    // exit 3).
    ++out.failed_steps;
    out.failure = printf_string("step %ld at %.3f s failed: %s", k, t, r.failure.c_str());
    return false;
  }
  const ExperimentSample s = sample_at(t, control.pressure);
  const robot::WallForces& forces = state.forces;
  out.samples.push_back(s);
  record_frame(t);
  if (scene.shape_interval > 0.0 && t >= next_shape - 1e-9) {
    out.shapes.push_back(
        {t, state.body.x, forces.normal, forces.shear, forces.normal_vector, forces.shear_vector, forces.pressure});
    next_shape += scene.shape_interval;
  }
  if (scene.target && out.time_to_target < 0.0 &&
      (s.tip - *scene.target - displacement(*scene.target, t)).norm() <= scene.target_tolerance) {
    out.time_to_target = t;
    out.success = true;
  }
  if (scene.biopsy && out.success && !aim_until) aim_until = t + scene.biopsy->aim_time;
  if (aim_until && t >= *aim_until - 1e-9 && open) aimed = true;  // the puncture starts inside the gate's window
  if (out.success && scene.stop_at_target && !scene.biopsy) stopped = true;
  return true;
}

Experiment::Experiment(const ExperimentScene& scene) : m_impl(std::make_unique<Impl>(scene)) {}

Experiment::~Experiment() = default;

bool Experiment::step(const StepRequest& request) {
  if (ended()) throw std::logic_error("Experiment::step: the run has ended");
  m_impl->check(request);  // a bad request changes nothing
  try {
    return m_impl->step(request);
  } catch (...) {
    m_impl->broken = true;  // thrown midway: the magnets, the airway or the body may have moved
    throw;
  }
}

bool Experiment::done() const {
  const Impl& e = *m_impl;
  // The grid index as `magvine run` counts its steps (a driver's own dt leaves it), or the time.
  return ended() || e.stopped || e.grid >= e.scheduled || e.state.time >= e.scene.duration;
}

bool Experiment::ended() const {
  const Impl& e = *m_impl;
  return e.finished || e.broken || !e.out.converged || e.aimed;
}

ExperimentResult Experiment::finish() {
  Impl& e = *m_impl;
  if (e.finished) throw std::logic_error("Experiment::finish: called twice");
  e.finished = true;
  ExperimentResult& out = e.out;
  // The puncture ends a biopsy run that reached its stop (also when the run's duration ended the aiming).
  if (e.aim_until && out.converged) e.puncture();
  if (e.navigator) {
    out.recoveries = e.navigator->recoveries();
    out.guidance = std::move(e.navigator->guidance());
  }
  if (e.arms) {
    out.platform = e.arms->figures();
    out.platform->compute_s = e.platform_seconds;
    out.arm_samples = e.arms->samples();
  }
  for (const robot::GrowthEvent& g : e.growth_events) out.events.push_back(run_event(g));
  out.events.insert(out.events.end(), e.navigator_events.begin(), e.navigator_events.end());
  std::stable_sort(out.events.begin(), out.events.end(),
                   [](const RunEvent& a, const RunEvent& b) { return a.time < b.time; });
  out.final_state = e.state.body;
  out.final_forces = e.state.forces;
  out.runtime_s = e.clock.seconds();
  return std::move(out);
}

double Experiment::time() const {
  return m_impl->state.time;
}
long Experiment::steps() const {
  return m_impl->taken;
}
long Experiment::scheduled_steps() const {
  return m_impl->scheduled;
}
const robot::GrowthState& Experiment::state() const {
  return m_impl->state;
}
double Experiment::pressure() const {
  return m_impl->pressure_now;
}
Vec3 Experiment::tip_at_rest() const {
  return m_impl->at_rest(m_impl->state.body.tip(), m_impl->state.time);
}
double Experiment::everted_length() const {
  return m_impl->workspace.body.length;
}
const std::vector<magnetics::Pose>& Experiment::magnet_poses() const {
  return m_impl->poses;
}
magnetics::FieldSample Experiment::field_at(const Vec3& x) const {
  return m_impl->field ? m_impl->field(x) : magnetics::FieldSample{};
}
const ExperimentResult& Experiment::result() const {
  return m_impl->out;
}
const std::vector<Vec3>& Experiment::airway_vertices() const {
  return m_impl->breathing_world ? m_impl->moved_vertices : m_impl->anatomy.mesh().vertices;
}

ExperimentResult run_experiment(const ExperimentScene& scene, const std::function<void(double)>& progress) {
  Experiment e(scene);
  double reported = 0.0;
  while (!e.done()) {
    if (!e.step()) break;
    reported = std::min(1.0, static_cast<double>(e.steps()) / static_cast<double>(e.scheduled_steps()));
    if (progress) progress(reported);
  }
  ExperimentResult out = e.finish();
  if (progress && out.converged && reported < 1.0) progress(1.0);
  return out;
}

}  // namespace magvine::scene
