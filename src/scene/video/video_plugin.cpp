// The video plugin (video_plugin.hpp), libmagvine_video.so: the render module's images and videos for the scene and
// the command line, loaded on demand. Only magvine_video_plugin() is exported.

#include "magvine/scene/video_plugin.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <system_error>
#include <thread>

#include "magvine/anatomy/breathing.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"
#include "magvine/render/lumen.hpp"
#include "magvine/render/particles.hpp"
#include "magvine/render/renderer.hpp"
#include "magvine/render/video.hpp"
#include "magvine/scene/experiment.hpp"

namespace magvine::scene {
namespace {

/// The platform's torso (an elliptic cylinder, translucent like the walls) and table (a box) as overview meshes.
std::vector<render::OverviewMesh> meshes_of(const platform::PlatformModel& p) {
  std::vector<render::OverviewMesh> out;
  const auto box_or_cylinder = [&](const platform::Iso3& frame, double a, double b, double lo, double hi, int sides,
                                   std::array<float, 3> colour, double opacity) {
    render::OverviewMesh m;
    m.colour = colour;
    m.opacity = opacity;
    for (int i = 0; i < sides; ++i) {
      const double phi = 2.0 * kPi * (i + 0.5) / sides;
      const double x = sides == 4 ? std::copysign(a, std::cos(phi)) : a * std::cos(phi);
      const double y = sides == 4 ? std::copysign(b, std::sin(phi)) : b * std::sin(phi);
      m.vertices.push_back(frame * Vec3(x, y, lo));
      m.vertices.push_back(frame * Vec3(x, y, hi));
    }
    const auto n = static_cast<std::uint32_t>(sides);
    const auto c0 = static_cast<std::uint32_t>(m.vertices.size());
    m.vertices.push_back(frame * Vec3(0, 0, lo));
    m.vertices.push_back(frame * Vec3(0, 0, hi));
    for (std::uint32_t i = 0; i < n; ++i) {
      const std::uint32_t j = (i + 1) % n;
      m.triangles.push_back({2 * i, 2 * j, 2 * i + 1});
      m.triangles.push_back({2 * j, 2 * j + 1, 2 * i + 1});
      m.triangles.push_back({c0, 2 * j, 2 * i});
      m.triangles.push_back({c0 + 1, 2 * i + 1, 2 * j + 1});
    }
    out.push_back(std::move(m));
  };
  if (p.body) {
    const platform::TorsoModel& t = *p.body;
    box_or_cylinder(t.frame, 0.5 * t.breadth, 0.5 * t.depth, -0.5 * t.length, 0.5 * t.length, 64, {0.9f, 0.75f, 0.65f},
                    0.15);
  }
  if (p.table) {
    const platform::TableModel& t = *p.table;
    // The box's local z is up; its x across and y along: a 4-sided "cylinder" with corners at ±half.
    box_or_cylinder(t.frame, 0.5 * t.width, 0.5 * t.length, -t.thickness, 0.0, 4, {0.45f, 0.5f, 0.55f}, 1.0);
  }
  return out;
}

namespace fs = std::filesystem;

/// A folder of PNGs written under a temporary name and renamed into place when complete.
class FrameFolder {
 public:
  FrameFolder(const fs::path& dir, const std::string& name)
      : m_final(dir / name), m_temp(dir / ("." + name + ".partial-" + std::to_string(::getpid()))) {
    std::error_code ec;
    fs::remove_all(m_temp, ec);
    create_output_directory(m_temp);
  }
  FrameFolder(const FrameFolder&) = delete;
  FrameFolder& operator=(const FrameFolder&) = delete;
  ~FrameFolder() {
    if (m_done) return;
    std::error_code ec;
    fs::remove_all(m_temp, ec);
  }
  fs::path file(int k) const {
    char name[32];
    std::snprintf(name, sizeof name, "%06d.png", k);
    return m_temp / name;
  }
  const fs::path& temp() const { return m_temp; }
  void commit() {
    std::error_code ec;
    fs::remove_all(m_final, ec);
    fs::rename(m_temp, m_final, ec);
    if (ec) throw InputError(m_final.string(), 0, "", "cannot move the finished frames into place: " + ec.message());
    m_done = true;
  }

