#pragma once
/// The model of a growth experiment (a scene file with an `anatomy:` key), immutable once loaded: the anatomy (built
/// once, with its collision world, and shared by every run, trial and thread that uses the scene), the body, the
/// growth law, the magnets, the control schedules or the navigator's settings, the outputs. The file format is
/// documented once, in docs/scenes.md (experiment scenes); every value is checked when the scene is loaded
/// (docs/scenes.md: validation of inputs), so a run that starts has a valid scene.

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "magvine/anatomy/airway_graph.hpp"
#include "magvine/anatomy/biopsy_plan.hpp"
#include "magvine/anatomy/breathing.hpp"
#include "magvine/anatomy/collision_world.hpp"
#include "magvine/anatomy/triangle_mesh.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/magnetics/magnet_motion.hpp"
#include "magvine/platform/platform.hpp"
#include "magvine/robot/growth.hpp"
#include "magvine/robot/needle.hpp"
#include "magvine/robot/vine.hpp"

namespace magvine::scene {

/// A scalar schedule: linear between keyframes, held beyond the first and last.
struct Schedule {
  std::vector<double> times;   ///< [s], increasing
  std::vector<double> values;  ///< SI
  double at(double time) const;
};

/// A uniform-field schedule (control.field: a coil system, as the thesis's follow-the-leader designs assume): linear
/// between keyframes, held beyond the first and last.
struct FieldSchedule {
  std::vector<double> times;  ///< [s], increasing
  std::vector<Vec3> values;   ///< [T]
  Vec3 at(double time) const;
};

/// One magnet's pose at a time (magnetics/magnet_motion.hpp).
using MagnetKeyframe = magnetics::MagnetKeyframe;

/// The automatic navigator of control.navigator: its settings (navigator.hpp runs it).
struct Navigator {
  std::string target;          ///< branch name
  int target_branch = -1;      ///< its id in the phantom's graph
  int magnet = 0;              ///< index in magnets:
  double distance = 0.11;      ///< [m]
  double min_distance = 0.10;  ///< [m]
  double max_distance = 0.30;  ///< [m]
  double lead = 0.015;         ///< [m]
  double interval = 0.1;       ///< [s]
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
  /// Camera guidance (control.navigator.guidance: {mode: camera}; docs/experiments.md, camera guidance): the magnet's
  /// line comes from the lumens the tip camera shows (render/lumen.hpp), chosen with the plan; the tip's place along
  /// the plan is dead reckoning from the everted length, its orientation read as from a sensor in the tip. The
  /// navigator never reads the tip's position (the oracle's mode, without it, does). In a breathing airway it reads
  /// the respiratory phase and knows the breathing model: its dead reckoning and the plan's directions are taken in
  /// the airway's shape at the look, and its magnet rides with the model where it takes the tip to be.
  struct Camera {
    int size = 160;                   ///< the image's side [px]
    double fov = 2.0943951023931953;  ///< equidistant fisheye, across the width [rad] (120°)
    double noise = 0.0;               ///< sensor noise σ [8-bit grey levels]
    double min_area = 0.002;          ///< smallest lumen, fraction of the image
    double junction_window = 20e-3;   ///< [m] (below)
    bool frames = false;              ///< annotated frames of each choice between lumens (guidance/*.png)
  };
  std::optional<Camera> camera;
  /// Gating to the breathing phase (control.navigator.gate; a scene with anatomy.breathing): the navigator places
  /// its magnet and regulates only while inspiration(t) lies in [from, to] (e.g. [0, 0.2]: near exhalation, where
  /// Lujan's profile rests); outside, the tether holds the everted length and the magnet rides with the airway. A
  /// biopsy's puncture starts inside the window (unless the duration ends first).
  struct Gate {
    double from = 0.0;
    double to = 1.0;
    bool open(double inspiration) const { return inspiration >= from && inspiration <= to; }
  };
  std::optional<Gate> gate;
};

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

/// One outputs.video entry (docs/scenes.md: videos). Angles [rad], lengths [m].
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

/// The anatomy of an experiment: a generated phantom or an imported mesh, its airway graph, and the collision world
/// built on it. Immutable; shared (std::shared_ptr) by every copy of the scene, so trials on many threads query one
/// world (its queries are const and thread-safe).
struct SceneAnatomy {
  std::string label;                          ///< "phantom y_bifurcation" or the mesh path (for messages)
  std::optional<anatomy::AirwayGraph> graph;  ///< a generated phantom's, or anatomy.graph's
  bool closed = false;            ///< the mesh is closed (generated, or watertight): inside/outside is defined
  anatomy::CollisionWorld world;  ///< contacts, rays, inside/outside

