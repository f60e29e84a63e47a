#pragma once
/// The optional image and video writers (the render module: Embree ray casting of the airway, OpenCV images and
/// video files), built as a plugin, libmagvine_video.so, with MAGVINE_WITH_RENDER and loaded only by the runs and
/// verbs that write images or video: magvine starts without the codec stack (FFmpeg and its libraries), and a build
/// or a machine without the plugin runs every other verb. The plugin renders and encodes; files are written
/// atomically (videos by the plugin, images by the host).

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "magvine/anatomy/airway_graph.hpp"
#include "magvine/anatomy/triangle_mesh.hpp"
#include "magvine/core/eigen_types.hpp"

namespace magvine::scene {

struct ExperimentScene;
struct ExperimentResult;

/// What an experiment's overview shows that the scene and the result do not hold directly.
struct VideoInputs {
  std::vector<Vec3> planned_path;        ///< the navigator's [m]; empty without one
  std::vector<double> magnet_diameters;  ///< per magnet [m]; 0: a point dipole
  std::vector<double> magnet_lengths;    ///< [m]
};

/// A particle video (an MPM scene's mpm.video): one framing for all frames.
struct ParticleVideoRequest {
  Vec3 view = -Vec3::UnitY();  ///< looking along this direction
  Vec3 up = Vec3::UnitZ();
  int width = 640;
  int height = 480;
  double fps = 30.0;
  double radius = 0.0;                                     ///< the particles' disc radius [m]
  const std::vector<std::vector<Vec3>>* frames = nullptr;  ///< positions per frame [m]
  const std::vector<std::uint16_t>* body = nullptr;        ///< body of each particle (colour)
};

/// One image of a mesh (`magvine render`): the endoscope view (and its depth) or the overview.
struct MeshImageRequest {
  const anatomy::TriangleMesh* mesh = nullptr;  ///< [m]
  Vec3 eye = Vec3::Zero();                      ///< [m]
  Vec3 look = Vec3::UnitX();                    ///< [m]
  Vec3 up = Vec3::UnitZ();
  bool endoscope = true;
  bool fisheye = true;
  double fov = 0.0;  ///< across the width [rad]
  int width = 320;
  int height = 320;
  double depth_range = 0.1;  ///< [m] at level 65535 (endoscope)
  bool depth = false;        ///< also the 16-bit depth map
};

/// An encoded image and what the host reports of it.
struct EncodedImages {
  std::string png;            ///< the image, PNG bytes
  std::string depth_png;      ///< the depth map, 16-bit PNG bytes (when asked for)
  double hit_fraction = 1.0;  ///< of the endoscope's rays that hit the wall
};

/// A dark opening the tip camera shows (render/lumen.hpp): its ray in the world (from the camera's orientation) and
/// its share of the picture.
struct SeenLumen {
  Vec3 direction = Vec3::UnitX();  ///< unit, world frame
  double area = 0.0;               ///< fraction of the image
};

/// The tip camera of a camera-guided navigator (Navigator::Camera): renders the endoscope's view from a lens pose
/// and finds the lumens in it. Frames are numbered from 0 in the order looked (the sensor noise's seed).
class TipEye {
 public:
  virtual ~TipEye() = default;
  /// The lumens seen from `lens` with the tip's directors `tip_frame` (column 0 the optical axis, column 1 image up),
  /// largest first.
  virtual std::vector<SeenLumen> look(const Vec3& lens, const Mat3& tip_frame) = 0;
  /// The last frame looked with its lumens drawn, `chosen` (index into look's answer, −1: none) in green: PNG bytes.
  virtual std::string picture(int chosen) const = 0;
  /// Moves the airway's vertices (breathing; same count and order as the mesh's): later looks see it there.
  virtual void move(const std::vector<Vec3>& vertices) = 0;
};

/// An RGB image: height rows of width pixels, 3 bytes each (red, green, blue), top row first.
struct Picture {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgb;
};

/// What the tip camera of the Python API's Simulation.render is: the endoscope's lens and image.
struct TipViewSettings {
  bool fisheye = true;
  double fov = 2.0;  ///< across the width [rad]
  int width = 160;
  int height = 160;
  double noise = 0.0;      ///< sensor noise σ [grey levels]
  std::uint64_t seed = 0;  ///< the noise's
};

/// The endoscope's view from the tip, its renderer (the airway's ray-casting BVH) and auto-exposure kept from picture
/// to picture. Pictures are numbered from 0 in the order taken (the noise's seed).
class TipView {
 public:
  virtual ~TipView() = default;
  /// The picture from `lens` with the tip's directors `tip_frame` (column 0 the optical axis, column 1 image up).
  virtual Picture look(const Vec3& lens, const Mat3& tip_frame) = 0;
  /// Moves the airway's vertices (breathing; same count and order as the mesh's).
  virtual void move(const std::vector<Vec3>& vertices) = 0;
};

/// The plugin's entry points (C++ types; the plugin is built from this tree with the same compiler).
struct VideoPlugin {
  static constexpr int kAbi = 5;
  int abi = kAbi;
  /// Renders every video of scene.videos from result.frames into `dir` (each file, and each PNG folder, appears
  /// complete or not at all). Returns JSON text {"videos": [{camera, file, codec, frames, fps, size}, ...],
  /// "renderers": n}: metrics.json's entries and how many renderers it built (the plugin keeps its own copy of the
  /// usage counters; the host notes them).
  std::string (*experiment_videos)(const ExperimentScene& scene, const ExperimentResult& result,
                                   const VideoInputs& inputs, const std::filesystem::path& dir) = nullptr;
  /// Writes `stem`.mp4 (or .avi); returns the file.
  std::filesystem::path (*particle_video)(const ParticleVideoRequest& request,
                                          const std::filesystem::path& stem) = nullptr;
  /// Checks a mesh image's camera (field of view for the lens, viewing direction, up) before the mesh is read:
  /// InputError naming what is wrong.
  void (*check_mesh_image)(const MeshImageRequest& request) = nullptr;
  /// One image of a mesh (its camera checked as check_mesh_image does).
  EncodedImages (*mesh_image)(const MeshImageRequest& request) = nullptr;
  /// A picture of an airway graph over its semi-transparent mesh (800 × 800, face-on).
  EncodedImages (*graph_picture)(const anatomy::TriangleMesh& mesh, const anatomy::AirwayGraph& graph) = nullptr;
  /// The tip camera of scene.navigator's camera guidance, on the scene's airway mesh.
  std::unique_ptr<TipEye> (*tip_eye)(const ExperimentScene& scene) = nullptr;
  /// A tip camera on `mesh` (borrowed: it must outlive the view).
  std::unique_ptr<TipView> (*tip_view)(const anatomy::TriangleMesh& mesh, const TipViewSettings& settings) = nullptr;
};

/// Whether this magvine was built with the render module (and so has the plugin).
bool video_plugin_built();

/// For a run that asks for video (`wanted`): loads the plugin before the run, so that a build that has it but
/// cannot load it fails with an InputError (exit 2) before anything is written. Returns whether the videos will be
/// made: false when this build has no render module (the run then skips them, as its metrics.json says).
bool preload_video_plugin(bool wanted, const std::string& what);

/// The plugin, loaded on first use (thread-safe) from $MAGVINE_VIDEO_PLUGIN, else libmagvine_video.so beside the
/// executable, else the build tree's. InputError naming what is missing when this build has no render module or the
/// library cannot be loaded; `what` says who asked (e.g. "outputs.video").
const VideoPlugin& video_plugin(const std::string& what);

}  // namespace magvine::scene
