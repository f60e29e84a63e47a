// Rendering (issue 7): the tip camera's 320 × 320 endoscope frame and the 640 × 480 overview of a ~200k-triangle
// airway — the CT airway lidc0525 (195k triangles) when ../shared/airways is there, else a generated tube of the
// same size — and the renderer choice, measured on the same view:
//   /tip/...        the full endoscope frame (Embree packets of 8 rays, shading, exposure, gamma), 1 thread
//   /overview/...   the third-person view (single rays through up to 4 semi-transparent wall layers)
//   /visibility/... (views 0: down the trachea, 1: a tip 1 mm from the wall looking 30° towards it) what each candidate renderer spends on visibility alone for the pinhole view (depth per pixel):
//                   embree_packet8 (what the renderer uses), embree_single (rtcIntersect1 per pixel), and
//                   raster (a z-buffer rasteriser with perspective-correct depth, written here only for this
//                   comparison). Counter `depth_mismatch`: the fraction of pixels whose depth differs from the
//                   packet ray cast's by more than 1 % (a rasteriser without near-plane clipping drops the
//                   triangles that cross the lens plane: the wall next to the lens goes missing).
// Targets (issue 7): tip ≥ 60 frames/s on one core, overview ≥ 20 frames/s.
//
//   cmake --build build-bench --target bench_render && build-bench/tests/bench/bench_render

#include <benchmark/benchmark.h>
#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/core.hpp>
#include <vector>

#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/primitives.hpp"
#include "magvine/core/units.hpp"
#include "magvine/render/renderer.hpp"
#include "support/airways.hpp"

namespace {

using namespace magvine;
using namespace magvine::render;

struct Airway {
  anatomy::TriangleMesh mesh;
  Camera tip;  ///< inside the trachea, looking down it
  std::string label;
};

const Airway& airway() {
  static const Airway a = [] {
    Airway out;
    if (const auto path = test::airway_file("lidc0525_medmpd_p5_airway_mc.stl")) {
      out.mesh = anatomy::import_mesh(*path).mesh;
      out.label = "lidc0525";
      // The trachea is the top (+z, superior) of the tree: the centre of the top 2 cm of vertices, 25 mm down.
      const anatomy::Aabb box = anatomy::bounding_box(out.mesh);
      Vec3 sum = Vec3::Zero();
      double n = 0.0;
      for (const Vec3& v : out.mesh.vertices) {
        if (v.z() > box.max.z() - 0.02) {
          sum += v;
          n += 1.0;
        }
      }
      out.tip.position = sum / n - Vec3(0.0, 0.0, 0.025);
      out.tip.forward = -Vec3::UnitZ();
      out.tip.up = Vec3::UnitY();
    } else {
      out.mesh = anatomy::make_tube({.radius = 9e-3, .length = 0.1, .segments = 256, .rings = 400, .capped = true});
      out.label = "tube (airway absent)";
      out.tip.position = Vec3(0.0, 0.0, 0.02);
      out.tip.forward = Vec3::UnitZ();
      out.tip.up = Vec3::UnitY();
    }
    out.tip.width = out.tip.height = 320;
    out.tip.fov = 110.0 * kDegToRad;
    return out;
  }();
  return a;
}

const AirwayRenderer& renderer() {
  static const AirwayRenderer r(airway().mesh, 1);
  return r;
}

void BM_Tip(benchmark::State& state, Lens lens) {
  Camera cam = airway().tip;
  cam.lens = lens;
  const AirwayRenderer& r = renderer();
  double hit = 0.0;
  for (auto _ : state) {
    const EndoscopeFrame f = r.render_endoscope(cam, EndoscopeLook{});
    hit = cv::countNonZero(f.depth) / static_cast<double>(f.depth.total());
    benchmark::DoNotOptimize(f.color.data);
  }
  state.counters["fps"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["hit_fraction"] = hit;
  state.counters["triangles"] = static_cast<double>(r.triangle_count());
  state.SetLabel(airway().label);
}
BENCHMARK_CAPTURE(BM_Tip, fisheye, Lens::kFisheye)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Tip, pinhole, Lens::kPinhole)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_Overview(benchmark::State& state) {
  const AirwayRenderer& r = renderer();
  const anatomy::Aabb box = anatomy::bounding_box(airway().mesh);
  const Camera cam = framing_camera(box, Vec3(0.0, -1.0, 0.0), Vec3::UnitZ(), Lens::kPinhole, 40.0 * kDegToRad, 640, 480);
  OverviewContent content;
  const Vec3 a = airway().tip.position;
  for (int i = 0; i <= 40; ++i) content.body.push_back(a + airway().tip.forward * (0.002 * i));
  content.target = content.body.back();
  content.path = content.body;
  content.magnets.push_back({a + Vec3(0.0, -0.12, -0.05), Vec3::UnitY(), 0.1016, 0.1016});
  for (auto _ : state) {
    const cv::Mat img = r.render_overview(cam, content);
    benchmark::DoNotOptimize(img.data);
  }
  state.counters["fps"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.SetLabel(airway().label);
}
BENCHMARK(BM_Overview)->Unit(benchmark::kMillisecond)->UseRealTime();

// ---- Visibility only: the renderer candidates on the pinhole tip view ----

/// The pinhole tip camera's per-pixel world rays.
struct Rays {
  Camera cam;
  Mat3 frame;
  std::vector<Vec3> dir;  ///< world, per pixel
  std::vector<double> axial;  ///< d · forward
};

Rays make_rays(const Camera& cam) {
    Rays out;
    out.cam = cam;
    out.cam.lens = Lens::kPinhole;
    out.frame = camera_frame(out.cam);
    const double f = focal_pixels(out.cam);
    for (int y = 0; y < out.cam.height; ++y) {
      for (int x = 0; x < out.cam.width; ++x) {
        const Vec3 d = camera_ray(out.cam, f, x + 0.5, y + 0.5);
        out.dir.push_back(out.frame * d);
        out.axial.push_back(d.z());
      }
    }
    return out;
}

double wall_distance(const Vec3& from, const Vec3& dir);

/// View 0: down the trachea's middle. View 1: a tip against the wall (1 mm from it), looking 30° towards it.
const Rays& rays(int view) {
  static const Rays axis = make_rays(airway().tip);
  static const Rays wall = [] {
    Camera c = airway().tip;
    const Vec3 side = c.up.cross(c.forward).normalized();
    c.position += (wall_distance(c.position, side) - 1e-3) * side;
    c.forward = (c.forward.normalized() + std::tan(30.0 * kDegToRad) * side).normalized();
    return make_rays(c);
  }();
  return view == 0 ? axis : wall;
}

struct EmbreeScene {
  RTCDevice device = rtcNewDevice(nullptr);
  RTCScene scene = nullptr;
  EmbreeScene() {
    const anatomy::TriangleMesh& m = airway().mesh;
    scene = rtcNewScene(device);
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, m.vertices.size()));
    auto* f = static_cast<unsigned*>(
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, m.triangles.size()));
    for (std::size_t i = 0; i < m.vertices.size(); ++i) {
      for (int k = 0; k < 3; ++k) v[3 * i + k] = static_cast<float>(m.vertices[i][k]);
    }
    for (std::size_t i = 0; i < m.triangles.size(); ++i) {
      for (int k = 0; k < 3; ++k) f[3 * i + k] = m.triangles[i][k];
    }
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(scene);
  }
  ~EmbreeScene() {
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
  }
};