  /// The airway wall [m] (the world's copy).
  const anatomy::TriangleMesh& mesh() const { return world.mesh(); }
};

/// Anatomies already built, keyed by what the scene's `anatomy:` entry asks for (the phantom kind and parameters, or
/// the mesh's path, units and graph), so that loading many scenes over one anatomy (variants of a scene, a test that
/// loads a scene hundreds of times) builds it once. Explicit: pass one to the loader to share; thread-safe.
class AnatomyCache {
 public:
  /// The anatomy for `key`, built by `build` the first time.
  template <class Build>
  std::shared_ptr<const SceneAnatomy> get(const std::string& key, const Build& build) {
    {
      const std::lock_guard lock(m_mutex);
      if (const auto it = m_built.find(key); it != m_built.end()) return it->second;
    }
    std::shared_ptr<const SceneAnatomy> built = build();
    const std::lock_guard lock(m_mutex);
    return m_built.emplace(key, std::move(built)).first->second;
  }

 private:
  std::mutex m_mutex;
  std::map<std::string, std::shared_ptr<const SceneAnatomy>> m_built;
};

/// A biopsy (control.navigator.target: {nodule, radius, max_needle, max_angle, needle}; docs/ct.md): the navigator
/// takes the vine to the planned stop; then for `aim_time` its magnet, on the line from the tip to the nodule, aims
/// the tip while the vine grows on towards the nodule (until the wall ahead blocks it); then the needle is pushed out
/// of the tip with the tether held (robot/needle.hpp) and the run ends.
struct Biopsy {
  Vec3 nodule = Vec3::Zero();  ///< its centre [m]
  double radius = 5e-3;        ///< [m]
  anatomy::BiopsyPlan plan;
  std::optional<Vec3> given_stop;  ///< target.stop, when given: the plan's stop is its nearest reachable node [m]
  robot::NeedleTool needle;
  double aim_time = 2.0;  ///< [s]
};

struct ExperimentScene {
  std::string file;                             ///< the scene file (for messages)
  std::shared_ptr<const SceneAnatomy> anatomy;  ///< never null in a loaded scene
  robot::VineParameters vine;  ///< the vine (a pushed rod: its inserted length and radius; growth.rod the rod)
  Vec3 base_position = Vec3::Zero();
  Mat3 base_frame = Mat3::Identity();
  robot::GrowthOptions growth;
  std::optional<magnetics::FieldModel> magnets;
  std::vector<std::vector<MagnetKeyframe>> magnet_keyframes;  ///< per source of `magnets`; empty: its rest pose
  Schedule pressure;                                          ///< [Pa]
  std::optional<Schedule> tether;                             ///< [m]
  std::optional<FieldSchedule> uniform_field;                 ///< control.field, added to the magnets' field
  std::optional<Navigator> navigator;
  double duration = 0.0;       ///< [s]
  double dt = 0.02;            ///< [s]
  std::optional<Vec3> target;  ///< [m]
  /// control.navigator.target: {nodule: ...}: the nodule, the planned stop (the target above) and the needle.
  std::optional<Biopsy> biopsy;
  /// anatomy.breathing: the airway moves (anatomy/breathing.hpp); the run refits its own copy of the collision world
  /// every step, and the nodule, the target and the navigator's path move with it.
  std::optional<anatomy::BreathingParams> breathing;
  double target_tolerance = 0.0;         ///< [m]
  bool stop_at_target = true;            ///< end the run when the target is reached (simulation.stop_at_target)
  TrialPerturbation perturbation;        ///< for `magvine trials`
  Vec3 navigator_offset = Vec3::Zero();  ///< a trial's placement error added to the navigator's poses [m]
  std::uint64_t seed = 0;
  double shape_interval = 0.0;      ///< outputs.shape_interval [s]: the body every so often in shapes.csv; 0: off
  std::vector<VideoOutput> videos;  ///< outputs.video
  /// The patient, table and arms (platform:, docs/platform.md); null: the magnets float free where they are put.
  std::shared_ptr<const platform::PlatformModel> platform;
};

/// Whether a scene file is an experiment (has `anatomy:`) rather than a free-space scene. InputError for an
/// unreadable or malformed file.
bool is_experiment_scene(const std::filesystem::path& file);

/// Loads and checks an experiment scene: InputError (one line: file, line, key, what is wrong) for anything a run
/// would trip over, including a base or target outside the lumen and a magnet overlapping the anatomy. `cache`
/// (optional) shares anatomies between loads.
ExperimentScene load_experiment_scene(const std::filesystem::path& file, AnatomyCache* cache = nullptr);
/// The same from text; `directory`: where relative paths (mesh:, graph:) are resolved.
ExperimentScene parse_experiment_scene(const std::string& text, const std::string& file_label,
                                       const std::filesystem::path& directory, AnatomyCache* cache = nullptr);

}  // namespace magvine::scene
