#pragma once
/// The automatic navigator of an experiment (control.navigator; docs/experiments.md): one controller with its own
/// state that places its magnet from the tip and the planned path, and regulates the pressure and the tether for a
/// held tip (boost), at junctions (deflation) and out of wrong turns (recovery).

#include <array>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "magvine/core/eigen_types.hpp"
#include "magvine/platform/platform.hpp"
#include "magvine/robot/growth.hpp"
#include "magvine/scene/events.hpp"
#include "magvine/scene/experiment_scene.hpp"
#include "magvine/scene/video_plugin.hpp"

namespace magvine::scene {

/// The navigator's pose for its magnet: `path` is the planned centreline as one polyline; the aim point lies `lead`
/// along it past the tip's nearest point on it (so a short branch does not hide the turn after it); the magnet sits
/// `distance` from the tip on the line towards the aim (less the `lateral` share of its component along the tangent)
/// plus `offset`, its axis along that line for a fill, or set by `skin_mode` for a magnetic skin whose moment is
/// `skin` in the body frame. `line` returns that unit line.
MagnetKeyframe navigate(const Navigator& nav, const std::vector<Vec3>& path, const Vec3& tip, const Mat3& tip_frame,
                        const std::optional<Vec3>& skin, double time, const Vec3& offset, Vec3& line);

/// The planned path to branch `branch` as one polyline: the centrelines of the branches from the root joined [m].
std::vector<Vec3> planned_path(const anatomy::AirwayGraph& graph, int branch);

/// The planned path's lumen radius at each point of planned_path(graph, branch) (the graph's node radii) [m].
std::vector<double> planned_radii(const anatomy::AirwayGraph& graph, int branch);

/// `path` drawn taut inside its lumen: each interior point moved to the middle of its neighbours, kept within
/// `clearance[i]` of where it was (clearance has one entry per point), sweep after sweep until no point moves 1 µm
/// in a sweep (or `max_sweeps`); the ends stay. These are Gauss–Seidel sweeps on Σ|p_i+1 − p_i|² under those
/// bounds, whose minimiser is a string drawn tight through the balls the lumen leaves a body, its points evened out
/// along it: the centreline's wiggles inside a wide lumen (an airway graph's skeleton at a junction) drop out, and a
/// bend is cut only as far as the clearance lets the string go. The stop bounds the last sweep's step, not the
/// distance to the minimiser: a long free stretch contracts slowly (200 points over 100 mm wiggling ±2 mm inside 6 mm
/// stop after 540 sweeps up to 2 mm from it, the length within 0.1 mm). Camera guidance measures its dead reckoning
/// along it.
std::vector<Vec3> taut_path(const std::vector<Vec3>& path, const std::vector<double>& clearance,
                            int max_sweeps = 20000);

/// Arc length [m] along a polyline of its nearest point to x.
double arc_length_of_nearest(const std::vector<Vec3>& path, const Vec3& x);
/// How far along `path` the tip has got towards the target, 0–1: the arc lengths of their nearest points on it, in
/// ratio (metrics.json's path_progress; 1 for a target at the path's start).
double path_progress(const std::vector<Vec3>& path, const Vec3& target, const Vec3& tip);
/// The path to a scene's target: the navigator's plan, or without a navigator the path to the graph's branch nearest
/// the target; empty without a graph or a target.
std::vector<Vec3> target_path(const ExperimentScene& scene);
/// The point of a polyline at arc length s from its start [m] (its ends beyond [0, length]).
Vec3 point_at_arc_length(const std::vector<Vec3>& path, double s);

/// One placement of a camera-guided navigator (Navigator::Camera): what it saw and what it chose.
struct GuidanceSample {
  double time = 0.0;          ///< [s]
  double length = 0.0;        ///< everted [m]
  double arc = 0.0;           ///< its estimate of the tip's arc length along the plan [m]
  int lumens = 0;             ///< seen
  int chosen = -1;            ///< the lumen it steered for (index in what it saw); −1: none, it steered by the plan
  int junction = -1;          ///< the junction on the plan the choice was about (0: the first), −1: none ahead
  Vec3 line = Vec3::UnitX();  ///< the magnet's line from the tip, world
  // The truth, for the report: the experiment fills these in; the navigator never reads them.
  double true_arc = 0.0;    ///< the tip's arc length along the plan [m]
  double line_error = 0.0;  ///< angle between `line` and the oracle's line from the true tip [rad]
  std::string picture;      ///< the frame with its lumens drawn (PNG; Camera::frames, when it chose between several)
};

/// The navigator of one run. Each step: `place` (before the magnets' poses are updated), then `regulate` (after the
/// schedules set the control, before the growth advances).
class NavigatorController {
 public:
  /// `scene` must have a navigator (and so an airway graph and magnets); borrowed, it must outlive the controller.
  /// Places the magnet from the straight body's tip.
  explicit NavigatorController(const ExperimentScene& scene);