const EmbreeScene& embree() {
  static const EmbreeScene e;
  return e;
}

double wall_distance(const Vec3& from, const Vec3& dir) {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh;
  rh.ray.org_x = static_cast<float>(from.x());
  rh.ray.org_y = static_cast<float>(from.y());
  rh.ray.org_z = static_cast<float>(from.z());
  rh.ray.dir_x = static_cast<float>(dir.x());
  rh.ray.dir_y = static_cast<float>(dir.y());
  rh.ray.dir_z = static_cast<float>(dir.z());
  rh.ray.tnear = 0.0f;
  rh.ray.tfar = std::numeric_limits<float>::infinity();
  rh.ray.mask = ~0u;
  rh.ray.flags = 0;
  rh.ray.time = 0.0f;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(embree().scene, &ctx, &rh);
  return rh.ray.tfar;
}

std::vector<float> depth_packet8(int view) {
  const Rays& r = rays(view);
  const int w = r.cam.width, h = r.cam.height;
  std::vector<float> depth(static_cast<std::size_t>(w * h), 0.0f);
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  for (int ty = 0; ty < h; ty += 2) {
    for (int tx = 0; tx < w; tx += 4) {
      alignas(32) RTCRayHit8 rh;
      alignas(32) int valid[8];
      for (int k = 0; k < 8; ++k) {
        const std::size_t i = static_cast<std::size_t>((ty + k / 4) * w + tx + k % 4);
        valid[k] = -1;
        rh.ray.org_x[k] = static_cast<float>(r.cam.position.x());
        rh.ray.org_y[k] = static_cast<float>(r.cam.position.y());
        rh.ray.org_z[k] = static_cast<float>(r.cam.position.z());
        rh.ray.dir_x[k] = static_cast<float>(r.dir[i].x());
        rh.ray.dir_y[k] = static_cast<float>(r.dir[i].y());
        rh.ray.dir_z[k] = static_cast<float>(r.dir[i].z());
        rh.ray.tnear[k] = 0.0f;
        rh.ray.tfar[k] = std::numeric_limits<float>::infinity();
        rh.ray.mask[k] = ~0u;
        rh.ray.flags[k] = 0;
        rh.ray.time[k] = 0.0f;
        rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
      }
      rtcIntersect8(valid, embree().scene, &ctx, &rh);
      for (int k = 0; k < 8; ++k) {
        const std::size_t i = static_cast<std::size_t>((ty + k / 4) * w + tx + k % 4);
        if (rh.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID) depth[i] = rh.ray.tfar[k] * static_cast<float>(r.axial[i]);
      }
    }
  }
  return depth;
}

