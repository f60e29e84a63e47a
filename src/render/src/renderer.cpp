#include "magvine/render/renderer.hpp"

#include <embree3/rtcore.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <opencv2/core.hpp>
#include <random>
#include <span>
#include <string>
#include <thread>

#include "magvine/anatomy/segment_geometry.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/text.hpp"
#include "magvine/core/units.hpp"
#include "magvine/core/usage.hpp"

namespace magvine::render {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
/// Packet tiles: 4 × 2 pixels per rtcIntersect8 call (coherent primary rays; the research note measured 2.4× the
/// single-ray rate).
constexpr int kTileW = 4;
constexpr int kTileH = 2;
/// Entries of the gamma table over linear [0, 1]: fine enough that the darkest grey levels are not skipped.
constexpr int kGammaTable = 65536;

[[noreturn]] void embree_failure(RTCDevice device, const std::string& what) {
  const RTCError code = device != nullptr ? rtcGetDeviceError(device) : RTC_ERROR_UNKNOWN;
  throw NumericalError("render: Embree failed to " + what + " (error " + std::to_string(static_cast<int>(code)) + ")");
}

/// Runs body(row) for rows 0..rows−1 on `threads` threads, rows interleaved (neighbouring rows cost alike).
template <class Body>
void parallel_rows(int rows, int threads, const Body& body) {
  threads = std::max(1, std::min(threads, rows));
  if (threads == 1) {
    for (int r = 0; r < rows; ++r) body(r);
    return;
  }
  std::vector<std::thread> pool;
  pool.reserve(static_cast<std::size_t>(threads - 1));
  for (int k = 1; k < threads; ++k) {
    pool.emplace_back([&, k] {
      for (int r = k; r < rows; r += threads) body(r);
    });
  }
  for (int r = 0; r < rows; r += threads) body(r);
  for (auto& t : pool) t.join();
}

/// x^n for a non-negative integer n by squaring (the specular lobe: std::pow costs more than the rest of a pixel).
inline float int_pow(float x, unsigned n) {
  float r = 1.0f;
  while (n != 0u) {
    if ((n & 1u) != 0u) r *= x;
    x *= x;
    n >>= 1u;
  }
  return r;
}

/// The endoscope's light on a surface (the header's law): radiance = E (ρ cos_i / π + k_s cos_i^s) for irradiance E;
/// `diffuse` is ρ/π (times any texture), `glint` k_s, `shininess` s.
inline float lit(float irradiance, float cos_i, float diffuse, float glint, unsigned shininess) {
  return irradiance * (diffuse * cos_i + glint * int_pow(cos_i, shininess));
}

inline std::uint32_t hash3(std::int32_t x, std::int32_t y, std::int32_t z) {
  auto h = static_cast<std::uint32_t>(x) * 0x8da6b343u ^ static_cast<std::uint32_t>(y) * 0xd8163841u ^
           static_cast<std::uint32_t>(z) * 0xcb1ab31fu;
  h ^= h >> 13;
  h *= 0x5bd1e995u;
  h ^= h >> 15;
  return h;
}

/// Smooth value noise in [−1, 1] on a lattice of `cell` metres: the mucosa's mottling, fixed to the wall.
float value_noise(const float p[3], float inv_cell) {
  float f[3];
  std::int32_t i[3];
  for (int k = 0; k < 3; ++k) {
    const float s = p[k] * inv_cell;
    const float fl = std::floor(s);
    i[k] = static_cast<std::int32_t>(fl);
    const float t = s - fl;
    f[k] = t * t * (3.0f - 2.0f * t);
  }
  float c[2][2][2];
  for (int a = 0; a < 2; ++a) {
    for (int b = 0; b < 2; ++b) {
      for (int d = 0; d < 2; ++d) {
        c[a][b][d] = static_cast<float>(hash3(i[0] + a, i[1] + b, i[2] + d) & 0xffffu) * (2.0f / 65535.0f) - 1.0f;
      }
    }
  }
  const auto lerp = [](float u, float v, float t) { return u + (v - u) * t; };
  const float x00 = lerp(c[0][0][0], c[1][0][0], f[0]);
  const float x10 = lerp(c[0][1][0], c[1][1][0], f[0]);
  const float x01 = lerp(c[0][0][1], c[1][0][1], f[0]);
  const float x11 = lerp(c[0][1][1], c[1][1][1], f[0]);
  return lerp(lerp(x00, x10, f[1]), lerp(x01, x11, f[1]), f[2]);
}

/// The per-pixel rays of one lens in the camera frame, with each pixel's light weight spot(ψ)·vignetting.
struct RayTable {
  Lens lens = Lens::kPinhole;
  double fov = 0.0, spot_exponent = 0.0, vignetting = 0.0;
  int width = 0, height = 0;
  std::vector<float> dir;     ///< 3 per pixel, unit, camera frame
  std::vector<float> weight;  ///< per pixel
};

RayTable make_ray_table(const Camera& camera, double spot_exponent, double vignetting) {
  RayTable t;
  t.lens = camera.lens;
  t.fov = camera.fov;
  t.spot_exponent = spot_exponent;
  t.vignetting = vignetting;
  t.width = camera.width;
  t.height = camera.height;
  const double focal = focal_pixels(camera);
  const auto n = static_cast<std::size_t>(camera.width) * static_cast<std::size_t>(camera.height);
  t.dir.resize(3 * n);
  t.weight.resize(n);
  const double half_diag2 = 0.25 * (camera.width * camera.width + camera.height * camera.height);
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const double px = x + 0.5;
      const double py = y + 0.5;
      const Vec3 d = camera_ray(camera, focal, px, py);
      const std::size_t i =
          static_cast<std::size_t>(y) * static_cast<std::size_t>(camera.width) + static_cast<std::size_t>(x);
      for (int k = 0; k < 3; ++k) t.dir[3 * i + static_cast<std::size_t>(k)] = static_cast<float>(d[k]);
      const double dx = px - 0.5 * camera.width;
      const double dy = py - 0.5 * camera.height;
      const double spot = d.z() > 0.0 ? std::pow(d.z(), spot_exponent) : 0.0;
      t.weight[i] = static_cast<float>(spot * std::max(0.0, 1.0 - vignetting * (dx * dx + dy * dy) / half_diag2));
    }
  }
  return t;
}

