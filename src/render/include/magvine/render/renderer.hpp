#pragma once
/// CPU ray-cast rendering of an airway (Embree; Wald et al., ACM TOG 33(4) 143, 2014): the endoscope's view from a
/// tip camera, with its depth as ground truth, and a third-person overview of the anatomy with the robot, the
/// magnets, the target and the planned path.
///
/// Endoscope shading (../shared/reference/render-and-vine-physics.md A1; the light sits at the lens, so the light
/// and view directions coincide): for a ray d hitting the wall at range t with normal n,
///   cos_i = |n·d|,  E = spot(ψ) / (t² + t0²),  spot(ψ) = cos^μ ψ (ψ: the ray's angle to the optical axis),
///   radiance = E (ρ cos_i / π + k_s cos_i^s)        (Lambert + a tight specular glint of wet mucosa)
///   pixel = (gain · (1 − a r²) · radiance)^(1/γ)     (r: distance from the image centre over half the diagonal)
/// The gain is fixed or set by auto-exposure (the 95th percentile of luminance maps to `exposure_target`, eased
/// from frame to frame as a bronchoscope's exposure loop does). Optional Gaussian sensor noise, seeded.

#include <array>
#include <cstdint>
#include <memory>
#include <opencv2/core/mat.hpp>
#include <optional>
#include <span>
#include <utility>
#include <vector>

#include "magvine/anatomy/triangle_mesh.hpp"
#include "magvine/render/camera.hpp"

namespace magvine::render {

/// How the endoscope sees the wall (defaults: pink-red mucosa under a tip LED).
struct EndoscopeLook {
  Vec3 albedo{0.80, 0.45, 0.40};  ///< ρ, linear RGB
  double specular = 0.35;         ///< k_s
  double shininess = 40.0;        ///< s: tighter glints when larger
  double spot_exponent = 2.0;     ///< μ of the light's cos^μ profile
  double light_softening = 1e-3;  ///< t0 [m]: keeps a wall touching the lens finite
  double vignetting = 0.35;       ///< a: the corners get 1 − a of the centre's light
  double gamma = 2.2;
  double exposure = 0.0;          ///< fixed gain; 0: auto-exposure
  double exposure_target = 0.85;  ///< auto-exposure puts the 95th percentile of luminance here (before gamma)
  double texture = 0.12;          ///< relative amplitude of the mucosa's procedural mottling (0: plain)
  double noise = 0.0;             ///< sensor noise σ in 8-bit grey levels (0: none)
  std::uint64_t seed = 0;         ///< noise seed (with the frame number)
};

/// Auto-exposure state carried from frame to frame of a video.
struct AutoExposure {
  double gain = 0.0;    ///< the last frame's gain; 0: none yet (the first frame takes its own at once)
  double easing = 0.5;  ///< fraction of the way (in log gain) to the new frame's ideal gain
};

/// One endoscope frame.
struct EndoscopeFrame {
  cv::Mat color;      ///< CV_8UC3, BGR (OpenCV's order)
  cv::Mat depth;      ///< CV_32F, z-depth along the optical axis [m]; 0 where the ray hits nothing
  double gain = 0.0;  ///< the exposure gain used
};

/// What the overview shows besides the anatomy.
struct OverviewMagnet {
  Vec3 position = Vec3::Zero();  ///< centre [m]
  Vec3 axis = Vec3::UnitZ();     ///< magnetisation (north) direction
  double diameter = 0.0;         ///< [m]; 0 (a point dipole): drawn as a 20 mm ball
  double length = 0.0;           ///< [m]
};

/// A triangle mesh in the overview (the platform's torso and table): drawn with its opacity, below 1 composited like
/// the walls.
struct OverviewMesh {
  std::vector<Vec3> vertices;  ///< [m]
  std::vector<std::array<std::uint32_t, 3>> triangles;
  std::array<float, 3> colour{0.8f, 0.8f, 0.8f};  ///< linear RGB
  double opacity = 1.0;                           ///< per surface crossed
};

/// A capsule (a robot arm's link), grey.
struct OverviewCapsule {
  Vec3 a = Vec3::Zero();  ///< [m]
  Vec3 b = Vec3::Zero();  ///< [m]
  double radius = 0.0;    ///< [m]
};

/// The nearest t > 0 at which the ray o + t·d (d unit) enters the capsule of points within `radius` of the segment
/// [a, b], with the outward unit normal there; nullopt when it misses or starts inside (o within `radius` of the
/// segment). The capsule is the union of a cylinder and two balls, so its entry is the first of theirs: the
/// cylinder's root from |(x − a) × u|² = r² (u the unit axis) where it lands between the ends, and each ball's
/// |x − c|² = r².
std::optional<std::pair<double, Vec3>> ray_capsule(const Vec3& o, const Vec3& d, const OverviewCapsule& capsule);

/// How a tool looks in the endoscope: brushed steel, linear RGB albedo and a broad glint.
struct ToolLook {
  Vec3 albedo{0.55, 0.56, 0.60};
  double specular = 0.6;
  double shininess = 12.0;
};

struct OverviewContent {
  std::vector<Vec3> body;       ///< the robot's centreline, base first [m]
  double body_radius = 2.5e-3;  ///< [m]
  std::vector<OverviewMagnet> magnets;
  std::optional<Vec3> target;             ///< [m]
  double target_radius = 2e-3;            ///< [m]
  std::vector<Vec3> path;                 ///< the planned path [m]
  std::vector<std::vector<Vec3>> lines;   ///< more polylines [m] (an airway graph's branches), dark orange
  double line_radius = 0.5e-3;            ///< [m]
  std::vector<OverviewMesh> meshes;       ///< the patient's torso (translucent), the table
  std::vector<OverviewCapsule> capsules;  ///< the arms' links, a biopsy needle
};

struct OverviewLook {
  double anatomy_opacity = 0.3;         ///< per wall layer the ray crosses
  int max_layers = 4;                   ///< wall layers composited before the rest counts as hidden
  cv::Vec3b background{250, 250, 250};  ///< BGR
};

/// Renders one anatomy mesh from any camera. Building it builds Embree's BVH of the mesh (once); rendering is
/// read-only, so one renderer serves any number of frames. `threads` ≥ 1 share each frame's rows.
class AirwayRenderer {
 public:
  explicit AirwayRenderer(const anatomy::TriangleMesh& mesh, int threads = 1);
  ~AirwayRenderer();
  AirwayRenderer(const AirwayRenderer&) = delete;
  AirwayRenderer& operator=(const AirwayRenderer&) = delete;

