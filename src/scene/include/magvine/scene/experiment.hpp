#pragma once
/// Growth experiments (issue 6, first part): a vine grown through anatomy under keyframed control of its pressure,
/// its tether and the magnets' poses, run by `magvine run` for any scene file with an `anatomy:` key.
///
/// ```yaml
/// units: {length: mm, pressure: kPa}       # as in free_space.hpp; times in seconds
/// anatomy:                                  # one of:
///   phantom: {kind: y_bifurcation}          #   a generated phantom (bronchial_tree, tube, y_bifurcation, s_bend,
///                                           #   constriction) at its default parameters; bronchial_tree also takes
///                                           #   max_generation
///   # mesh: airway.stl                      #   or a mesh file (any format assimp reads), relative to this file,
///   # mesh_units: mm                        #   in mm | cm | m (default: units.length)
///   # graph: extract                        #   its airway graph (navigator, branch metrics): extracted from the
///   # graph_root: [0, 20, 30]               #   mesh (anatomy/centerline.hpp; root near this point, default the
///                                           #   widest end), or a graph JSON file (anatomy/airway_graph.hpp)
/// robot:                                    # a vine as in free_space.hpp; length = the everted length at t = 0
///   kind: vine
///   ...
/// growth:                                   # optional (robot/growth.hpp); defaults in brackets
///   mode: eversion                          # eversion | pushed
///   yield_pressure: 5                       # Y0 [5 kPa], pressure units
///   length_yield: 0.012                     # c_L [12 kPa/m], pressure units per length unit
///   turning_yield: 1                        # c_θ [1 kPa/rad], pressure units per radian
///   extensibility: 2                        # K [2 µm/(s·Pa)], in µm/(s·Pa)
///   friction: 0.3                           # Coulomb μ against the wall
///   edge_length: 2.5                        # h [the radius], length units
///   max_incidence: 73.3                     # steepest wall the tip slides along [atan(1/friction)], degrees
/// magnets:                                  # optional, as in the magnets file; poses at t = 0
///   - {kind: cylinder, diameter: 101.6, length: 101.6, polarisation: 1.48, position: [60, -150, 0], axis: [0, 1, 0]}
/// control:
///   pressure: [[0, 35], [20, 35]]           # keyframes [time, pressure]: linear between, held beyond the ends;
///                                           # none: robot.pressure (or the pressure commands)
///   tether: [[0, 5], [20, 105]]             # optional keyframes [time, released length]; none: free growth
///   magnets:                                # optional, per magnet (index in magnets:), poses at times
///     - {magnet: 0, keyframes: [{time: 0, position: [60, -150, 0], axis: [0, 1, 0]}, {time: 10, ...}]}
///   # navigator: {target: "0-1", magnet: 0, distance: 110}   # or: steer a magnet automatically (below)
///   # commands:                             # or a gamepad script (like the thesis's), in time order; each does one
///   #   - {time: 2, move: [0, 20, 0]}       # thing, ramped over `over` seconds [0.5]: move a magnet (index
///   #   - {time: 3, rotate: {axis: [0, 0, 1], angle: 90}}   # `magnet` [0]) by a vector, turn its axis about a
///   #   - {time: 4, pressure: -6}           # world axis [degrees], step the pressure up/down (from
///   #   - {time: 5, over: 4, grow: 20}      # robot.pressure), release the tether (from the initial length)
/// simulation: {duration: 20, dt: 0.02, gravity: [0, 0, -9.81]}   # duration and step [s]; gravity [m/s²];
///                                                                  # stop_at_target: true (default) ends the run
///                                                                  # when the target is reached
/// target: {position: [100, -20, 0], tolerance: 5}                 # optional: success when the tip is within it
/// outputs:                                 # optional
///   shape_interval: 0.5                     #   the body's nodes every 0.5 s in shapes.csv (off by default)
///   video: {camera: tip}                    #   a video of the run (render module), or a list of them; below
/// ```
/// Videos (`outputs.video`, one map or a list; a build without the render module checks the keys, warns and
/// writes everything else, with "videos_skipped" in metrics.json): `camera: tip` films the
/// endoscope view from the tip along its tangent (image up: the tip's first director), `camera: overview` a
/// third-person view of the semi-transparent anatomy with the body, the magnets (north half red, an arrow along
/// the magnetisation), the target and the planned path. Keys, defaults in brackets: `size` [[320, 320] tip,
/// [640, 480] overview] px; `fov` [110 tip, 40 overview] degrees across the width; `lens` [fisheye tip, pinhole
/// overview] fisheye | pinhole; `fps` [30] frames per second of video; `speed` [1] simulated seconds per second of
/// video (a frame every speed/fps simulated seconds, the first at t = 0); `frames` [false] also every frame as
/// PNG; `depth` [false] (tip) the z-depth of every frame as a 16-bit PNG, level = depth / depth_range · 65535
/// (`depth_range` [100] length units; C3VD's scale); `noise` [0] sensor noise σ in grey levels, seeded by `seed`;
/// `from`, `up` (overview) the viewing direction towards the camera and the image's up [along the anatomy's
/// thinnest extent]. Files: tip.mp4 (or tip.avi where OpenCV has no MP4 writer), overview.mp4, tip_frames/,
/// tip_depth/ (with depth.json giving the scale); listed in metrics.json under "videos".
///
/// Magnet poses between keyframes: positions linear, axes turned along the great circle (slerp); held beyond the
/// ends.
///
/// Navigator (`control.navigator`; it plans on the airway graph: a generated phantom's, or anatomy.graph's): the path of branches from the
/// root to `target` (a branch name, or a point [x, y, z] snapped to the nearest centreline: its branch, and success
/// within 1.5 lumen radii of the snapped point), its centrelines joined into one polyline; every `interval` seconds (default 0.1)
/// the aim point is `lead` (default 15 mm) along that polyline past the tip's nearest point on it (the target's end
/// at most), so the turn after a short branch is aimed at before the tip gets there. The magnet is placed on the line from the tip through the aim point,
/// `distance` from the tip (clamped to min_distance–max_distance, default 100–300 mm: the EPM stays outside the
/// patient; moved further out along that line while it would overlap the airway mesh), its axis along that line (for a magnetic skin, turned so that the field at the tip runs along the skin's moment:
/// gradient mode, thesis 4.7.1): the tip then sits on the magnet's axis, where a magnetic-fluid fill is pulled
/// hardest towards it (gradient pull; skins get gradient mode, below; torque mode is not automated). Its success: the tip within
/// 1.5 lumen radii of the target branch's end (unless `target:` gives a point). Placement checks (InputError): a
/// magnet overlapping the anatomy at rest or at a keyframe (at load); a base or target outside the lumen of closed
/// anatomy (when the run starts). Unknown keys are errors naming the closest valid one (exit 2), and every problem names the file, line and
/// key. Paths are relative to the scene file.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "magvine/anatomy/airway_graph.hpp"
#include "magvine/anatomy/triangle_mesh.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/robot/growth.hpp"
#include "magvine/robot/vine.hpp"