std::vector<float> depth_single(int view) {
  const Rays& r = rays(view);
  std::vector<float> depth(r.dir.size(), 0.0f);
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  for (std::size_t i = 0; i < r.dir.size(); ++i) {
    RTCRayHit rh;
    rh.ray.org_x = static_cast<float>(r.cam.position.x());
    rh.ray.org_y = static_cast<float>(r.cam.position.y());
    rh.ray.org_z = static_cast<float>(r.cam.position.z());
    rh.ray.dir_x = static_cast<float>(r.dir[i].x());
    rh.ray.dir_y = static_cast<float>(r.dir[i].y());
    rh.ray.dir_z = static_cast<float>(r.dir[i].z());
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = std::numeric_limits<float>::infinity();
    rh.ray.mask = ~0u;
    rh.ray.flags = 0;
    rh.ray.time = 0.0f;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(embree().scene, &ctx, &rh);
    if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) depth[i] = rh.ray.tfar * static_cast<float>(r.axial[i]);
  }
  return depth;
}

/// A z-buffer rasteriser: camera-space vertices, triangles entirely in front of the near plane (1 mm) projected and
/// filled by edge functions at pixel centres, 1/z interpolated in screen space (perspective-correct depth).
std::vector<float> depth_raster(int view) {
  const Rays& r = rays(view);
  const int w = r.cam.width, h = r.cam.height;
  const double f = focal_pixels(r.cam);
  const anatomy::TriangleMesh& m = airway().mesh;
  constexpr double kNear = 1e-3;
  std::vector<Eigen::Vector3f> cv(m.vertices.size());  // x_px, y_px, 1/z
  std::vector<char> front(m.vertices.size());
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    const Vec3 c = r.frame.transpose() * (m.vertices[i] - r.cam.position);
    front[i] = c.z() > kNear;
    cv[i] = Eigen::Vector3f(static_cast<float>(0.5 * w + f * c.x() / c.z()), static_cast<float>(0.5 * h + f * c.y() / c.z()),
                            static_cast<float>(1.0 / c.z()));
  }
  std::vector<float> inv_z(static_cast<std::size_t>(w * h), 0.0f);  // 0: nothing yet (1/z > 0 in front)
  for (const anatomy::Triangle& t : m.triangles) {
    if (!front[t[0]] || !front[t[1]] || !front[t[2]]) continue;  // no near-plane clipping
    const Eigen::Vector3f& a = cv[t[0]];
    const Eigen::Vector3f& b = cv[t[1]];
    const Eigen::Vector3f& c = cv[t[2]];
    const float area = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
    if (std::fabs(area) < 1e-12f) continue;
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({a.x(), b.x(), c.x()}) - 0.5f)));
    const int x1 = std::min(w - 1, static_cast<int>(std::ceil(std::max({a.x(), b.x(), c.x()}) - 0.5f)));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({a.y(), b.y(), c.y()}) - 0.5f)));
    const int y1 = std::min(h - 1, static_cast<int>(std::ceil(std::max({a.y(), b.y(), c.y()}) - 0.5f)));
    for (int y = y0; y <= y1; ++y) {
      const float py = y + 0.5f;
      for (int x = x0; x <= x1; ++x) {
        const float px = x + 0.5f;
        const float w0 = ((b.x() - px) * (c.y() - py) - (b.y() - py) * (c.x() - px)) / area;
        const float w1 = ((c.x() - px) * (a.y() - py) - (c.y() - py) * (a.x() - px)) / area;
        const float w2 = 1.0f - w0 - w1;
        if (w0 < 0.0f || w1 < 0.0f || w2 < 0.0f) continue;
        const float iz = w0 * a.z() + w1 * b.z() + w2 * c.z();
        float& cell = inv_z[static_cast<std::size_t>(y * w + x)];
        if (iz > cell) cell = iz;  // nearer
      }
    }
  }
  for (float& v : inv_z) v = v > 0.0f ? 1.0f / v : 0.0f;
  return inv_z;
}

double mismatch(const std::vector<float>& depth, int view) {
  const std::vector<float> reference = depth_packet8(view);
  std::size_t bad = 0;
  for (std::size_t i = 0; i < depth.size(); ++i) {
    if (std::fabs(depth[i] - reference[i]) > 0.01f * std::max(reference[i], 1e-6f)) ++bad;
  }
  return static_cast<double>(bad) / static_cast<double>(depth.size());
}

template <class Fn>
void BM_Visibility(benchmark::State& state, Fn fn) {
  const auto view = static_cast<int>(state.range(0));
  (void)rays(view);
  std::vector<float> depth;
  for (auto _ : state) {
    depth = fn(view);
    benchmark::DoNotOptimize(depth.data());
  }
  state.counters["fps"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["depth_mismatch"] = mismatch(depth, view);
  state.SetLabel(airway().label + (view == 0 ? ", down the trachea" : ", 1 mm from the wall"));
}
BENCHMARK_CAPTURE(BM_Visibility, embree_packet8, depth_packet8)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Visibility, embree_single, depth_single)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Visibility, raster, depth_raster)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