void check_look(const EndoscopeLook& look) {
  const auto bad = [](const char* key, const char* what) { throw InputError("render", 0, key, what); };
  if (!look.albedo.allFinite() || (look.albedo.array() < 0.0).any() || (look.albedo.array() > 1.0).any()) {
    bad("albedo", "each channel must lie in [0, 1]");
  }
  if (!(look.specular >= 0.0)) bad("specular", "must be ≥ 0");
  if (!(look.shininess >= 0.0 && look.shininess <= 1000.0)) bad("shininess", "must lie in [0, 1000]");
  if (!(look.spot_exponent >= 0.0 && look.spot_exponent <= 100.0)) bad("spot_exponent", "must lie in [0, 100]");
  if (!(look.light_softening > 0.0 && std::isfinite(look.light_softening))) bad("light_softening", "must be > 0");
  if (!(look.vignetting >= 0.0 && look.vignetting <= 1.0)) bad("vignetting", "must lie in [0, 1]");
  if (!(look.gamma > 0.0 && look.gamma <= 10.0)) bad("gamma", "must lie in (0, 10]");
  if (!(look.exposure >= 0.0 && std::isfinite(look.exposure))) bad("exposure", "must be ≥ 0 (0: auto)");
  if (!(look.exposure_target > 0.0 && look.exposure_target <= 1.0)) bad("exposure_target", "must lie in (0, 1]");
  if (!(look.texture >= 0.0 && look.texture < 1.0)) bad("texture", "must lie in [0, 1)");
  if (!(look.noise >= 0.0 && std::isfinite(look.noise))) bad("noise", "must be ≥ 0");
}

}  // namespace

namespace {

/// Area-weighted unit vertex normals, 3 floats per vertex (UnitZ for a vertex of zero-area triangles only).
std::vector<float> vertex_normals(std::span<const Vec3> vertices, const std::vector<anatomy::Triangle>& triangles) {
  std::vector<Vec3> acc(vertices.size(), Vec3::Zero());
  for (const anatomy::Triangle& t : triangles) {
    const Vec3 a = (vertices[t[1]] - vertices[t[0]]).cross(vertices[t[2]] - vertices[t[0]]);  // area_vector
    for (const std::uint32_t v : t) acc[v] += a;
  }
  std::vector<float> out(3 * acc.size());
  for (std::size_t i = 0; i < acc.size(); ++i) {
    const double n = acc[i].norm();
    const Vec3 u = n > 0.0 ? Vec3(acc[i] / n) : Vec3::UnitZ();
    for (int k = 0; k < 3; ++k) out[3 * i + static_cast<std::size_t>(k)] = static_cast<float>(u[k]);
  }
  return out;
}

}  // namespace

struct AirwayRenderer::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  RTCGeometry geometry = nullptr;            ///< the airway's triangles (owned by the scene)
  float* vertices = nullptr;                 ///< its vertex buffer, 3 per vertex (Embree's)
  bool refitting = false;                    ///< moved at least once: later commits refit the tree
  std::vector<float> normals;                ///< 3 per vertex, unit
  std::vector<anatomy::Triangle> triangles;  ///< for the normals' interpolation
  int threads = 1;
  mutable std::mutex table_mutex;
  mutable std::shared_ptr<const RayTable> table;

  ~Impl() {
    if (scene != nullptr) rtcReleaseScene(scene);
    if (device != nullptr) rtcReleaseDevice(device);
  }

  std::shared_ptr<const RayTable> rays(const Camera& camera, const EndoscopeLook& look) const {
    const std::lock_guard<std::mutex> lock(table_mutex);
    if (!table || table->lens != camera.lens || table->fov != camera.fov || table->width != camera.width ||
        table->height != camera.height || table->spot_exponent != look.spot_exponent ||
        table->vignetting != look.vignetting) {
      table = std::make_shared<const RayTable>(make_ray_table(camera, look.spot_exponent, look.vignetting));
    }
    return table;
  }
};