  /// Re-places the magnet at time t when an interval has passed, from the tip of the last equilibrium; moves it out
  /// along its line while it overlaps the anatomy (a "workspace" event, once, when even max_distance overlaps).
  void place(double t, const Vec3& tip, const Mat3& tip_frame, double length, std::vector<RunEvent>& events);

  /// Regulates `control` at time t: `length` the everted length, `branch` the last sample's branch (−1: none yet),
  /// `reached` whether the target has been reached. Boost for a held tip, deflation at a junction on the path,
  /// recovery from a wrong turn or a long hold ("recover" events).
  void regulate(double t, double length, int branch, bool reached, const Vec3& tip, robot::GrowthControl& control,
                std::vector<RunEvent>& events);

  /// A gated step outside its window (Navigator::Gate): nothing is regulated, and the time held does not count
  /// towards a boost or a recovery.
  void pause(double t, double length);

  /// The planned path (the plan's centrelines joined) [m].
  const std::vector<Vec3>& path() const { return m_path; }

  /// Places its magnet through an arm of the platform from now on (when an arm holds it): each placement then
  /// chooses among the lines round its ideal one the best that the arm reaches clear of the patient (a feasible
  /// placement, docs/platform.md) and sets the arm's goal. Places it now, from the tip at time t.
  void use_platform(platform::PlatformRun* run, double t, const Vec3& tip, const Mat3& tip_frame, double length,
                    std::vector<RunEvent>& events);

  /// Camera guidance (scene.navigator->camera): `look` shows it the tip camera's lumens (the experiment renders the
  /// view from where the tip is; the navigator sees only the lumens). From then on each placement steers from them,
  /// and place() and regulate() read the tip's orientation and the everted length, never the tip's position.
  void use_camera(std::function<std::vector<SeenLumen>()> look);
  /// Every camera-guided placement so far.
  std::vector<GuidanceSample>& guidance() { return m_guidance; }
  const std::vector<GuidanceSample>& guidance() const { return m_guidance; }
  /// The oracle's line from `tip` (navigate's), for the report of a camera-guided run.
  Vec3 oracle_line(const Vec3& tip, const Mat3& tip_frame) const;
  /// Where it takes the tip to be with `length` everted [m], in the plan's (rest) frame: camera-guided, the point
  /// its dead reckoning puts on the plan (in the airway as it is at airway_at's time); otherwise nullopt (the oracle
  /// reads the tip).
  std::optional<Vec3> estimated_tip(double length) const;
  /// The time of the airway's shape the body lies in now (a breathing airway; the experiment sets it each step
  /// before place and regulate): camera guidance's dead reckoning and the plan's directions are taken in that shape.
  void airway_at(double time);

  /// Whether it places magnet `magnet` (its own, or with a platform the other arm's of a dEPM pair).
  bool steers(int magnet) const;

  /// The magnet it steers (index in magnets:) and its current pose.
  int magnet() const { return m_nav.magnet; }
  const MagnetKeyframe& pose() const { return m_pose; }
  /// Times it backed the vine out (Navigator::Recovery).
  int recoveries() const { return m_recovery_used; }