 private:
  fs::path m_final;
  fs::path m_temp;
  bool m_done = false;
};

/// Half the side of the tip camera's sensor [m] (the thesis's NanEYE, 1 × 1 mm, 5.6.5).
constexpr double kCameraHalfWidth = 0.5e-3;

/// The tip camera: at the lens, looking along the tip's tangent (directors' column 0), image up its column 1.
render::Camera tip_camera(const Vec3& lens, const Mat3& tip_frame, bool fisheye, double fov, int width, int height) {
  render::Camera c;
  c.position = lens;
  c.forward = tip_frame.col(0);
  c.up = tip_frame.col(1);
  c.lens = fisheye ? render::Lens::kFisheye : render::Lens::kPinhole;
  c.fov = fov;
  c.width = width;
  c.height = height;
  return c;
}

render::Camera tip_camera(const VideoOutput& v, const FrameSample& f) {
  return tip_camera(f.nodes.back(), f.tip_frame, v.fisheye, v.fov, v.width, v.height);
}

std::string experiment_videos(const ExperimentScene& scene, const ExperimentResult& result, const VideoInputs& in,
                              const fs::path& dir) {
  nlohmann::json entries = nlohmann::json::array();
  if (scene.videos.empty() || result.frames.empty())
    return nlohmann::json{{"videos", entries}, {"renderers", 0}}.dump();
  const int threads = static_cast<int>(std::clamp(std::thread::hardware_concurrency(), 1u, 8u));
  render::AirwayRenderer renderer(scene.anatomy->mesh(), threads);
  // A breathing airway (anatomy.breathing) is drawn in its shape at each frame's time: the renderer's vertices moved
  // by the displacement field (each vertex's amplitude kept, the phase once a frame).
  std::vector<double> amplitudes;
  std::vector<Vec3> moved;
  double shape_time = 0.0;  // the time the renderer's shape is at (the rest shape: inspiration 1, t = 0)
  if (scene.breathing) amplitudes = anatomy::breathing_amplitudes(*scene.breathing, scene.anatomy->mesh().vertices);
  const auto shape_at = [&](double t) {
    if (!scene.breathing || t == shape_time) return;
    anatomy::breathing_vertices(*scene.breathing, scene.anatomy->mesh().vertices, amplitudes, t, moved);
    renderer.move(moved);
    shape_time = t;
  };
  create_output_directory(dir);
  const double last = result.frames.back().time;
  const std::vector<render::OverviewMesh> platform_meshes =
      scene.platform ? meshes_of(*scene.platform) : std::vector<render::OverviewMesh>{};

  for (const VideoOutput& v : scene.videos) {
    const bool tip = v.view == VideoOutput::View::kTip;
    render::Camera overview;
    if (!tip) {
      // One camera for the whole video, framing the anatomy and the body wherever it went (a magnet 10 cm out
      // would shrink the airway to a few pixels; it enters the picture where it comes close), from the side away
      // from the magnets so that they stay behind the body.
      const anatomy::Aabb anatomy_box = anatomy::bounding_box(scene.anatomy->mesh());
      anatomy::Aabb box = anatomy_box;
      Vec3 magnets_mean = Vec3::Zero();
      double count = 0.0;
      for (const FrameSample& f : result.frames) {
        for (const Vec3& x : f.nodes) {
          box.min = box.min.cwiseMin(x - Vec3::Constant(scene.vine.radius));
          box.max = box.max.cwiseMax(x + Vec3::Constant(scene.vine.radius));
        }
        for (const Vec3& m : f.magnet_positions) {
          magnets_mean += m;
          count += 1.0;
        }
      }
      if (scene.platform) {
        // The platform's torso in view too (the arms reach beyond it).
        for (const render::OverviewMesh& m : platform_meshes) {
          if (m.opacity >= 1.0) continue;  // the table runs far beyond the body
          for (const Vec3& x : m.vertices) {
            box.min = box.min.cwiseMin(x);
            box.max = box.max.cwiseMax(x);
          }
        }
      }
      auto [from, up] = render::face_on_view(anatomy_box);
      if (count > 0.0 && (magnets_mean / count - 0.5 * (anatomy_box.min + anatomy_box.max)).dot(from) > 0.0) {
        from = -from;
      }
      if (scene.platform && scene.platform->body) {
        // The patient seen from the front and a little to the side, the head up (the table behind).
        const Mat3& torso = scene.platform->body->frame.linear();
        from = (torso.col(1) + 0.5 * torso.col(0)).normalized();
        up = torso.col(2);
      }
      overview =
          render::framing_camera(box, v.from.value_or(from), v.up.value_or(up),
                                 v.fisheye ? render::Lens::kFisheye : render::Lens::kPinhole, v.fov, v.width, v.height);
    }
    render::VideoFile video(dir / v.name(), v.fps, v.width, v.height);
    std::optional<FrameFolder> pngs;
    std::optional<FrameFolder> depths;
    if (v.frames) pngs.emplace(dir, v.name() + "_frames");
    if (v.depth) depths.emplace(dir, v.name() + "_depth");
    render::EndoscopeLook look;
    look.noise = v.noise;
    look.seed = scene.seed;
    render::AutoExposure exposure;
    const double interval = v.speed / v.fps;
    std::size_t j = 0;
    for (int k = 0;; ++k) {
      const double t = k * interval;
      if (t > last + 1e-9) break;
      while (j + 1 < result.frames.size() && result.frames[j].time < t - 1e-9) ++j;
      const FrameSample& f = result.frames[j];
      shape_at(f.time);
      cv::Mat image;
      if (tip) {
        // The needle seen from beside its channel: the 1 mm × 1 mm camera (thesis fig 5.10C) and the needle lie side
        // by side, touching, the needle below the image's centre (the model's needle runs along the tip's axis).
        std::vector<render::OverviewCapsule> tools;
        if (f.needle_radius > 0.0) {
          const Vec3 beside = -(kCameraHalfWidth + f.needle_radius) * f.tip_frame.col(1);
          tools.push_back({f.needle_base + beside, f.needle_tip + beside, f.needle_radius});
        }
        const render::EndoscopeFrame e =
            renderer.render_endoscope(tip_camera(v, f), look, static_cast<std::uint64_t>(k), &exposure, tools);
        image = e.color;
        if (depths) render::write_png(depths->file(k), render::depth_to_u16(e.depth, v.depth_range));
      } else {
        render::OverviewContent content;
        content.body = f.nodes;
        content.body_radius = scene.vine.radius;
        content.target = scene.target;
        content.target_radius = std::max(scene.target_tolerance, 1e-3);
        content.path = in.planned_path;
        if (scene.breathing) {
          // The target and the planned path ride with the airway, as the wall does.
          const auto carried = [&](const Vec3& x) {
            return Vec3(x + anatomy::breathing_displacement(*scene.breathing, x, f.time));
          };
          if (content.target) content.target = carried(*content.target);
          for (Vec3& x : content.path) x = carried(x);
        }
        for (std::size_t i = 0; i < f.magnet_positions.size(); ++i) {
          content.magnets.push_back({f.magnet_positions[i], f.magnet_axes[i],
                                     i < in.magnet_diameters.size() ? in.magnet_diameters[i] : 0.0,
                                     i < in.magnet_lengths.size() ? in.magnet_lengths[i] : 0.0});
        }
        content.meshes = platform_meshes;
        for (const platform::PlatformRun::Capsule& c : f.arm_links) content.capsules.push_back({c.a, c.b, c.radius});
        if (f.needle_radius > 0.0) content.capsules.push_back({f.needle_base, f.needle_tip, f.needle_radius});
        image = renderer.render_overview(overview, content);
      }
      video.write(image);
      if (pngs) render::write_png(pngs->file(k), image);
    }
    const fs::path file = video.finish();
    if (pngs) pngs->commit();
    if (depths) {
      nlohmann::json scale = {{"units", "z-depth along the optical axis; level = depth / range * 65535, 0 = no hit"},
                              {"range_m", v.depth_range},
                              {"metres_per_level", v.depth_range / 65535.0}};
      write_file_atomically(depths->temp() / "depth.json", scale.dump(2) + "\n");
      depths->commit();
    }
    nlohmann::json e = {{"camera", v.name()},     {"file", file.filename().string()},
                        {"codec", video.codec()}, {"frames", video.frames()},
                        {"fps", v.fps},           {"size", {v.width, v.height}}};
    if (v.frames) e["frames_dir"] = v.name() + "_frames";
    if (v.depth) e["depth_dir"] = v.name() + "_depth";
    entries.push_back(e);
  }
  return nlohmann::json{{"videos", entries}, {"renderers", 1}}.dump();
}

fs::path particle_video(const ParticleVideoRequest& r, const fs::path& stem) {
  const render::ParticleView view =
      render::frame_particles(*r.frames, r.view, r.up, static_cast<double>(r.width) / r.height, r.radius);
  render::VideoFile file(stem, r.fps, r.width, r.height);
  for (const std::vector<Vec3>& f : *r.frames) file.write(render::draw_particles(f, *r.body, view, r.width, r.height));
  return file.finish();
}

/// PNG bytes of an 8- or 16-bit image.
std::string encode_png(const cv::Mat& image) {
  return render::encode_png(image, "png");
}

/// The camera of a mesh image, checked: the field of view for the lens, a viewing direction and an up that is not
/// along it (InputError otherwise).
render::Camera camera_of(const MeshImageRequest& r) {
  render::Camera cam;
  cam.position = r.eye;
  cam.forward = r.look - r.eye;
  cam.up = r.up;
  cam.lens = r.fisheye ? render::Lens::kFisheye : render::Lens::kPinhole;
  cam.fov = r.fov;
  cam.width = r.width;
  cam.height = r.height;
  (void)render::focal_pixels(cam);
  (void)render::camera_frame(cam);
  return cam;
}

void check_mesh_image(const MeshImageRequest& r) {
  (void)camera_of(r);
}

EncodedImages mesh_image(const MeshImageRequest& r) {
  const render::Camera cam = camera_of(r);
  const render::AirwayRenderer renderer(*r.mesh, 2);
  EncodedImages out;
  if (r.endoscope) {
    const render::EndoscopeFrame f = renderer.render_endoscope(cam, render::EndoscopeLook{});
    out.hit_fraction = cv::countNonZero(f.depth) / static_cast<double>(f.depth.total());
    out.png = encode_png(f.color);
    if (r.depth) out.depth_png = encode_png(render::depth_to_u16(f.depth, r.depth_range));
  } else {
    out.png = encode_png(renderer.render_overview(cam, render::OverviewContent{}));
  }
  return out;
}

EncodedImages graph_picture(const anatomy::TriangleMesh& mesh, const anatomy::AirwayGraph& graph) {
  const anatomy::Aabb box = anatomy::bounding_box(mesh);
  const Vec3 size = box.max - box.min;
  const auto [axis, up] = render::face_on_view(box);
  const render::Camera cam = render::framing_camera(box, -axis, up, render::Lens::kPinhole, 40.0 * kDegToRad, 800, 800);
  render::OverviewContent content;
  for (const anatomy::AirwayBranch& b : graph.branches) {
    std::vector<Vec3> line;
    for (const std::uint32_t n : b.nodes) line.push_back(graph.nodes[n].position);
    content.lines.push_back(std::move(line));
  }
  content.line_radius = 0.0015 * size.maxCoeff();
  EncodedImages out;
  out.png = encode_png(render::AirwayRenderer(mesh, 2).render_overview(cam, content));
  return out;
}

/// The camera-guided navigator's tip camera (TipEye): the endoscope's view with auto-exposure carried from look to
/// look, as a bronchoscope's exposure loop does, and the lumens found in it.
class LumenEye final : public TipEye {
 public:
  LumenEye(const anatomy::TriangleMesh& mesh, const Navigator::Camera& settings, std::uint64_t seed)
      : m_renderer(mesh, 1), m_settings(settings) {
    m_look.noise = settings.noise;
    m_look.seed = seed;
    m_lumen.min_area = settings.min_area;
  }
  std::vector<SeenLumen> look(const Vec3& lens, const Mat3& tip_frame) override {
    m_camera = tip_camera(lens, tip_frame, true, m_settings.fov, m_settings.size, m_settings.size);
    m_frame = m_renderer.render_endoscope(m_camera, m_look, m_count++, &m_exposure).color;
    m_lumens = render::detect_lumens(m_frame, m_camera, m_lumen);
    const Mat3 frame = render::camera_frame(m_camera);
    std::vector<SeenLumen> out;
    for (const render::Lumen& l : m_lumens) out.push_back({frame * l.direction, l.area});
    return out;
  }
  std::string picture(int chosen) const override {
    return m_frame.empty() ? std::string() : encode_png(render::draw_lumens(m_frame, m_lumens, chosen));
  }
  void move(const std::vector<Vec3>& vertices) override { m_renderer.move(vertices); }