AirwayRenderer::AirwayRenderer(const anatomy::TriangleMesh& mesh, int threads) : m_impl(std::make_unique<Impl>()) {
  anatomy::validate_mesh(mesh, "render");
  usage::note(usage::Component::kRenderer);
  Impl& s = *m_impl;
  s.threads = std::max(1, threads);
  s.device = rtcNewDevice(nullptr);
  if (s.device == nullptr) embree_failure(nullptr, "create a device");
  s.scene = rtcNewScene(s.device);
  // Robust (watertight) intersection: the fast default lets rays through shared edges and vertices, which shows as
  // dotted lines of missed pixels along a tube's vertex rows.
  rtcSetSceneFlags(s.scene, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(s.scene, RTC_BUILD_QUALITY_HIGH);  // a static airway: a better tree pays over many frames
  RTCGeometry geom = rtcNewGeometry(s.device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                        3 * sizeof(float), mesh.vertices.size()));
  auto* f = static_cast<std::uint32_t*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                3 * sizeof(std::uint32_t), mesh.triangles.size()));
  if (v == nullptr || f == nullptr) embree_failure(s.device, "allocate the mesh buffers");
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    for (int k = 0; k < 3; ++k) v[3 * i + static_cast<std::size_t>(k)] = static_cast<float>(mesh.vertices[i][k]);
  }
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      f[3 * t + static_cast<std::size_t>(k)] = mesh.triangles[t][static_cast<std::size_t>(k)];
    }
  }
  s.normals = vertex_normals(mesh.vertices, mesh.triangles);
  s.triangles = mesh.triangles;
  s.geometry = geom;
  s.vertices = v;
  rtcCommitGeometry(geom);
  rtcAttachGeometry(s.scene, geom);
  rtcReleaseGeometry(geom);  // the scene holds it
  rtcCommitScene(s.scene);
  if (rtcGetDeviceError(s.device) != RTC_ERROR_NONE) embree_failure(s.device, "build the airway's BVH");
}

void AirwayRenderer::move(std::span<const Vec3> vertices) {
  Impl& s = *m_impl;
  const std::size_t n = s.normals.size() / 3;
  if (vertices.size() != n) {
    throw InputError("render", 0, "vertices", printf_string("%zu vertices for an airway of %zu", vertices.size(), n));
  }
  for (const Vec3& x : vertices) {
    if (!x.allFinite()) throw InputError("render", 0, "vertices", "a moved vertex is not finite");
  }
  std::vector<float> normals = vertex_normals(vertices, s.triangles);  // what may throw, before anything changes
  if (!s.refitting) {
    // From now on each commit refits the tree built on the first shape (Embree's refit keeps its topology). Embree
    // reads a geometry's build quality only in a scene of low build quality (the rtcSetGeometryBuildQuality manual),
    // and measured, Embree 3.13 still rebuilt the whole tree at every commit until the scene was also dynamic
    // (docs/rendering.md). The first commit after this builds the geometry's own tree; the later ones refit it.
    rtcSetSceneBuildQuality(s.scene, RTC_BUILD_QUALITY_LOW);
    rtcSetSceneFlags(s.scene, rtcGetSceneFlags(s.scene) | RTC_SCENE_FLAG_DYNAMIC);
    rtcSetGeometryBuildQuality(s.geometry, RTC_BUILD_QUALITY_REFIT);
    s.refitting = true;
  }
  for (std::size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) s.vertices[3 * i + static_cast<std::size_t>(k)] = static_cast<float>(vertices[i][k]);
  }
  s.normals = std::move(normals);
  rtcUpdateGeometryBuffer(s.geometry, RTC_BUFFER_TYPE_VERTEX, 0);
  rtcCommitGeometry(s.geometry);
  rtcCommitScene(s.scene);
  if (rtcGetDeviceError(s.device) != RTC_ERROR_NONE) embree_failure(s.device, "refit the airway's BVH");
}

AirwayRenderer::~AirwayRenderer() = default;

std::size_t AirwayRenderer::triangle_count() const {
  return m_impl->triangles.size();
}
int AirwayRenderer::threads() const {
  return m_impl->threads;
}