 private:
  bool keep_clear(const Vec3& tip);
  void next_placement_after(double t);
  /// Camera guidance: the tip's arc length along the plan (its rest frame) by dead reckoning: the everted length laid
  /// from the base along the plan drawn taut in its lumen (as the breathing model has moved it at m_airway_time where
  /// the airway breathes), the point there taken back to the plan segment by segment; and the branch of the plan
  /// there.
  double estimated_arc(double length) const;
  int estimated_branch(double length) const;
  /// A rest-frame point where the breathing model has it at m_airway_time (the point itself without breathing).
  Vec3 moved(const Vec3& x) const;
  /// The unit direction from rest-frame point ab[0] to ab[1] as the airway is at m_airway_time.
  Vec3 moved_direction(const std::array<Vec3, 2>& ab) const { return (moved(ab[1]) - moved(ab[0])).normalized(); }
  /// Camera guidance's placement: the magnet's line from the lumens seen.
  void place_by_camera(double t, const Mat3& tip_frame, double length);
  /// A magnet it places through an arm, and where the arm has it.
  struct HeldMagnet {
    int arm = -1;
    int magnet = -1;
    bool placed = false;                         ///< the arm has had a placement
    MagnetKeyframe placement;                    ///< its last placement (the arm's goal)
    std::array<double, 3> shell{0.0, 0.0, 0.0};  ///< where round the torso: angle [rad], level [m], stand-off [m]
    Vec3 side = Vec3::Zero();                    ///< with two arms, its side of the patient (placements keep to it)
    bool warned = false;
    magnetics::FieldModel own;  ///< its magnet alone (the pull of a placement)
    /// Shell points already found (a fill's: they depend on the place alone), keyed by angle, level and stand-off
    /// in units of 1e-4 (rad, m).
    std::map<std::tuple<long, long, long>, std::optional<Vec3>> shell_cache;
  };
  void place_with_arm(HeldMagnet& h, double t, const Vec3& tip, const Mat3& tip_frame, double length,
                      std::vector<RunEvent>& events);
  /// The pull of h's magnet at `pose` on a saturated fill at the tip, along `towards`: ∇|B|·towards [T/m].
  double pull(const HeldMagnet& h, const MagnetKeyframe& pose, const Vec3& tip, const Vec3& towards) const;
  void recover(double t, double length, int branch, robot::GrowthControl& control, std::vector<RunEvent>& events);

  const ExperimentScene& m_scene;
  const Navigator& m_nav;
  std::vector<int> m_plan;                      ///< branches from the root to the target
  std::vector<Vec3> m_path;                     ///< their centrelines joined
  std::optional<Vec3> m_skin;                   ///< a magnetic skin's moment direction, body frame (skin modes)
  MagnetKeyframe m_pose;                        ///< the magnet's current pose (asked of the arm, with a platform)
  platform::PlatformRun* m_platform = nullptr;  ///< the arms, when one holds its magnet
  std::vector<HeldMagnet> m_held;               ///< its magnet's arm first, then (dEPM) the other
  Vec3 m_line = Vec3::UnitX();                  ///< the line from the tip it was placed on
  double m_next_placement = 0.0;                ///< [s]
  bool m_workspace_warned = false;
  // Held tip (boost and recovery): the everted length and when it last changed.
  double m_grown_at = 0.0;
  double m_grown_length = -1.0;
  double m_boost_until = -1.0;     ///< boosting until the everted length reaches this [m] (< 0: not boosting)
  std::vector<int> m_deflated_at;  ///< branches whose end junction the vine was deflated for
  double m_deflate_until = -1.0;   ///< [s]
  // Recovery (Navigator::Recovery).
  double m_shortest = 0.0;  ///< the vine's starting length: no retraction goes below it [m]
  double m_on_path = 0.0;   ///< the everted length at the last sample on the path [m]
  bool m_retracting = false;
  double m_from = 0.0;         ///< the retraction: from this length [m]
  double m_to = 0.0;           ///< to this length [m]
  double m_since = 0.0;        ///< since this time [s]
  double m_last = 0.0;         ///< the everted length at the last step of the retraction [m]
  double m_last_tether = 0.0;  ///< and the tether it set then [m]
  int m_recovery_used = 0;
  // Camera guidance.
  std::function<std::vector<SeenLumen>()> m_look;  ///< set: camera-guided
  std::vector<Vec3> m_reckon;                      ///< the dead reckoning's path: m_path drawn taut (taut_path)
  double m_base_arc = 0.0;                         ///< the base's arc length along m_reckon [m]
  double m_airway_time = 0.0;                      ///< airway_at's [s]
  std::vector<double> m_reckon_amplitudes;         ///< breathing amplitudes of m_reckon's points [m]
  /// Camera guidance in a breathing airway: m_reckon moved to m_airway_time, and the base's arc along it [m] (set
  /// by airway_at and use_camera, read by estimated_arc).
  std::vector<Vec3> m_moved_reckon;
  double m_moved_base_arc = 0.0;
  /// The plan's junctions: arc length along the plan [m], and the planned child's and its siblings' first points
  /// with the points `lead` into each (rest frame; the directions between them are taken as the airway is at the
  /// look).
  struct Junction {
    double arc = 0.0;
    std::array<Vec3, 2> planned{Vec3::Zero(), Vec3::Zero()};
    std::vector<std::array<Vec3, 2>> others;
  };
  std::vector<Junction> m_junctions;
  std::vector<double> m_branch_end;  ///< arc length along the plan at each plan branch's end [m]
  std::vector<GuidanceSample> m_guidance;
};

}  // namespace magvine::scene
