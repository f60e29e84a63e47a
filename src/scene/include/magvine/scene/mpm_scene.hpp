#pragma once
/// MPM scenes (`mpm:` section; built only with MAGVINE_WITH_MPM): soft magnetic bodies of any shape sampled into
/// particles, an applied field (uniform, keyframed or rotating) and/or permanent magnets, obstacles, clamps and
/// probes. `magvine mpm SCENE.yaml --out DIR` runs one; docs/scenes.md documents the keys.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "magvine/magnetics/field_model.hpp"
#include "magvine/magnetics/magnet_motion.hpp"
#include "magvine/mpm/mpm.hpp"

namespace magvine::scene {

/// The applied uniform field of an MPM scene (magnetics/magnet_motion.hpp: keyframed or rotating).
using MpmFieldSchedule = magnetics::UniformFieldSchedule;

/// A point followed through the run: the mean of the particles that start within `radius` of it.
struct MpmProbe {
  std::string name;
  Vec3 at = Vec3::Zero();  ///< [m]
  std::vector<std::uint32_t> particles;
};

/// A particle video (`mpm.video`; written when the render module is built).
struct MpmVideo {
  Vec3 view = -Vec3::UnitY();  ///< looking along this direction
  Vec3 up = Vec3::UnitZ();
  int width = 640, height = 480;
  double fps = 30.0;
  double speed = 0.1;  ///< simulated seconds per second of video
};

/// A loaded MPM scene, SI units; the model holds every particle.
struct MpmScene {
  std::string file;
  int dimension = 3;
  mpm::MpmModel<2> model2;              ///< used when dimension == 2
  mpm::MpmModel<3> model3;              ///< used when dimension == 3
  std::vector<Vec3> positions;          ///< initial particle positions [m] (z = 0 in 2D)
  std::vector<std::string> body_names;  ///< per body; model.section holds the body index
  double time_step = 0.0;               ///< [s]
  double stable_step = 0.0;             ///< the explicit step's bound courant·δx/c_P [s]
  bool implicit = false;                ///< implicit steps (mpm::implicit_step), halved where one fails
  bool total_lagrangian = false;        ///< mpm.frame: total — the total-Lagrangian steps (mpm/total_lagrangian.hpp)
  mpm::ImplicitSettings newton;         ///< for implicit steps
  double duration = 0.0;                ///< [s]
  double settle_window = 0.0;           ///< > 0: stop once every probe moved less than settle_tolerance over this [s]
  double settle_tolerance = 0.0;        ///< [m]
  double snapshot_interval = 0.0;       ///< [s] between PLY snapshots; 0: the first and last only
  MpmFieldSchedule field;
  std::optional<magnetics::FieldModel> magnets;  ///< static permanent magnets (exact cylinder or dipole)
  std::vector<MpmProbe> probes;
  std::optional<MpmVideo> video;
};

/// Parses and validates (InputError naming the file, line and key for anything wrong; meshes relative to the scene).
MpmScene load_mpm_scene(const std::filesystem::path& file);
MpmScene parse_mpm_scene(const std::string& text, const std::string& file_label,
                         const std::filesystem::path& base_dir = {});
/// True when the file has a top-level `mpm:` key.
bool is_mpm_scene(const std::filesystem::path& file);

/// One probe sample.
struct MpmSample {
  double time = 0.0;
  std::vector<Vec3> probes;  ///< [m]
  double kinetic_energy = 0.0;
};

struct MpmResult {
  bool ok = true;
  std::string failure;  ///< the step's cause when !ok
  bool settled = false;
  long steps = 0;
  long newton = 0;    ///< implicit steps: Newton iterations over the run
  long cg = 0;        ///< implicit steps: conjugate-gradient iterations (Hessian products) over the run
  long retries = 0;   ///< implicit steps: steps taken again at half the step after a failure
  double time = 0.0;  ///< simulated [s]
  double runtime_s = 0.0;
  std::vector<MpmSample> samples;
  /// Particle positions at the snapshot times [m] (first: t = 0, last: the end).
  std::vector<std::pair<double, std::vector<Vec3>>> snapshots;
  /// Particle positions at the video's frame times [m] (with `video`).
  std::vector<std::vector<Vec3>> frames;
};

/// Runs the scene; `progress(fraction)` is called now and then.
MpmResult run_mpm_scene(const MpmScene& scene, const std::function<void(double)>& progress = {});

/// Writes DIR/metrics.json, DIR/probes.csv, DIR/snapshots/NNNN.ply (positions in mm) and, with a video and the
/// render module, DIR/particles.mp4 (or .avi); atomically per file.
void write_mpm_outputs(const MpmScene& scene, const MpmResult& result, const std::filesystem::path& dir);

}  // namespace magvine::scene