namespace {

/// ray_capsule for an origin known to lie outside the capsule (the endoscope checks its lens once per frame).
std::optional<std::pair<double, Vec3>> capsule_entry(const Vec3& o, const Vec3& d, const OverviewCapsule& capsule) {
  const double r = capsule.radius;
  std::optional<std::pair<double, Vec3>> best;
  const auto take = [&](double t, const Vec3& n) {
    if (t > 0.0 && (!best || t < best->first)) best = std::make_pair(t, n);
  };
  const Vec3 axis = capsule.b - capsule.a;
  const double length = axis.norm();
  if (length > 0.0) {
    // |w × u|² = r² with w = (o − a) + t d: the parts of w and d across u give a t² + 2 b t + c = 0.
    const Vec3 u = axis / length;
    const Vec3 w0 = o - capsule.a;
    const Vec3 wp = w0 - w0.dot(u) * u;
    const Vec3 dp = d - d.dot(u) * u;
    const double qa = dp.squaredNorm(), qb = wp.dot(dp), qc = wp.squaredNorm() - r * r;
    const double disc = qb * qb - qa * qc;
    if (qa > 0.0 && disc >= 0.0) {
      const double t = (-qb - std::sqrt(disc)) / qa;  // the entry root
      const double s = (w0 + t * d).dot(u);
      if (s > 0.0 && s < length) take(t, (wp + t * dp) / r);
    }
  }
  for (const Vec3& c : {capsule.a, capsule.b}) {
    const Vec3 oc = o - c;
    const double qb = oc.dot(d), qc = oc.squaredNorm() - r * r;
    const double disc = qb * qb - qc;
    if (disc >= 0.0) {
      const double t = -qb - std::sqrt(disc);
      take(t, (oc + t * d) / r);
    }
  }
  return best;
}

bool inside(const Vec3& x, const OverviewCapsule& capsule) {
  return (x - anatomy::closest_point_on_segment(x, capsule.a, capsule.b)).norm() <= capsule.radius;
}

}  // namespace

std::optional<std::pair<double, Vec3>> ray_capsule(const Vec3& o, const Vec3& d, const OverviewCapsule& capsule) {
  if (inside(o, capsule)) return std::nullopt;
  return capsule_entry(o, d, capsule);
}