namespace magvine::scene {

/// A scalar schedule: linear between keyframes, held beyond the first and last.
struct Schedule {
  std::vector<double> times;   ///< [s], increasing
  std::vector<double> values;  ///< SI
  double at(double time) const;
};

/// One magnet's pose at a time.
struct MagnetKeyframe {
  double time = 0.0;
  Vec3 position = Vec3::Zero();  ///< [m]
  Vec3 axis = Vec3::UnitZ();     ///< unit: the magnetisation axis (the source's local z)
};

/// The automatic navigator of control.navigator.
struct Navigator {
  std::string target;             ///< branch name
  int target_branch = -1;         ///< its id in the phantom's graph
  int magnet = 0;                 ///< index in magnets:
  double distance = 0.11;         ///< [m]
  double min_distance = 0.10;     ///< [m]
  double max_distance = 0.30;     ///< [m]
  double lead = 0.015;            ///< [m]
  double interval = 0.1;          ///< [s]
  /// Pressure regulation for skin vines (thesis 4.7.3): when the tip comes within junction_distance of a junction on
  /// the path (each once), the pressure is held at most deflate_pressure [Pa] for deflate_time [s] while the magnet
  /// bends the body towards the next branch. 0: off.
  double deflate_pressure = 0.0;
  /// How much of the aim direction's component along the tip's tangent the magnet's line leaves out: 0 the line
  /// through the aim point (a fluid's pull), 1 straight across the tip towards the aim's side (what creases a
  /// deflated skin vine towards the next branch).
  double lateral = 0.0;
  /// How the magnet bends a magnetic skin (thesis 4.7.1): gradient (its field at the tip along the skin's moment m:
  /// pulled towards the magnet, no torque) or torque (its field across m, along ω' × m, where ω' is the axis that
  /// turns the tip towards the aim with the part along m taken out: m × B then bends the tip towards the aim; where
  /// that part is most of the turn, as when the next branch turns about m itself, gradient mode for that step).
  enum class SkinMode { kGradient, kTorque };
  SkinMode skin_mode = SkinMode::kGradient;
  double deflate_time = 2.0;        ///< [s]
  double junction_distance = 0.01;  ///< [m]
  /// Pressure regulation for a blocked tip: when the vine has not grown for boost_after [s], with no tether or made
  /// length holding it (the tip held at a
  /// junction's entry, where bending into the branch stores more energy than the growth force does work), the
  /// pressure is raised to at least boost_pressure [Pa] until the tip has grown boost_length [m] further; the growth
  /// force (P − Y)·πR² rises faster with P than the crease moment πR³P does. 0: off.
  double boost_pressure = 0.0;
  double boost_after = 0.5;    ///< [s]
  double boost_length = 5e-3;  ///< [m]
  /// Recovery from a wrong turn (control.navigator.recover; retries 0: off). When the tip has grown `past` [m] into
  /// a branch off the planned path, or has been held for `after` [s] (a boost included), the navigator deflates the
  /// vine to the growth's retraction_pressure and pulls the tether back at `speed` [m/s] until the everted length is
  /// `back` [m] short of where the tip left the path (held: of where it is), then gives the pressure back and lets it
  /// grow again, at most `retries` times a run. The retraction is tip-driven (growth.retraction_pressure): a deflated
  /// vine whose tip inverts, as with a tip retraction device; the thesis pulled its deflated vines out whole (its 5.7).
  struct Recovery {
    int retries = 0;
    double past = 4e-3;    ///< [m]
    double after = 2.0;    ///< [s]
    double back = 20e-3;   ///< [m]
    double speed = 20e-3;  ///< [m/s]
  };
  Recovery recover;
};

/// The navigator's pose for its magnet (experiment runs call it every `interval`): `path` is the planned centreline
/// as one polyline; the aim point lies `lead` along it past the tip's nearest point on it (so a short branch does
/// not hide the turn after it); the magnet sits `distance` from the tip on the line towards the aim (less the
/// `lateral` share of its component along the tangent) plus `offset`, its axis along that line for a fill, or set
/// by `skin_mode` for a magnetic skin whose moment is `skin` in the body frame. `line` returns that unit line.
MagnetKeyframe navigate(const Navigator& nav, const std::vector<Vec3>& path, const Vec3& tip, const Mat3& tip_frame,
                        const std::optional<Vec3>& skin, double time, const Vec3& offset, Vec3& line);

/// Seeded perturbations of `magvine trials` (the scene's optional `trials:` section; each trial draws its own
/// normal deviates once, from the scene's seed, the target and the repeat number): the magnets' placement is off by
/// a constant offset (each coordinate σ = magnet_position_sd, default 2 mm: a robot arm's and a registration's
/// error), the pressure by a constant (σ = pressure_sd, default 0.5 kPa: a regulator's), the film's modulus and the
/// growth law's yield by a factor (σ = material_spread, default 5 %: batch to batch). A pushed rod: its moduli by
/// that factor, and no pressure.
struct TrialPerturbation {
  double magnet_position_sd = 2e-3;  ///< [m]
  double pressure_sd = 0.5e3;        ///< [Pa]
  double material_spread = 0.05;     ///< relative
};

/// One outputs.video entry (above). Angles [rad], lengths [m].
struct VideoOutput {
  enum class View { kTip, kOverview };
  View view = View::kTip;
  int width = 320;
  int height = 320;
  double fov = 1.9198621771937625;  ///< 110°
  bool fisheye = true;
  double fps = 30.0;
  double speed = 1.0;        ///< simulated seconds per second of video
  bool frames = false;       ///< PNG of every frame
  bool depth = false;        ///< tip: 16-bit depth PNGs
  double depth_range = 0.1;  ///< [m] at level 65535
  double noise = 0.0;        ///< grey levels
  std::optional<Vec3> from;  ///< overview: towards the camera
  std::optional<Vec3> up;    ///< overview: image up
  std::string name() const { return view == View::kTip ? "tip" : "overview"; }
};

struct ExperimentScene {
  std::string file;                 ///< the scene file (for messages)
  std::string anatomy_label;        ///< "phantom y_bifurcation" or the mesh path
  anatomy::TriangleMesh mesh;       ///< [m]
  std::optional<anatomy::AirwayGraph> graph;  ///< ground-truth graph of a generated phantom
  robot::VineParameters vine;
  Vec3 base_position = Vec3::Zero();
  Mat3 base_frame = Mat3::Identity();
  robot::GrowthOptions growth;
  std::optional<magnetics::FieldModel> magnets;
  std::vector<std::vector<MagnetKeyframe>> magnet_keyframes;  ///< per source of `magnets`; empty: its rest pose
  Schedule pressure;                ///< [Pa]
  std::optional<Schedule> tether;   ///< [m]
  std::optional<Navigator> navigator;
  double duration = 0.0;            ///< [s]
  double dt = 0.02;                 ///< [s]
  std::optional<Vec3> target;       ///< [m]
  double target_tolerance = 0.0;    ///< [m]
  bool stop_at_target = true;       ///< end the run when the target is reached (simulation.stop_at_target)
  TrialPerturbation perturbation;   ///< for `magvine trials`
  Vec3 navigator_offset = Vec3::Zero();  ///< a trial's placement error added to the navigator's poses [m]
  std::uint64_t seed = 0;
  double shape_interval = 0.0;      ///< outputs.shape_interval [s]: the body every so often in shapes.csv; 0: off
  std::vector<VideoOutput> videos;  ///< outputs.video
  bool closed_anatomy = false;      ///< the mesh is closed (generated, or watertight): inside/outside is defined
  int target_line = 0;              ///< lines of target: and robot.base: in the file (for messages)
  int base_line = 0;
};

/// Whether a scene file is an experiment (has `anatomy:`) rather than a free-space scene. InputError for an
/// unreadable or malformed file.
bool is_experiment_scene(const std::filesystem::path& file);

ExperimentScene load_experiment_scene(const std::filesystem::path& file);
/// `directory`: where relative paths (mesh:) are resolved.
ExperimentScene parse_experiment_scene(const std::string& text, const std::string& file_label,
                                       const std::filesystem::path& directory);

/// One sample of the run, every step.
struct ExperimentSample {
  double time = 0.0;           ///< [s]
  Vec3 tip = Vec3::Zero();     ///< [m]
  double length = 0.0;         ///< everted length [m]
  double pressure = 0.0;       ///< [Pa]
  double max_normal = 0.0;     ///< largest wall normal force on a node [N]
  double mean_normal = 0.0;    ///< over the nodes in contact [N]
  double total_normal = 0.0;   ///< [N]
  double total_shear = 0.0;    ///< [N]
  int branch = -1;             ///< nearest branch of the phantom's graph to the tip (−1: no graph)
  bool unsettled = false;      ///< its wall forces are not an equilibrium (robot::WallForces::unsettled)
};

struct MagnetSample {
  double time = 0.0;
  int magnet = 0;
  Vec3 position = Vec3::Zero();
  Vec3 axis = Vec3::UnitZ();
};

/// The body's nodes at a time (outputs.shape_interval).
struct ShapeSample {
  double time = 0.0;         ///< [s]
  std::vector<Vec3> nodes;   ///< clamp first, tip last [m]
  std::vector<double> normal;  ///< wall normal force on the tissue per node [N] (0 off the wall)
  std::vector<double> shear;   ///< wall shear force on the tissue per node [N]
};

/// What a video frame needs of the run at one time (recorded when the scene has outputs.video).
struct FrameSample {
  double time = 0.0;               ///< [s]
  std::vector<Vec3> nodes;         ///< the body, clamp first [m]
  Mat3 tip_frame = Mat3::Identity();  ///< the tip's directors (column 0: tangent)
  std::vector<Vec3> magnet_positions;  ///< [m]
  std::vector<Vec3> magnet_axes;
};

struct ExperimentResult {
  std::vector<ExperimentSample> samples;
  std::vector<ShapeSample> shapes;  ///< every outputs.shape_interval (opt-in)
  std::vector<FrameSample> frames;  ///< every video frame's time (outputs.video)
  std::vector<MagnetSample> magnet_samples;  ///< at every step where a keyframed magnet moved, and at t = 0
  std::vector<robot::GrowthEvent> events;
  robot::RodState final_state;
  robot::WallForces final_forces;  ///< on the tissue, per node, at the end
  bool converged = true;       ///< the last step reached equilibrium
  int failed_steps = 0;        ///< steps whose new loads did not converge (the body kept its last equilibrium)
  std::string failure;         ///< the first such step's cause
  bool success = false;        ///< the tip came within the target's tolerance (false without a target)
  double time_to_target = -1;  ///< [s], −1 when not reached
  int recoveries = 0;          ///< times the navigator backed the vine out of a wrong turn (Navigator::Recovery)
  double runtime_s = 0.0;
};

/// Runs the experiment from t = 0 to duration in steps of dt. `progress` (optional) is called with the fraction
/// done after each step.
ExperimentResult run_experiment(const ExperimentScene& scene,
                                const std::function<void(double)>& progress = nullptr);

/// The steps whose wall forces are not an equilibrium (ExperimentSample::unsettled): how many, and the largest normal
/// force on a node among them [N]. metrics.json, trials.csv and `magvine run` report these apart from the maxima.
struct UnsettledSteps {
  int count = 0;
  double max_normal = 0.0;
};
UnsettledSteps unsettled_steps(const ExperimentResult& result);

/// The scene with its navigator aimed at branch `target` (its end the target point). InputError when the scene has no
/// navigator or no such branch.
ExperimentScene with_target(const ExperimentScene& scene, const std::string& target);

/// The scene perturbed for one trial (TrialPerturbation), deterministic in `seed`.
ExperimentScene perturbed(const ExperimentScene& scene, std::uint64_t seed);

struct TrialOutcome {
  std::string target;
  int repeat = 0;
  std::uint64_t seed = 0;
  bool success = false;
  bool burst = false;            ///< the perturbed pressure burst the vine
  double time_to_target = -1.0;  ///< [s]
  double everted_length = 0.0;   ///< [m]
  double final_error = 0.0;      ///< tip to target [m]
  double max_normal = 0.0;       ///< [N], over the steps whose contacts settled
  UnsettledSteps unsettled;      ///< the steps left out of max_normal
  int retractions = 0;           ///< the navigator's (ExperimentResult::recoveries)
  double runtime_s = 0.0;
  /// Why a failed trial failed, one line: the last event that stopped the tip (with its numbers), the branch it was
  /// in, how far from the target it ended and after how many retractions; empty on success.
  std::string reason;
};

/// Runs `repeats` perturbed trials towards each target (branch names; empty: the scene's own target) on `jobs`
/// threads; outcomes in (target, repeat) order whatever the threads. `progress` gets (done, total). With `runs_dir`,
/// each trial's own outputs (write_experiment_outputs, without videos) go to runs_dir/<target>_r<repeat>: its events,
/// trajectories and metrics, to see why a trial failed.
std::vector<TrialOutcome> run_trials(const ExperimentScene& scene, const std::vector<std::string>& targets,
                                     int repeats, int jobs, const std::function<void(int, int)>& progress = nullptr,
                                     const std::filesystem::path& runs_dir = {});

/// trials.csv (every trial, with the reason of each failure) and summary.csv + summary.md in the form of thesis
/// table 5.2 (target, path length = the everted length at the target [mm], success rate, mean time to target and its
/// SD [s], over the successes; summary.md lists the failures with their reasons below the table), atomically into
/// `dir`.
void write_trial_outputs(const std::vector<TrialOutcome>& outcomes, const std::filesystem::path& dir);

/// Writes, atomically, into `dir` (created): metrics.json, tip_trajectory.csv, magnet_trajectory.csv (when the
/// scene has magnets), events.json, shape.csv (the final body), shapes.csv (t_s,node,x_m,y_m,z_m; with
/// outputs.shape_interval) and, with an airway graph (a generated phantom's or anatomy.graph), graph.json (the
/// centreline graph, anatomy/airway_graph.hpp). metrics.json keys: success, time_to_target_s,
/// final_tip_error_m (null without a target), tip_position_m, everted_length_m, tip_path_length_m, branches_reached
/// (graph names in order, with a graph), generation_reached, tip_to_centreline_m (at the end) and
/// mean_tip_to_centreline_m (time average), path_progress (0–1 along the navigator's planned path to its target),
/// max_wall_normal_N, mean_wall_normal_N (time average of the total), max_wall_shear_N (largest total over the
/// steps), stalls, blocked, retractions (the navigator's), events, magnet_travel_m, simulated_s, runtime_s,
/// real_time_factor, converged (the last step), failed_steps, failure, seed, and with outputs.video the videos
/// (tip.mp4 / overview.mp4, or .avi) and "videos": [{camera, file, codec, frames, fps, size}].
void write_experiment_outputs(const ExperimentScene& scene, const ExperimentResult& result,
                              const std::filesystem::path& dir);

}  // namespace magvine::scene