  /// The endoscope's view. `frame_index` seeds the noise with look.seed; `exposure` (optional) carries the
  /// auto-exposure from frame to frame. `tools` are capsules in view (a biopsy needle out of the tool channel), drawn
  /// in steel (`ToolLook`) under the same light, and in the depth map; the lens must lie outside them. InputError for a
  /// bad camera or look, or a lens inside a tool.
  EndoscopeFrame render_endoscope(const Camera& camera, const EndoscopeLook& look, std::uint64_t frame_index = 0,
                                  AutoExposure* exposure = nullptr, std::span<const OverviewCapsule> tools = {}) const;

  /// Third-person view: the anatomy's walls semi-transparent (each crossing composited at look.anatomy_opacity), the
  /// robot's body (light blue), each magnet (north half red, south half blue, an arrow along its axis), the target
  /// (green ball) and the planned path (yellow). Headlight shading. CV_8UC3, BGR.
  cv::Mat render_overview(const Camera& camera, const OverviewContent& content,
                          const OverviewLook& look = OverviewLook{}) const;

  /// Moves the airway's vertices (as many as the mesh has, same triangles; a breathing airway's shape at a frame's
  /// time): the vertex normals follow, and Embree refits its tree (built on the first shape) instead of rebuilding
  /// it. Not thread-safe against renders running at the same time. InputError for a wrong count or a non-finite
  /// vertex.
  void move(std::span<const Vec3> vertices);

  std::size_t triangle_count() const;
  int threads() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m_impl;
};

/// The overview's default viewing axis for anatomy in `box`: its thinnest extent (a tree lying in a plane is seen
/// face on), as {axis towards the camera (+ side; the caller may flip it), image up: z, or y when z is the thinnest}.
std::pair<Vec3, Vec3> face_on_view(const anatomy::Aabb& box);

/// A camera that frames `box` (grown by 5 %) seen from direction `from` (towards the camera), up `up`.
Camera framing_camera(const anatomy::Aabb& box, const Vec3& from, const Vec3& up, Lens lens, double fov, int width,
                      int height);

}  // namespace magvine::render
