#pragma once
/// Growth experiments: a vine grown (or a rod pushed) through anatomy under keyframed control of its pressure, its
/// tether and the magnets' poses, or under the navigator, run by `magvine run` for any scene with an `anatomy:` key.
/// The scene model and its loader: experiment_scene.hpp (format: docs/scenes.md); the navigator: navigator.hpp;
/// trials: trials.hpp; outputs: docs/cli.md (magvine run).

#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "magvine/robot/growth.hpp"
#include "magvine/robot/needle.hpp"
#include "magvine/scene/events.hpp"
#include "magvine/scene/experiment_scene.hpp"
#include "magvine/scene/navigator.hpp"

namespace magvine::scene {

/// One sample of the run, every step.
struct ExperimentSample {
  double time = 0.0;          ///< [s]
  Vec3 tip = Vec3::Zero();    ///< [m]
  double length = 0.0;        ///< everted length [m]
  double pressure = 0.0;      ///< [Pa]
  double max_normal = 0.0;    ///< largest wall normal force on a node [N]
  double max_line_load = 0.0; ///< largest normal force per length of body (robot::WallForces::max_line_load) [N/m]
  double mean_normal = 0.0;   ///< over the nodes in contact [N]
  double total_normal = 0.0;  ///< [N]
  double total_shear = 0.0;   ///< [N]
  double max_pressure = 0.0;  ///< largest contact pressure on the tissue (robot::WallForces::pressure) [Pa]
  int branch = -1;            ///< nearest branch of the phantom's graph to the tip (−1: no graph)
  double centreline = 0.0;    ///< the tip's distance from that branch's centreline [m] (0: no graph)
  /// The global balance of the converged body: |Σ(wall + friction + magnetic + gravity + clamp)| over the largest
  /// of those loads (robot::WallForces::imbalance, largest_load); 0 for a body without loads.
  double imbalance = 0.0;
  /// With anatomy.breathing: the fraction of inspiration (anatomy::inspiration; 1 at full inspiration, the rest
  /// shape); NaN without.
  double inspiration = std::numeric_limits<double>::quiet_NaN();
};

struct MagnetSample {
  double time = 0.0;
  int magnet = 0;
  Vec3 position = Vec3::Zero();
  Vec3 axis = Vec3::UnitZ();
};

/// The body's nodes at a time (outputs.shape_interval).
struct ShapeSample {
  double time = 0.0;                ///< [s]
  std::vector<Vec3> nodes;          ///< clamp first, tip last [m]
  std::vector<double> normal;       ///< wall normal force on the tissue per node [N] (0 off the wall)
  std::vector<double> shear;        ///< wall shear force on the tissue per node [N]
  std::vector<Vec3> normal_vector;  ///< the normal force on the tissue as a vector, per node [N]
  std::vector<Vec3> shear_vector;   ///< the friction force on the tissue as a vector, per node [N]
  std::vector<double> pressure;     ///< the contact pressure on the tissue per node [Pa] (0 off the wall)
};

/// What a video frame needs of the run at one time (recorded when the scene has outputs.video).
struct FrameSample {
  double time = 0.0;                   ///< [s]
  std::vector<Vec3> nodes;             ///< the body, clamp first [m]
  Mat3 tip_frame = Mat3::Identity();   ///< the tip's directors (column 0: tangent)
  std::vector<Vec3> magnet_positions;  ///< [m]
  std::vector<Vec3> magnet_axes;
  std::vector<platform::PlatformRun::Capsule> arm_links;  ///< with a platform: the arms' capsules [m]
  /// During a biopsy's puncture: the needle from the tip to its point [m] (needle_radius 0: no needle).
  Vec3 needle_base = Vec3::Zero();
  Vec3 needle_tip = Vec3::Zero();
  double needle_radius = 0.0;  ///< [m]
};

struct ExperimentResult {
  std::vector<ExperimentSample> samples;
  std::vector<ShapeSample> shapes;           ///< every outputs.shape_interval (opt-in)
  std::vector<FrameSample> frames;           ///< every video frame's time (outputs.video)
  std::vector<MagnetSample> magnet_samples;  ///< at every step where a keyframed magnet moved, and at t = 0
  std::vector<RunEvent> events;              ///< the growth's and the navigator's, in time order
  robot::RodState final_state;
  robot::WallForces final_forces;  ///< on the tissue, per node, at the end
  bool converged = true;           ///< the last step reached equilibrium
  int failed_steps = 0;            ///< steps that did not converge, even in halves: the run ends at the first (0 or 1)
  std::string failure;             ///< that step's cause
  bool success = false;            ///< the tip came within the target's tolerance (false without a target)
  double time_to_target = -1;      ///< [s], −1 when not reached
  int recoveries = 0;              ///< times the navigator backed the vine out of a wrong turn (Navigator::Recovery)
  /// A biopsy scene whose vine reached its stop: the tip's angle to the nodule after aiming [rad], and the puncture.
  double aim_angle = 0.0;
  std::optional<robot::PunctureReport> puncture;
  /// A camera-guided navigator's placements (Navigator::Camera), with the truth beside each.
  std::vector<GuidanceSample> guidance;
  /// With a platform: what the run measured of the arms, and their joints every step (arms.csv).
  std::optional<platform::PlatformFigures> platform;
  std::vector<platform::ArmSample> arm_samples;
  double runtime_s = 0.0;
};

/// What a driver (the Python API's Simulation.step, its NavigationEnv) sets in place of the scene's schedules. Each
/// setting holds from the step that sets it on, until another replaces it; unset, the scene's schedule (or the
/// navigator) decides.
struct StepRequest {
  /// The step [s]; unset: to the next multiple of the scene's dt (as `magvine run` steps; clipped at its duration).
  std::optional<double> dt;
  std::optional<double> pressure;  ///< P [Pa] (replaces control.pressure and the navigator's regulation)
  std::optional<double> tether;    ///< the length the tether has released [m]
  /// A magnet's pose (index into the scene's magnets; position [m], axis unit): replaces its keyframes (with a
  /// platform it is asked of the arm that holds it). A magnet the navigator steers is refused.
  struct Magnet {
    int magnet = 0;
    Vec3 position = Vec3::Zero();
    Vec3 axis = Vec3::UnitZ();
  };
  std::vector<Magnet> magnets;
};

/// An experiment advanced one step at a time (what run_experiment does in a loop; the Python API's Simulation). The
/// scene is borrowed and must outlive it. Not thread-safe; several experiments run in parallel in several threads
/// (the core holds no global state).
class Experiment {
 public:
  /// Starts the run at t = 0 (the body as the growth starts it, the navigator planned, the arms placed).
  explicit Experiment(const ExperimentScene& scene);
  ~Experiment();
  Experiment(const Experiment&) = delete;
  Experiment& operator=(const Experiment&) = delete;