EndoscopeFrame AirwayRenderer::render_endoscope(const Camera& camera, const EndoscopeLook& look,
                                                std::uint64_t frame_index, AutoExposure* exposure,
                                                std::span<const OverviewCapsule> tools) const {
  check_look(look);
  for (const OverviewCapsule& tool : tools) {
    if (!(tool.radius > 0.0) || !tool.a.allFinite() || !tool.b.allFinite())
      throw InputError("render", 0, "tools", "a tool needs finite ends and a radius > 0");
    if (inside(camera.position, tool)) throw InputError("render", 0, "tools", "the lens lies inside a tool");
  }
  const ToolLook steel;
  const float steel_diffuse[3] = {static_cast<float>(steel.albedo.x() / kPi),
                                  static_cast<float>(steel.albedo.y() / kPi),
                                  static_cast<float>(steel.albedo.z() / kPi)};
  const auto steel_glint = static_cast<float>(steel.specular);
  const auto steel_shininess = static_cast<unsigned>(std::lround(steel.shininess));
  const Vec3 o_world = camera.position;
  const Mat3 frame = camera_frame(camera);
  const std::shared_ptr<const RayTable> table = m_impl->rays(camera, look);
  const Impl& s = *m_impl;
  const int w = camera.width;
  const int h = camera.height;
  const auto n_px = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
  std::vector<float> radiance(3 * n_px, 0.0f);
  EndoscopeFrame out;
  out.depth = cv::Mat(h, w, CV_32F, cv::Scalar(0.0f));

  float rot[9];  // camera → world, row-major
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) rot[3 * r + c] = static_cast<float>(frame(r, c));
  }
  const float org[3] = {static_cast<float>(camera.position.x()), static_cast<float>(camera.position.y()),
                        static_cast<float>(camera.position.z())};
  const float t0sq = static_cast<float>(look.light_softening * look.light_softening);
  const float diffuse[3] = {static_cast<float>(look.albedo.x() / kPi), static_cast<float>(look.albedo.y() / kPi),
                            static_cast<float>(look.albedo.z() / kPi)};
  const auto ks = static_cast<float>(look.specular);
  const auto shininess = static_cast<unsigned>(std::lround(look.shininess));
  const auto texture = static_cast<float>(look.texture);
  constexpr float kInvCell = 1.0f / 1.5e-3f;  // mottling of ~1.5 mm patches

  const int tile_rows = (h + kTileH - 1) / kTileH;
  parallel_rows(tile_rows, s.threads, [&](int tr) {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    alignas(32) RTCRayHit8 rh;
    alignas(32) int valid[8];
    std::array<std::size_t, 8> pixel{};
    for (int tx = 0; tx < w; tx += kTileW) {
      for (int k = 0; k < 8; ++k) {
        const int x = tx + k % kTileW;
        const int y = tr * kTileH + k / kTileW;
        valid[k] = (x < w && y < h) ? -1 : 0;
        const std::size_t i =
            valid[k] != 0 ? static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x) : 0;
        pixel[static_cast<std::size_t>(k)] = i;
        const float* d = &table->dir[3 * i];
        rh.ray.org_x[k] = org[0];
        rh.ray.org_y[k] = org[1];
        rh.ray.org_z[k] = org[2];
        rh.ray.dir_x[k] = rot[0] * d[0] + rot[1] * d[1] + rot[2] * d[2];
        rh.ray.dir_y[k] = rot[3] * d[0] + rot[4] * d[1] + rot[5] * d[2];
        rh.ray.dir_z[k] = rot[6] * d[0] + rot[7] * d[1] + rot[8] * d[2];
        rh.ray.tnear[k] = 0.0f;
        rh.ray.tfar[k] = kInf;
        rh.ray.mask[k] = 0xffffffffu;
        rh.ray.flags[k] = 0;
        rh.ray.time[k] = 0.0f;
        rh.ray.id[k] = static_cast<unsigned>(k);
        rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
      }
      rtcIntersect8(valid, s.scene, &ctx, &rh);
      for (int k = 0; k < 8; ++k) {
        if (valid[k] == 0) continue;
        const std::size_t i = pixel[static_cast<std::size_t>(k)];
        const float dx = rh.ray.dir_x[k], dy = rh.ray.dir_y[k], dz = rh.ray.dir_z[k];
        const bool wall_hit = rh.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID;
        if (!tools.empty()) {
          // A tool in front of the wall takes the pixel, shaded by the same light with steel's reflectance.
          const Vec3 d = Vec3(dx, dy, dz).normalized();
          std::optional<std::pair<double, Vec3>> near;
          for (const OverviewCapsule& tool : tools) {
            const auto hit = capsule_entry(o_world, d, tool);  // the lens is outside (checked above)
            if (hit && (!near || hit->first < near->first)) near = hit;
          }
          if (near && (!wall_hit || near->first < rh.ray.tfar[k])) {
            const auto t = static_cast<float>(near->first);
            const auto cos_i = static_cast<float>(std::min(1.0, std::fabs(near->second.dot(d))));
            const float irradiance = table->weight[i] / (t * t + t0sq);
            for (int c = 0; c < 3; ++c)
              radiance[3 * i + static_cast<std::size_t>(c)] = lit(irradiance, cos_i, steel_diffuse[c], steel_glint,
                                                                   steel_shininess);
            reinterpret_cast<float*>(out.depth.data)[i] = t * table->dir[3 * i + 2];
            continue;
          }
        }
        if (!wall_hit) continue;
        const float t = rh.ray.tfar[k];
        const anatomy::Triangle& tri = s.triangles[rh.hit.primID[k]];
        const float u = rh.hit.u[k], v = rh.hit.v[k];
        const float* n0 = &s.normals[3 * tri[0]];
        const float* n1 = &s.normals[3 * tri[1]];
        const float* n2 = &s.normals[3 * tri[2]];
        float n[3];
        for (int c = 0; c < 3; ++c) n[c] = (1.0f - u - v) * n0[c] + u * n1[c] + v * n2[c];
        const float nn = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        const float cos_i = nn > 0.0f ? std::min(1.0f, std::fabs(n[0] * dx + n[1] * dy + n[2] * dz) / nn) : 0.0f;
        const float irradiance = table->weight[i] / (t * t + t0sq);
        float mottle = 1.0f;
        if (texture > 0.0f) {
          const float p[3] = {org[0] + t * dx, org[1] + t * dy, org[2] + t * dz};
          mottle = 1.0f + texture * value_noise(p, kInvCell);
        }
        for (int c = 0; c < 3; ++c)
          radiance[3 * i + static_cast<std::size_t>(c)] = lit(irradiance, cos_i, diffuse[c] * mottle, ks, shininess);
        reinterpret_cast<float*>(out.depth.data)[i] = t * table->dir[3 * i + 2];  // continuous CV_32F
      }
    }
  });

  // Exposure: the 95th percentile of luminance (every 3rd pixel is plenty) to exposure_target.
  double gain = look.exposure;
  if (gain <= 0.0) {
    std::vector<float> lum;
    lum.reserve(n_px / 3 + 1);
    for (std::size_t i = 0; i < n_px; i += 3) {
      lum.push_back(0.2126f * radiance[3 * i] + 0.7152f * radiance[3 * i + 1] + 0.0722f * radiance[3 * i + 2]);
    }
    const auto q = lum.begin() + static_cast<std::ptrdiff_t>(0.95 * static_cast<double>(lum.size() - 1));
    std::nth_element(lum.begin(), q, lum.end());
    const double ideal = *q > 0.0f ? look.exposure_target / static_cast<double>(*q) : 1.0;
    gain = ideal;
    if (exposure != nullptr) {
      if (exposure->gain > 0.0) {
        const double e = std::clamp(exposure->easing, 0.0, 1.0);
        gain = std::exp((1.0 - e) * std::log(exposure->gain) + e * std::log(ideal));
      }
      exposure->gain = gain;
    }
  }
  out.gain = gain;

  // Gamma by table; noise per row from its own seeded generator (the same pixels whatever the thread count).
  std::vector<std::uint8_t> curve(kGammaTable);
  for (int k = 0; k < kGammaTable; ++k) {
    curve[static_cast<std::size_t>(k)] = static_cast<std::uint8_t>(
        std::lround(255.0 * std::pow(static_cast<double>(k) / (kGammaTable - 1), 1.0 / look.gamma)));
  }
  out.color = cv::Mat(h, w, CV_8UC3);
  const auto g = static_cast<float>(gain);
  parallel_rows(h, s.threads, [&](int y) {
    std::mt19937_64 rng(look.seed ^ (0x9e3779b97f4a7c15ull * (frame_index + 1)) ^
                        (0xbf58476d1ce4e5b9ull * static_cast<std::uint64_t>(y + 1)));
    std::normal_distribution<float> normal(0.0f, static_cast<float>(look.noise));
    auto* row = out.color.ptr<cv::Vec3b>(y);
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x);
      for (int c = 0; c < 3; ++c) {
        const float lin = std::clamp(g * radiance[3 * i + static_cast<std::size_t>(c)], 0.0f, 1.0f);
        float value = curve[static_cast<std::size_t>(lin * (kGammaTable - 1) + 0.5f)];
        if (look.noise > 0.0) value = std::clamp(std::round(value + normal(rng)), 0.0f, 255.0f);
        row[x][2 - c] = static_cast<std::uint8_t>(value);  // RGB → BGR
      }
    }
  });
  return out;
}