 private:
  render::AirwayRenderer m_renderer;
  Navigator::Camera m_settings;
  render::EndoscopeLook m_look;
  render::LumenSettings m_lumen;
  render::AutoExposure m_exposure;
  render::Camera m_camera;
  std::uint64_t m_count = 0;
  cv::Mat m_frame;
  std::vector<render::Lumen> m_lumens;
};

std::unique_ptr<TipEye> tip_eye(const ExperimentScene& scene) {
  return std::make_unique<LumenEye>(scene.anatomy->mesh(), *scene.navigator->camera, scene.seed);
}

/// Simulation.render's tip camera (TipView): the endoscope's picture, as the videos' tip camera takes it.
class TipPictures final : public TipView {
 public:
  TipPictures(const anatomy::TriangleMesh& mesh, const TipViewSettings& settings)
      : m_renderer(mesh, 1), m_settings(settings) {
    m_look.noise = settings.noise;
    m_look.seed = settings.seed;
  }
  Picture look(const Vec3& lens, const Mat3& tip_frame) override {
    const render::Camera camera =
        tip_camera(lens, tip_frame, m_settings.fisheye, m_settings.fov, m_settings.width, m_settings.height);
    const cv::Mat bgr = m_renderer.render_endoscope(camera, m_look, m_count++, &m_exposure).color;
    cv::Mat rgb;
    cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
    Picture p;
    p.width = rgb.cols;
    p.height = rgb.rows;
    p.rgb.resize(static_cast<std::size_t>(rgb.rows) * static_cast<std::size_t>(rgb.cols) * 3);
    for (int r = 0; r < rgb.rows; ++r) {
      std::memcpy(p.rgb.data() + static_cast<std::size_t>(r) * static_cast<std::size_t>(rgb.cols) * 3, rgb.ptr(r),
                  static_cast<std::size_t>(rgb.cols) * 3);
    }
    return p;
  }
  void move(const std::vector<Vec3>& vertices) override { m_renderer.move(vertices); }

 private:
  render::AirwayRenderer m_renderer;
  TipViewSettings m_settings;
  render::EndoscopeLook m_look;
  render::AutoExposure m_exposure;
  std::uint64_t m_count = 0;
};

std::unique_ptr<TipView> tip_view(const anatomy::TriangleMesh& mesh, const TipViewSettings& settings) {
  return std::make_unique<TipPictures>(mesh, settings);
}

const VideoPlugin kPlugin{VideoPlugin::kAbi, experiment_videos, particle_video, check_mesh_image,
                          mesh_image,        graph_picture,     tip_eye,        tip_view};

}  // namespace
}  // namespace magvine::scene

/// The plugin's one exported symbol (video_plugin.hpp).
extern "C" __attribute__((visibility("default"))) const magvine::scene::VideoPlugin* magvine_video_plugin() {
  return &magvine::scene::kPlugin;
}