  /// One step under the scene's schedules and the driver's settings. Returns false when the step found no
  /// equilibrium even in halves (result().failure names it; the run has ended). InputError for a bad request (a
  /// non-positive or non-finite dt, a magnet out of range or steered by the navigator, a non-finite value).
  /// std::logic_error once ended().
  bool step(const StepRequest& request = {});
  /// Whether `magvine run` would stop here: the duration reached, the target reached with stop_at_target, a failed
  /// step, or a biopsy's aiming done (finish() then pushes the needle).
  bool done() const;
  /// Whether no step may follow: a failed step, a step that threw, a biopsy's aiming done, or finish() called.
  bool ended() const;
  /// Ends the run (a biopsy's puncture, if the vine reached its stop) and returns its result; the experiment is
  /// spent.
  ExperimentResult finish();

  double time() const;                      ///< [s]
  long steps() const;                       ///< steps taken
  long scheduled_steps() const;             ///< `magvine run`'s: ceil(duration / dt)
  const robot::GrowthState& state() const;  ///< the body, its contact history and its wall forces
  double everted_length() const;            ///< [m]
  double pressure() const;  ///< of the last step (before the first: the starting pressure, halved above burst) [Pa]
  /// The tip taken back to the rest shape of a breathing airway (where the graph, the plan and the target are) [m];
  /// the tip itself without breathing.
  Vec3 tip_at_rest() const;
  const std::vector<magnetics::Pose>& magnet_poses() const;
  /// The field the body reads now at x [T] and its gradient [T/m] (the magnets' at their poses and control.field).
  magnetics::FieldSample field_at(const Vec3& x) const;
  /// The result so far (samples, events, …; finish() completes it).
  const ExperimentResult& result() const;
  /// The airway's vertices as they are now (breathing moves them; otherwise the mesh's) [m].
  const std::vector<Vec3>& airway_vertices() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m_impl;
};

/// Runs the experiment from t = 0 to duration in steps of dt (Experiment, stepped until done()). `progress`
/// (optional) is called with the fraction done after each step.
ExperimentResult run_experiment(const ExperimentScene& scene, const std::function<void(double)>& progress = nullptr);
/// A vine's largest contact pressure over its inflation pressure at that step, over the run's steps (none for a
/// pushed catheter or rod, or a run without steps). A pressurised film presses a flat patch at its own pressure
/// (robot's film_contact_pressure: above it only where a node's force exceeds what half its film facing one wall
/// carries), so a value far above 1 is load the contact's rigid sphere carries that the film at that pressure could
/// not: a wedged node, or a deflated vine under a load (docs/growth-and-contact.md, Known gaps). metrics.json's max_contact_pressure_over_inflation.
std::optional<double> film_overload(const ExperimentScene& scene, const ExperimentResult& result);

/// Writes, atomically, into `dir` (created): metrics.json, tip_trajectory.csv, magnet_trajectory.csv (when the
/// scene has magnets), events.json, shape.csv (the final body), shapes.csv (t_s,node,x_m,y_m,z_m; with
/// outputs.shape_interval) and, with an airway graph (a generated phantom's or anatomy.graph), graph.json (the
/// centreline graph, anatomy/airway_graph.hpp). metrics.json keys: success, time_to_target_s,
/// final_tip_error_m (null without a target), tip_position_m, everted_length_m, tip_path_length_m, branches_reached
/// (graph names in order, with a graph), generation_reached, tip_to_centreline_m (at the end) and
/// mean_tip_to_centreline_m (time average), path_progress (0–1 along the navigator's planned path to its target),
/// max_wall_normal_N, mean_wall_normal_N (time average of the total), max_wall_shear_N (largest total over the
/// steps), max_contact_pressure_Pa (largest on a node over the steps), max_contact_pressure_over_inflation
/// (film_overload; null for a pushed body), stalls, blocked, retractions (the
/// navigator's), events, magnet_travel_m, simulated_s, runtime_s, real_time_factor, converged (the last step),
/// failed_steps, failure, seed, and with outputs.video the videos (tip.mp4 / overview.mp4, or .avi) and
/// "videos": [{camera, file, codec, frames, fps, size}].
void write_experiment_outputs(const ExperimentScene& scene, const ExperimentResult& result,
                              const std::filesystem::path& dir);

}  // namespace magvine::scene