namespace {

/// A triangle geometry of `device` holding the vertices and triangles (not yet committed).
template <class Triangles>
RTCGeometry triangle_geometry(RTCDevice device, const std::vector<Vec3>& vertices, const Triangles& triangles) {
  RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* v = static_cast<float*>(
      rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), vertices.size()));
  auto* f = static_cast<std::uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                3 * sizeof(std::uint32_t), triangles.size()));
  if (v == nullptr || f == nullptr) embree_failure(device, "allocate a mesh's buffers");
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    for (int k = 0; k < 3; ++k) v[3 * i + static_cast<std::size_t>(k)] = static_cast<float>(vertices[i][k]);
  }
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    for (std::size_t k = 0; k < 3; ++k) f[3 * i + k] = triangles[i][k];
  }
  return g;
}

/// The overview's per-frame scene: the airway as an instance of the renderer's static scene, plus the robot, the
/// magnets, the target and the path; a colour per geometry id.
class OverviewScene {
 public:
  explicit OverviewScene(RTCDevice device) : m_device(device), m_scene(rtcNewScene(device)) {
    if (m_scene == nullptr) embree_failure(device, "create the overview scene");
    rtcSetSceneFlags(m_scene, RTC_SCENE_FLAG_ROBUST);
  }
  ~OverviewScene() { rtcReleaseScene(m_scene); }
  OverviewScene(const OverviewScene&) = delete;
  OverviewScene& operator=(const OverviewScene&) = delete;

  RTCScene get() const { return m_scene; }
  const std::vector<cv::Vec3f>& colours() const { return m_colours; }
  unsigned anatomy() const { return m_anatomy; }

  void add_anatomy(RTCScene airway) {
    RTCGeometry g = rtcNewGeometry(m_device, RTC_GEOMETRY_TYPE_INSTANCE);
    rtcSetGeometryInstancedScene(g, airway);
    const float identity[12] = {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
    rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, identity);
    m_anatomy = attach(g, {0.85f, 0.55f, 0.55f});
  }

  /// A tube of spheres and cones through `points` (Embree's round linear curve).
  void add_curve(const std::vector<Vec3>& points, double radius, cv::Vec3f colour) {
    if (points.size() < 2) return;
    RTCGeometry g = rtcNewGeometry(m_device, RTC_GEOMETRY_TYPE_ROUND_LINEAR_CURVE);
    auto* v = static_cast<float*>(
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 4 * sizeof(float), points.size()));
    auto* idx = static_cast<std::uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT,
                                                                    sizeof(std::uint32_t), points.size() - 1));
    for (std::size_t i = 0; i < points.size(); ++i) {
      for (int k = 0; k < 3; ++k) v[4 * i + static_cast<std::size_t>(k)] = static_cast<float>(points[i][k]);
      v[4 * i + 3] = static_cast<float>(radius);
      if (i + 1 < points.size()) idx[i] = static_cast<std::uint32_t>(i);
    }
    attach(g, colour);
  }

  void add_ball(const Vec3& centre, double radius, cv::Vec3f colour) {
    RTCGeometry g = rtcNewGeometry(m_device, RTC_GEOMETRY_TYPE_SPHERE_POINT);
    auto* v = static_cast<float*>(
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 4 * sizeof(float), 1));
    for (int k = 0; k < 3; ++k) v[k] = static_cast<float>(centre[k]);
    v[3] = static_cast<float>(radius);
    attach(g, colour);
  }

  /// A closed cone frustum from `a` (radius ra) to `b` (radius rb; 0: a point).
  void add_frustum(const Vec3& a, const Vec3& b, double ra, double rb, cv::Vec3f colour) {
    constexpr int kSides = 40;
    const Vec3 axis = (b - a).normalized();
    const Vec3 e1 = axis.unitOrthogonal();
    const Vec3 e2 = axis.cross(e1);
    std::vector<Vec3> vs;
    std::vector<std::array<std::uint32_t, 3>> ts;
    for (int i = 0; i < kSides; ++i) {
      const double phi = 2.0 * kPi * i / kSides;
      const Vec3 radial = std::cos(phi) * e1 + std::sin(phi) * e2;
      vs.push_back(a + ra * radial);
      vs.push_back(b + rb * radial);
    }
    const auto ca = static_cast<std::uint32_t>(vs.size());
    vs.push_back(a);
    vs.push_back(b);
    for (std::uint32_t i = 0; i < kSides; ++i) {
      const std::uint32_t j = (i + 1) % kSides;
      ts.push_back({2 * i, 2 * j, 2 * i + 1});
      ts.push_back({2 * j, 2 * j + 1, 2 * i + 1});
      ts.push_back({ca, 2 * j, 2 * i});
      ts.push_back({ca + 1, 2 * i + 1, 2 * j + 1});
    }
    attach(triangle_geometry(m_device, vs, ts), colour);
  }

  /// A triangle mesh with its own opacity (below 1: composited like the walls).
  void add_mesh(const OverviewMesh& mesh) {
    if (mesh.vertices.empty() || mesh.triangles.empty()) return;
    RTCGeometry g = triangle_geometry(m_device, mesh.vertices, mesh.triangles);
    const unsigned id = attach(g, {mesh.colour[0], mesh.colour[1], mesh.colour[2]});
    if (m_opacity.size() <= id) m_opacity.resize(id + 1, 1.0f);
    m_opacity[id] = static_cast<float>(mesh.opacity);
  }

  /// Opacity of geometry `id` (1 unless a mesh set it).
  float opacity(unsigned id) const { return id < m_opacity.size() ? m_opacity[id] : 1.0f; }

  void commit() {
    rtcCommitScene(m_scene);
    if (rtcGetDeviceError(m_device) != RTC_ERROR_NONE) embree_failure(m_device, "build the overview scene");
  }

 private:
  unsigned attach(RTCGeometry g, cv::Vec3f colour) {
    rtcCommitGeometry(g);
    const unsigned id = rtcAttachGeometry(m_scene, g);
    rtcReleaseGeometry(g);
    if (m_colours.size() <= id) m_colours.resize(id + 1);
    m_colours[id] = colour;
    return id;
  }

  RTCDevice m_device;
  RTCScene m_scene;
  std::vector<cv::Vec3f> m_colours;  ///< linear RGB per geometry id
  std::vector<float> m_opacity;      ///< per geometry id (meshes only)
  unsigned m_anatomy = RTC_INVALID_GEOMETRY_ID;
};

}  // namespace

cv::Mat AirwayRenderer::render_overview(const Camera& camera, const OverviewContent& content,
                                        const OverviewLook& look) const {
  if (!(look.anatomy_opacity >= 0.0 && look.anatomy_opacity <= 1.0)) {
    throw InputError("render", 0, "anatomy_opacity", "must lie in [0, 1]");
  }
  const Mat3 frame = camera_frame(camera);
  const double focal = focal_pixels(camera);
  const Impl& s = *m_impl;
  OverviewScene scene(s.device);
  scene.add_anatomy(s.scene);
  scene.add_curve(content.body, content.body_radius, {0.55f, 0.80f, 1.0f});
  scene.add_curve(content.path, 0.35 * content.body_radius, {1.0f, 0.85f, 0.1f});
  for (const auto& line : content.lines) scene.add_curve(line, content.line_radius, {0.85f, 0.35f, 0.05f});
  if (content.target) scene.add_ball(*content.target, content.target_radius, {0.1f, 0.8f, 0.2f});
  for (const OverviewMagnet& m : content.magnets) {
    const Vec3 n = m.axis.normalized();
    const double half = m.diameter > 0.0 ? 0.5 * m.length : 10e-3;
    const double radius = m.diameter > 0.0 ? 0.5 * m.diameter : 10e-3;
    if (m.diameter > 0.0) {
      scene.add_frustum(m.position, m.position + half * n, radius, radius, {0.85f, 0.12f, 0.1f});  // north
      scene.add_frustum(m.position - half * n, m.position, radius, radius, {0.15f, 0.3f, 0.85f});  // south
    } else {
      scene.add_ball(m.position, radius, {0.85f, 0.12f, 0.1f});
    }
    // The field direction: an arrow out of the north face.
    const Vec3 foot = m.position + half * n;
    const Vec3 neck = foot + 0.6 * half * n;
    scene.add_frustum(foot, neck, 0.12 * radius, 0.12 * radius, {0.25f, 0.25f, 0.25f});
    scene.add_frustum(neck, neck + 0.45 * half * n, 0.3 * radius, 0.0, {0.25f, 0.25f, 0.25f});
  }
  for (const OverviewMesh& mesh : content.meshes) scene.add_mesh(mesh);
  for (const OverviewCapsule& c : content.capsules) scene.add_curve({c.a, c.b}, c.radius, {0.55f, 0.55f, 0.6f});
  scene.commit();

  cv::Mat image(camera.height, camera.width, CV_8UC3);
  const auto alpha = static_cast<float>(look.anatomy_opacity);
  const cv::Vec3f background(look.background[2] / 255.0f, look.background[1] / 255.0f, look.background[0] / 255.0f);
  const int layers = std::max(1, look.max_layers);
  parallel_rows(camera.height, s.threads, [&](int y) {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    auto* row = image.ptr<cv::Vec3b>(y);
    for (int x = 0; x < camera.width; ++x) {
      const Vec3 d = frame * camera_ray(camera, focal, x + 0.5, y + 0.5);
      cv::Vec3f colour(0.0f, 0.0f, 0.0f);
      float transmit = 1.0f;
      float tnear = 0.0f;
      bool done = false;
      for (int layer = 0; layer <= layers && !done; ++layer) {
        RTCRayHit rh;
        rh.ray.org_x = static_cast<float>(camera.position.x());
        rh.ray.org_y = static_cast<float>(camera.position.y());
        rh.ray.org_z = static_cast<float>(camera.position.z());
        rh.ray.dir_x = static_cast<float>(d.x());
        rh.ray.dir_y = static_cast<float>(d.y());
        rh.ray.dir_z = static_cast<float>(d.z());
        rh.ray.tnear = tnear;
        rh.ray.tfar = kInf;
        rh.ray.mask = 0xffffffffu;
        rh.ray.flags = 0;
        rh.ray.time = 0.0f;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(scene.get(), &ctx, &rh);
        if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
          colour += transmit * background;
          done = true;
          break;
        }
        const Vec3 ng(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z);
        const double nn = ng.norm();
        const auto facing = static_cast<float>(nn > 0.0 ? std::fabs(ng.dot(d)) / nn : 1.0);
        const float shade = 0.35f + 0.65f * facing;
        const bool wall = rh.hit.instID[0] != RTC_INVALID_GEOMETRY_ID;
        const cv::Vec3f base = wall ? scene.colours()[scene.anatomy()] : scene.colours()[rh.hit.geomID];
        const float surface = wall ? alpha : scene.opacity(rh.hit.geomID);
        if (surface < 1.0f && layer < layers) {
          // A grazing wall crosses more tissue: opacity 1 − (1 − α)^(1/cos), capped, outlines the airway.
          const float a = std::min(0.9f, 1.0f - std::pow(1.0f - surface, 1.0f / std::max(facing, 0.05f)));
          colour += transmit * a * shade * base;
          transmit *= 1.0f - a;
          tnear = rh.ray.tfar * (1.0f + 1e-5f) + 1e-6f;
          continue;
        }
        colour += transmit * shade * base;
        done = true;
      }
      if (!done) colour += transmit * background;
      for (int c = 0; c < 3; ++c) {
        row[x][2 - c] = static_cast<std::uint8_t>(std::lround(255.0f * std::clamp(colour[c], 0.0f, 1.0f)));
      }
    }
  });
  return image;
}

std::pair<Vec3, Vec3> face_on_view(const anatomy::Aabb& box) {
  const Vec3 size = box.max - box.min;
  int thin = 0;
  for (int k = 1; k < 3; ++k) {
    if (size[k] < size[thin]) thin = k;
  }
  return {Vec3::Unit(thin), thin == 2 ? Vec3(Vec3::UnitY()) : Vec3(Vec3::UnitZ())};
}

Camera framing_camera(const anatomy::Aabb& box, const Vec3& from, const Vec3& up, Lens lens, double fov, int width,
                      int height) {
  Camera c;
  c.lens = lens;
  c.fov = fov;
  c.width = width;
  c.height = height;
  c.up = up;
  c.forward = -from.normalized();
  const Vec3 centre = 0.5 * (box.min + box.max);
  const double radius = 0.5 * 1.05 * (box.max - box.min).norm();
  // The narrower of the two fields of view must hold the box's bounding sphere.
  const double half_w = 0.5 * fov;
  const double half_h = lens == Lens::kPinhole ? std::atan(std::tan(half_w) * height / width) : half_w * height / width;
  const double half = std::min(half_w, half_h);
  c.position = centre + from.normalized() * (radius / std::sin(std::max(half, 1e-3)));
  return c;
}

}  // namespace magvine::render
