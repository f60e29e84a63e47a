#include "magvine/anatomy/centerline.hpp"

#include <embree3/rtcore.h>

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cstdlib>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <queue>
#include <string>
#include <utility>
#include <vector>

#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"

namespace magvine::anatomy {
namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
/// Column rays are offset from the cell centres by these fractions of a voxel so that they do not run exactly
/// through the vertices of meshes made on a grid (marching cubes on a CT volume of the same spacing).
constexpr double kJitterB = 0.0137;
constexpr double kJitterC = 0.0291;
/// Rays in the plane across a branch that find its wall when a node is refined on the mesh.
constexpr int kRefineRays = 16;
constexpr int kRefineIterations = 4;

/// The mesh as an Embree scene (watertight intersection) for the voxeliser's column rays and the refinement.
class RayScene {
 public:
  explicit RayScene(const TriangleMesh& mesh) {
    m_device = rtcNewDevice("threads=1");  // one core, like the rest of the extraction
    if (m_device == nullptr) throw NumericalError("centreline: Embree could not create a device");
    m_scene = rtcNewScene(m_device);
    rtcSetSceneFlags(m_scene, RTC_SCENE_FLAG_ROBUST);
    RTCGeometry g = rtcNewGeometry(m_device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), mesh.vertices.size()));
    auto* f = static_cast<std::uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                  3 * sizeof(std::uint32_t), mesh.triangles.size()));
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
      for (int k = 0; k < 3; ++k) v[3 * i + static_cast<std::size_t>(k)] = static_cast<float>(mesh.vertices[i][k]);
    }
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
      for (std::size_t k = 0; k < 3; ++k) f[3 * t + k] = mesh.triangles[t][k];
    }
    rtcCommitGeometry(g);
    rtcAttachGeometry(m_scene, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(m_scene);
    if (rtcGetDeviceError(m_device) != RTC_ERROR_NONE) throw NumericalError("centreline: Embree could not build the BVH");
  }
  ~RayScene() {
    rtcReleaseScene(m_scene);
    rtcReleaseDevice(m_device);
  }
  RayScene(const RayScene&) = delete;
  RayScene& operator=(const RayScene&) = delete;

  /// Distance to the first wall along unit `d` from `o` [m], or +inf.
  double first_hit(const Vec3& o, const Vec3& d, double tnear = 0.0) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRayHit rh;
    rh.ray.org_x = static_cast<float>(o.x());
    rh.ray.org_y = static_cast<float>(o.y());
    rh.ray.org_z = static_cast<float>(o.z());
    rh.ray.dir_x = static_cast<float>(d.x());
    rh.ray.dir_y = static_cast<float>(d.y());
    rh.ray.dir_z = static_cast<float>(d.z());
    rh.ray.tnear = static_cast<float>(tnear);
    rh.ray.tfar = std::numeric_limits<float>::infinity();
    rh.ray.mask = ~0u;
    rh.ray.flags = 0;
    rh.ray.time = 0.0f;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(m_scene, &ctx, &rh);
    return rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? std::numeric_limits<double>::infinity() : rh.ray.tfar;
  }

  /// Every crossing along the ray, in order; crossings closer than `merge` count once (a ray through a shared edge
  /// meets both triangles at the same distance). `merge` must exceed Embree's single-precision resolution of t.
  void crossings(const Vec3& o, const Vec3& d, double merge, std::vector<double>& out) const {
    out.clear();
    double t = 0.0;
    for (int guard = 0; guard < 100000; ++guard) {
      const double hit = first_hit(o, d, t);
      if (!std::isfinite(hit)) return;
      if (out.empty() || hit - out.back() > merge) out.push_back(hit);
      t = std::max(hit + merge, static_cast<double>(std::nextafter(static_cast<float>(hit), 1e30f)));
    }
  }

 private:
  RTCDevice m_device = nullptr;
  RTCScene m_scene = nullptr;
};

struct Grid {
  Vec3 origin = Vec3::Zero();
  double h = 0.0;
  std::array<int, 3> n{0, 0, 0};
  std::size_t cells() const { return static_cast<std::size_t>(n[0]) * static_cast<std::size_t>(n[1]) * static_cast<std::size_t>(n[2]); }
  std::size_t id(int i, int j, int k) const {
    return (static_cast<std::size_t>(k) * static_cast<std::size_t>(n[1]) + static_cast<std::size_t>(j)) *
               static_cast<std::size_t>(n[0]) + static_cast<std::size_t>(i);
  }
};

/// Squared distance transform of one line (Felzenszwalb & Huttenlocher's lower envelope of parabolas).
void edt_line(const float* f, int n, float* d, int* v, float* z) {
  int k = 0;
  v[0] = 0;
  z[0] = -std::numeric_limits<float>::infinity();
  z[1] = std::numeric_limits<float>::infinity();
  for (int q = 1; q < n; ++q) {
    float s = 0.0f;
    for (;;) {
      const int p = v[k];
      s = ((f[q] + static_cast<float>(q) * static_cast<float>(q)) - (f[p] + static_cast<float>(p) * static_cast<float>(p))) /
          (2.0f * static_cast<float>(q - p));
      if (s > z[k] || k == 0) break;
      --k;
    }
    if (s <= z[k] && k == 0) {
      v[0] = q;
      z[0] = -std::numeric_limits<float>::infinity();
      z[1] = std::numeric_limits<float>::infinity();
      continue;
    }
    ++k;
    v[k] = q;
    z[k] = s;
    z[k + 1] = std::numeric_limits<float>::infinity();
  }
  k = 0;
  for (int q = 0; q < n; ++q) {
    while (z[k + 1] < static_cast<float>(q)) ++k;
    const float dq = static_cast<float>(q - v[k]);
    d[q] = dq * dq + f[v[k]];
  }
}

/// The 26 neighbour offsets with their lengths [voxels].
struct Neighbours {
  std::array<std::array<int, 3>, 26> step{};
  std::array<double, 26> length{};
  Neighbours() {
    int m = 0;
    for (int dk = -1; dk <= 1; ++dk) {
      for (int dj = -1; dj <= 1; ++dj) {
        for (int di = -1; di <= 1; ++di) {
          if (di == 0 && dj == 0 && dk == 0) continue;
          step[static_cast<std::size_t>(m)] = {di, dj, dk};
          length[static_cast<std::size_t>(m)] = std::sqrt(static_cast<double>(di * di + dj * dj + dk * dk));
          ++m;
        }
      }
    }
  }
};

/// The lumen's voxels: cell coordinates, distance to the wall [voxels], and the cell → voxel map.
struct Lumen {
  Grid grid;
  std::vector<std::array<int, 3>> ijk;
  std::vector<float> dbf;
  std::vector<std::uint32_t> index;  ///< per cell: voxel index or kNone

  std::uint32_t at(int i, int j, int k) const { return index[grid.id(i, j, k)]; }
  template <class Fn>
  void for_neighbours(std::uint32_t v, const Neighbours& nb, Fn&& fn) const {
    const auto& c = ijk[v];
    for (std::size_t m = 0; m < 26; ++m) {
      const std::uint32_t u = at(c[0] + nb.step[m][0], c[1] + nb.step[m][1], c[2] + nb.step[m][2]);
      if (u != kNone) fn(u, nb.length[m]);
    }
  }
  Vec3 position(std::uint32_t v) const {
    return grid.origin + grid.h * Vec3(ijk[v][0] + 0.5, ijk[v][1] + 0.5, ijk[v][2] + 0.5);
  }
  double separation(std::uint32_t a, std::uint32_t b) const {
    const double dx = ijk[a][0] - ijk[b][0], dy = ijk[a][1] - ijk[b][1], dz = ijk[a][2] - ijk[b][2];
    return std::sqrt(dx * dx + dy * dy + dz * dz);
  }
};

Grid choose_grid(const TriangleMesh& mesh, const CenterlineOptions& o) {
  const Aabb box = bounding_box(mesh);
  const Vec3 extent = box.max - box.min;
  double h = o.voxel;
  if (h <= 0.0) {
    // About 2 M voxels of lumen, and never more cells than the budget.
    const double volume = std::abs(signed_volume(mesh));
    h = std::cbrt(std::max(volume, 1e-12) / 2.0e6);
    h = std::max(h, std::cbrt(extent.prod() / static_cast<double>(o.max_cells)) * 1.05);
  }
  if (!(h > 0.0 && std::isfinite(h))) throw InputError("centreline", 0, "voxel", "must be a positive length");
  Grid g;
  g.h = h;
  g.origin = box.min - Vec3::Constant(1.5 * h);
  const auto size_grid = [&] {
    for (int a = 0; a < 3; ++a) g.n[static_cast<std::size_t>(a)] = static_cast<int>(std::ceil(extent[a] / g.h + 3.0));
    return static_cast<double>(g.n[0]) * g.n[1] * g.n[2];
  };
  while (o.voxel <= 0.0 && size_grid() > static_cast<double>(o.max_cells)) {  // auto: coarsen into the budget
    g.h *= 1.05;
    h = g.h;
    g.origin = box.min - Vec3::Constant(1.5 * h);
  }
  if (size_grid() > static_cast<double>(o.max_cells)) {
    throw InputError("centreline", 0, "voxel",
                     std::to_string(1e3 * h) + " mm gives " + std::to_string(g.n[0]) + " x " + std::to_string(g.n[1]) +
                         " x " + std::to_string(g.n[2]) + " cells, over the budget of " + std::to_string(o.max_cells));
  }
  return g;
}

/// Inside votes from column rays along each axis: a cell is inside when at least two axes say so.
std::vector<std::uint8_t> voxelise(const RayScene& rays, const Grid& g) {
  std::vector<std::uint8_t> votes(g.cells(), 0);
  std::vector<double> hits;
  for (int a = 0; a < 3; ++a) {
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    Vec3 dir = Vec3::Zero();
    dir[a] = 1.0;
    for (int ic = 0; ic < g.n[static_cast<std::size_t>(c)]; ++ic) {
      for (int ib = 0; ib < g.n[static_cast<std::size_t>(b)]; ++ib) {
        Vec3 o = g.origin;
        o[b] += (ib + 0.5 + kJitterB) * g.h;
        o[c] += (ic + 0.5 + kJitterC) * g.h;
        rays.crossings(o, dir, 1e-4 * g.h, hits);
        if (hits.empty() || hits.size() % 2 != 0) continue;  // a grazing ray: this column does not vote
        std::size_t next = 0;
        bool inside = false;
        for (int ia = 0; ia < g.n[static_cast<std::size_t>(a)]; ++ia) {
          const double s = (ia + 0.5) * g.h;
          while (next < hits.size() && hits[next] < s) {
            inside = !inside;
            ++next;
          }
          if (!inside) continue;
          std::array<int, 3> cell{};
          cell[static_cast<std::size_t>(a)] = ia;
          cell[static_cast<std::size_t>(b)] = ib;
          cell[static_cast<std::size_t>(c)] = ic;
          ++votes[g.id(cell[0], cell[1], cell[2])];
        }
      }
    }
  }
  return votes;
}

/// The lumen's largest 26-connected component with its distance transform.
Lumen lumen_of(const Grid& g, std::vector<std::uint8_t> votes, CenterlineReport& report) {
  const std::size_t cells = g.cells();
  // Squared EDT in voxels, stored as float bits in the buffer that becomes the cell → voxel map.
  std::vector<std::uint32_t> buf(cells);
  constexpr float kFar = 1e20f;
  for (std::size_t i = 0; i < cells; ++i) buf[i] = std::bit_cast<std::uint32_t>(votes[i] >= 2 ? kFar : 0.0f);
  std::vector<std::uint8_t>().swap(votes);
  const int longest = std::max({g.n[0], g.n[1], g.n[2]});
  std::vector<float> f(static_cast<std::size_t>(longest)), d(static_cast<std::size_t>(longest)),
      z(static_cast<std::size_t>(longest) + 1);
  std::vector<int> v(static_cast<std::size_t>(longest));
  for (int a = 0; a < 3; ++a) {
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    const int na = g.n[static_cast<std::size_t>(a)];
    for (int ic = 0; ic < g.n[static_cast<std::size_t>(c)]; ++ic) {
      for (int ib = 0; ib < g.n[static_cast<std::size_t>(b)]; ++ib) {
        std::array<int, 3> cell{};
        cell[static_cast<std::size_t>(b)] = ib;
        cell[static_cast<std::size_t>(c)] = ic;
        bool any = false;
        for (int ia = 0; ia < na; ++ia) {
          cell[static_cast<std::size_t>(a)] = ia;
          f[static_cast<std::size_t>(ia)] = std::bit_cast<float>(buf[g.id(cell[0], cell[1], cell[2])]);
          any = any || f[static_cast<std::size_t>(ia)] > 0.0f;
        }
        if (!any) continue;
        edt_line(f.data(), na, d.data(), v.data(), z.data());
        for (int ia = 0; ia < na; ++ia) {
          cell[static_cast<std::size_t>(a)] = ia;
          buf[g.id(cell[0], cell[1], cell[2])] = std::bit_cast<std::uint32_t>(d[static_cast<std::size_t>(ia)]);
        }
      }
    }
  }
  Lumen all;
  all.grid = g;
  for (int k = 0; k < g.n[2]; ++k) {
    for (int j = 0; j < g.n[1]; ++j) {
      for (int i = 0; i < g.n[0]; ++i) {
        const std::size_t id = g.id(i, j, k);
        const float d2 = std::bit_cast<float>(buf[id]);
        if (d2 > 0.0f) {
          all.ijk.push_back({i, j, k});
          all.dbf.push_back(std::sqrt(d2));
          buf[id] = static_cast<std::uint32_t>(all.ijk.size() - 1);
        } else {
          buf[id] = kNone;
        }
      }
    }
  }
  all.index = std::move(buf);
  if (all.ijk.empty()) {
    throw InputError("centreline", 0, "mesh", "no voxel lies inside the mesh (is it closed and the right way out?)");
  }
  // Components (26-connected); keep the largest.
  const Neighbours nb;
  std::vector<std::uint32_t> label(all.ijk.size(), kNone);
  std::vector<std::size_t> sizes;
  std::vector<std::uint32_t> stack;
  for (std::uint32_t s = 0; s < all.ijk.size(); ++s) {
    if (label[s] != kNone) continue;
    const auto id = static_cast<std::uint32_t>(sizes.size());
    sizes.push_back(0);
    label[s] = id;
    stack.push_back(s);
    while (!stack.empty()) {
      const std::uint32_t u = stack.back();
      stack.pop_back();
      ++sizes.back();
      all.for_neighbours(u, nb, [&](std::uint32_t w, double) {
        if (label[w] == kNone) {
          label[w] = id;
          stack.push_back(w);
        }
      });
    }
  }
  report.components = sizes.size();
  const auto keep = static_cast<std::uint32_t>(std::max_element(sizes.begin(), sizes.end()) - sizes.begin());
  if (sizes.size() == 1) return all;
  Lumen kept;
  kept.grid = g;
  kept.index = std::move(all.index);
  for (std::uint32_t s = 0; s < all.ijk.size(); ++s) {
    const std::size_t cell = g.id(all.ijk[s][0], all.ijk[s][1], all.ijk[s][2]);
    if (label[s] != keep) {
      kept.index[cell] = kNone;
      continue;
    }
    kept.index[cell] = static_cast<std::uint32_t>(kept.ijk.size());
    kept.ijk.push_back(all.ijk[s]);
    kept.dbf.push_back(all.dbf[s]);
  }
  return kept;
}

/// Shortest paths from `source` with step costs `cost(length, from, to)`: distances and parents.
template <class Cost>
void dijkstra(const Lumen& L, const Neighbours& nb, std::uint32_t source, const Cost& cost, std::vector<double>& dist,
              std::vector<std::uint32_t>& parent, std::vector<double>* length = nullptr) {
  const std::size_t n = L.ijk.size();
  dist.assign(n, std::numeric_limits<double>::infinity());
  parent.assign(n, kNone);
  if (length != nullptr) length->assign(n, 0.0);
  using Item = std::pair<double, std::uint32_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> heap;
  dist[source] = 0.0;
  parent[source] = source;
  heap.push({0.0, source});
  while (!heap.empty()) {
    const auto [d, u] = heap.top();
    heap.pop();
    if (d > dist[u]) continue;
    L.for_neighbours(u, nb, [&](std::uint32_t w, double len) {
      const double nd = d + cost(len, u, w);
      if (nd < dist[w]) {
        dist[w] = nd;
        parent[w] = u;
        if (length != nullptr) (*length)[w] = (*length)[u] + len;
        heap.push({nd, w});
      }
    });
  }
}

/// A smoothed, resampled polyline of voxel centres [m]; endpoints kept.
std::vector<Vec3> smooth(std::vector<Vec3> p, double spacing) {
  for (int it = 0; it < 6 && p.size() > 2; ++it) {
    std::vector<Vec3> q = p;
    for (std::size_t i = 1; i + 1 < p.size(); ++i) q[i] = 0.25 * p[i - 1] + 0.5 * p[i] + 0.25 * p[i + 1];
    p = std::move(q);
  }
  if (p.size() < 2) return p;
  std::vector<double> s(p.size(), 0.0);
  for (std::size_t i = 1; i < p.size(); ++i) s[i] = s[i - 1] + (p[i] - p[i - 1]).norm();
  const double total = s.back();
  const int pieces = std::max(1, static_cast<int>(std::round(total / spacing)));
  std::vector<Vec3> out;
  out.reserve(static_cast<std::size_t>(pieces) + 1);
  std::size_t seg = 0;
  for (int k = 0; k <= pieces; ++k) {
    const double at = total * k / pieces;
    while (seg + 2 < p.size() && s[seg + 1] < at) ++seg;
    const double span = s[seg + 1] - s[seg];
    const double u = span > 0.0 ? std::clamp((at - s[seg]) / span, 0.0, 1.0) : 0.0;
    out.push_back((1.0 - u) * p[seg] + u * p[seg + 1]);
  }
  out.front() = p.front();
  out.back() = p.back();
  return out;
}

/// Moves `x` to the middle of the lumen's cross-section across `tangent` (rays in that plane: the centroid of their
/// wall hits, a few times) and returns the radius there: the nearest wall hit (the largest inscribed circle, as
/// VMTK's maximum inscribed sphere radius). `x` stays when a ray finds no wall or it would move more than `limit`.
double refine_on_mesh(const RayScene& rays, Vec3& x, const Vec3& tangent, double limit) {
  const Vec3 e1 = tangent.unitOrthogonal();
  const Vec3 e2 = tangent.cross(e1);
  const Vec3 start = x;
  double radius = 0.0;
  for (int it = 0; it <= kRefineIterations; ++it) {
    Vec3 centroid = Vec3::Zero();
    double nearest = std::numeric_limits<double>::infinity();
    for (int k = 0; k < kRefineRays; ++k) {
      const double phi = 2.0 * kPi * k / kRefineRays;
      const Vec3 d = std::cos(phi) * e1 + std::sin(phi) * e2;
      const double t = rays.first_hit(x, d);
      if (!std::isfinite(t)) return -1.0;
      centroid += x + t * d;
      nearest = std::min(nearest, t);
    }
    centroid /= kRefineRays;
    radius = nearest;
    if (it == kRefineIterations) break;
    if ((centroid - start).norm() > limit) return radius;
    x = centroid;
  }
  return radius;
}

}  // namespace

AirwayGraph extract_airway_graph(const TriangleMesh& mesh, const CenterlineOptions& options,
                                 CenterlineReport* report_out) {
  const auto started = std::chrono::steady_clock::now();
  validate_mesh(mesh, "centreline");
  if (!(options.spur_factor >= 0.0) || !(options.ball_scale > 0.0) || !(options.ball_margin >= 0.0)) {
    throw InputError("centreline", 0, "options", "spur_factor ≥ 0, ball_scale > 0 and ball_margin ≥ 0");
  }
  CenterlineReport report;
  const Grid grid = choose_grid(mesh, options);
  report.voxel = grid.h;
  report.dims = grid.n;
  const RayScene rays(mesh);
  const Lumen L = lumen_of(grid, voxelise(rays, grid), report);
  report.inside_voxels = L.ijk.size();
  const std::size_t n = L.ijk.size();
  const Neighbours nb;

  // An end of the tree: the voxel geodesically farthest from the widest one.
  const auto widest = static_cast<std::uint32_t>(std::max_element(L.dbf.begin(), L.dbf.end()) - L.dbf.begin());
  std::vector<double> dist;
  std::vector<std::uint32_t> parent;
  dijkstra(L, nb, widest, [](double len, std::uint32_t, std::uint32_t) { return len; }, dist, parent);
  std::uint32_t end = widest;
  for (std::uint32_t v = 0; v < n; ++v) {
    if (std::isfinite(dist[v]) && dist[v] > dist[end]) end = v;
  }
  // Centred paths from that end: step cost length / DBF² (scale-free).
  std::vector<double> along;
  dijkstra(
      L, nb, end,
      [&L](double len, std::uint32_t a, std::uint32_t b) {
        return 0.5 * len * (1.0 / (L.dbf[a] * L.dbf[a]) + 1.0 / (L.dbf[b] * L.dbf[b]));
      },
      dist, parent, &along);

  // TEASAR: the farthest uncovered voxel's path back to the skeleton, covered by balls along it.
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return along[a] > along[b]; });
  std::vector<std::uint8_t> covered(n, 0), skeleton(n, 0);
  std::vector<std::uint32_t> stamp(n, 0), source(n, kNone);
  std::uint32_t iteration = 0;
  // Covers every voxel within ball_scale × R + ball_margin of the path, R at a path voxel p being the largest DBF
  // of the path voxels whose inscribed sphere holds p: in a blind end the path's last voxels lie close to the wall,
  // and their balls take the lumen's radius from the voxels a radius back, so they reach the end's corners.
  std::vector<double> ball_radius(n, 0.0);
  const auto cover = [&](const std::vector<std::uint32_t>& path) {
    ++iteration;
    std::queue<std::uint32_t> queue;
    const std::uint32_t widest_voxel = *std::max_element(
        path.begin(), path.end(), [&](std::uint32_t a, std::uint32_t b) { return L.dbf[a] < L.dbf[b]; });
    const auto window = static_cast<std::ptrdiff_t>(2.0f * (L.dbf[widest_voxel] + 2.0f)) + 1;
    for (std::size_t i = 0; i < path.size(); ++i) {
      const std::uint32_t p = path[i];
      double r = L.dbf[p];
      const auto lo = static_cast<std::size_t>(std::max<std::ptrdiff_t>(0, static_cast<std::ptrdiff_t>(i) - window));
      const auto hi = std::min(path.size(), i + static_cast<std::size_t>(window) + 1);
      for (std::size_t j = lo; j < hi; ++j) {
        const std::uint32_t q = path[j];
        if (L.dbf[q] > r && L.separation(p, q) <= L.dbf[q] + 1.0) r = L.dbf[q];
      }
      ball_radius[p] = options.ball_scale * r + options.ball_margin;
    }
    for (const std::uint32_t p : path) {
      stamp[p] = iteration;
      source[p] = p;
      covered[p] = 1;
      queue.push(p);
    }
    while (!queue.empty()) {
      const std::uint32_t u = queue.front();
      queue.pop();
      const std::uint32_t s = source[u];
      const double ball = ball_radius[s];
      L.for_neighbours(u, nb, [&](std::uint32_t w, double) {
        if (stamp[w] == iteration || L.separation(w, s) > ball) return;
        stamp[w] = iteration;
        source[w] = s;
        covered[w] = 1;
        queue.push(w);
      });
    }
  };
  skeleton[end] = 1;
  cover({end});
  // Each path is traced back only until it enters ground an earlier path's balls cover; it then joins the skeleton
  // voxel whose ball that is, straight across (a second path through a wide lumen would otherwise run beside the
  // first, a voxel apart, to a junction far upstream, and the bifurcation between them would be lost).
  std::vector<std::uint32_t> path, link;
  std::vector<std::uint32_t> skeleton_parent(n, kNone);
  const auto straight = [&](std::uint32_t from, std::uint32_t to, std::vector<std::uint32_t>& out) {
    out.clear();
    const auto& a0 = L.ijk[from];
    const auto& b0 = L.ijk[to];
    const double len = L.separation(from, to);
    const int steps = std::max(1, static_cast<int>(std::ceil(2.0 * len)));
    for (int k = 1; k < steps; ++k) {
      const double u = static_cast<double>(k) / steps;
      const std::uint32_t w = L.at(static_cast<int>(std::lround(a0[0] + u * (b0[0] - a0[0]))),
                                   static_cast<int>(std::lround(a0[1] + u * (b0[1] - a0[1]))),
                                   static_cast<int>(std::lround(a0[2] + u * (b0[2] - a0[2]))));
      if (w == kNone) return false;  // the straight line leaves the lumen
      if (w != to && (out.empty() ? w != from : w != out.back())) out.push_back(w);
    }
    return true;
  };
  for (const std::uint32_t target : order) {
    if (covered[target] != 0 || !std::isfinite(dist[target])) continue;
    path.clear();
    std::uint32_t v = target;
    while (covered[v] == 0 && skeleton[v] == 0) {
      path.push_back(v);
      v = parent[v];
    }
    // v: the first voxel already covered (or on the skeleton); the path so far is the new ground it reaches.
    const double reach = along[target] - along[v];
    std::vector<float> radii;
    for (const std::uint32_t p : path) radii.push_back(L.dbf[p]);
    double own = L.dbf[target];
    if (!radii.empty()) {
      std::nth_element(radii.begin(), radii.begin() + static_cast<std::ptrdiff_t>(radii.size() / 2), radii.end());
      own = radii[radii.size() / 2];
    }
    if (reach < options.spur_factor * own) {
      cover(path);
      ++report.spurs_pruned;
      continue;
    }
    // Join: straight from v to the skeleton voxel whose ball covers it, else along the shortest-path tree.
    std::uint32_t junction = skeleton[v] != 0 ? v : source[v];
    path.push_back(v);
    if (skeleton[v] != 0) {
      path.pop_back();
    } else if (!straight(v, junction, link)) {
      for (std::uint32_t w = parent[v]; ; w = parent[w]) {
        if (skeleton[w] != 0) {
          junction = w;
          break;
        }
        path.push_back(w);
      }
    } else {
      path.insert(path.end(), link.begin(), link.end());
    }
    for (std::size_t i = 0; i < path.size(); ++i) {  // the link may cross the skeleton before its end: join there
      if (skeleton[path[i]] != 0) {
        junction = path[i];
        path.resize(i);
        break;
      }
    }
    cover(path);
    for (std::size_t i = 0; i < path.size(); ++i) {
      skeleton[path[i]] = 1;
      skeleton_parent[path[i]] = i + 1 < path.size() ? path[i + 1] : junction;
    }
  }

  // The skeleton as an undirected tree.
  std::vector<std::vector<std::uint32_t>> adjacent(n);
  for (std::uint32_t v = 0; v < n; ++v) {
    if (skeleton[v] == 0 || v == end) continue;
    adjacent[v].push_back(skeleton_parent[v]);
    adjacent[skeleton_parent[v]].push_back(v);
  }
  // Terminal stubs: a leaf's chain shorter than (1 + spur_factor) × the lumen radius at its junction ends inside
  // the junction's own lumen (the corners of a wide flat end, where TEASAR's first path starts): pruned, repeatedly.
  for (bool pruned = true; pruned;) {
    pruned = false;
    for (std::uint32_t v = 0; v < n; ++v) {
      if (skeleton[v] == 0 || adjacent[v].size() != 1) continue;
      std::vector<std::uint32_t> chain{v};
      std::uint32_t prev = v, cur = adjacent[v][0];
      double length = L.separation(prev, cur);
      while (adjacent[cur].size() == 2) {
        const std::uint32_t next = adjacent[cur][0] == prev ? adjacent[cur][1] : adjacent[cur][0];
        chain.push_back(cur);
        length += L.separation(cur, next);
        prev = cur;
        cur = next;
      }
      if (adjacent[cur].size() < 3 || length >= (1.0 + options.spur_factor) * L.dbf[cur]) continue;
      for (const std::uint32_t c : chain) {
        skeleton[c] = 0;
        adjacent[c].clear();
      }
      auto& at = adjacent[cur];
      at.erase(std::find(at.begin(), at.end(), prev));
      ++report.spurs_pruned;
      pruned = true;
    }
  }
  report.skeleton_voxels = static_cast<std::size_t>(std::count(skeleton.begin(), skeleton.end(), std::uint8_t{1}));

  // The root: the leaf nearest the given point, else the end of the widest terminal branch.
  std::uint32_t root = kNone;
  double best = -std::numeric_limits<double>::infinity();
  for (std::uint32_t v = 0; v < n; ++v) {
    if (skeleton[v] == 0 || adjacent[v].size() != 1) continue;
    double score = 0.0;
    if (options.root) {
      score = -(L.position(v) - *options.root).norm();
    } else {
      std::uint32_t prev = v, cur = adjacent[v][0];
      double widest_here = L.dbf[v];
      while (adjacent[cur].size() == 2) {
        widest_here = std::max(widest_here, static_cast<double>(L.dbf[cur]));
        const std::uint32_t next = adjacent[cur][0] == prev ? adjacent[cur][1] : adjacent[cur][0];
        prev = cur;
        cur = next;
      }
      score = widest_here;
    }
    if (score > best) {
      best = score;
      root = v;
    }
  }

  // Branches: chains between junctions; a chain between two junctions shorter than its own (median) radius joins
  // them into one junction (two side paths that met the skeleton a few voxels apart).
  struct Chain {
    int parent = -1;                  ///< index into chains
    std::vector<std::uint32_t> voxels;  ///< from the junction (or root) to the next junction or leaf
  };
  std::vector<Chain> chains;
  struct Todo {
    int parent;
    std::vector<std::uint32_t> prefix;  ///< voxels from the parent's end up to `from`
    std::uint32_t from, next;
  };
  if (root == kNone) {
    throw InputError("centreline", 0, "voxel",
                     "the skeleton has no end: the voxel (" + std::to_string(1e3 * grid.h) + " mm) is too coarse for "
                     "this lumen");
  }
  std::vector<Todo> todo{{-1, {}, root, adjacent[root].empty() ? root : adjacent[root][0]}};
  while (!todo.empty()) {
    Todo t = std::move(todo.back());
    todo.pop_back();
    Chain c;
    c.parent = t.parent;
    c.voxels = std::move(t.prefix);
    c.voxels.push_back(t.from);
    std::uint32_t prev = t.from, cur = t.next;
    if (cur == prev) break;  // a single-voxel skeleton
    for (;;) {
      c.voxels.push_back(cur);
      if (adjacent[cur].size() != 2) break;
      const std::uint32_t next = adjacent[cur][0] == prev ? adjacent[cur][1] : adjacent[cur][0];
      prev = cur;
      cur = next;
    }
    const std::uint32_t last = c.voxels.back();
    double length = 0.0;
    for (std::size_t i = 1; i < c.voxels.size(); ++i) length += L.separation(c.voxels[i - 1], c.voxels[i]);
    const bool internal = adjacent[last].size() > 2;
    std::vector<float> r;
    for (const std::uint32_t x : c.voxels) r.push_back(L.dbf[x]);
    std::nth_element(r.begin(), r.begin() + static_cast<std::ptrdiff_t>(r.size() / 2), r.end());
    if (internal && t.parent >= 0 && length < r[r.size() / 2]) {
      // Too short to be a branch: its children continue the parent's junction (prefix carries this chain).
      const std::vector<std::uint32_t> prefix(c.voxels.begin(), c.voxels.end() - 1);
      for (const std::uint32_t w : adjacent[last]) {
        if (w == prev) continue;
        todo.push_back({t.parent, prefix, last, w});
      }
      continue;
    }
    chains.push_back(std::move(c));
    const int id = static_cast<int>(chains.size()) - 1;
    if (internal) {
      for (const std::uint32_t w : adjacent[last]) {
        if (w == prev) continue;
        todo.push_back({id, {}, last, w});
      }
    }
  }

  // A blind end's path runs on to the wall (its farthest voxel): the last stretch of one radius is cut, which puts
  // the end where a centreline ends, one radius short of the end wall. Likewise the root's start.
  const auto trim = [&](std::vector<std::uint32_t>& v, bool at_end) {
    if (v.size() < 3) return;
    std::vector<float> r;
    for (const std::uint32_t x : v) r.push_back(L.dbf[x]);
    std::nth_element(r.begin(), r.begin() + static_cast<std::ptrdiff_t>(r.size() / 2), r.end());
    const double radius = r[r.size() / 2];
    if (!at_end) std::reverse(v.begin(), v.end());
    const std::uint32_t tip = v.back();
    while (v.size() > 2 && L.separation(v.back(), tip) < radius) v.pop_back();
    if (!at_end) std::reverse(v.begin(), v.end());
  };
  for (Chain& c : chains) {
    if (adjacent[c.voxels.back()].size() == 1) trim(c.voxels, true);
    if (c.parent < 0 && adjacent[c.voxels.front()].size() == 1) trim(c.voxels, false);
  }

  if (chains.empty()) {
    throw InputError("centreline", 0, "voxel",
                     "the skeleton is a single voxel: the voxel (" + std::to_string(1e3 * grid.h) +
                         " mm) is too coarse for this lumen");
  }

  // Polylines [m], ordered children, refined nodes.
  AirwayGraph graph;
  std::vector<std::vector<Vec3>> lines(chains.size());
  for (std::size_t c = 0; c < chains.size(); ++c) {
    std::vector<Vec3> p;
    for (const std::uint32_t v : chains[c].voxels) p.push_back(L.position(v));
    lines[c] = smooth(std::move(p), 2.0 * grid.h);
  }
  std::vector<std::vector<int>> children(chains.size());
  std::vector<int> roots;
  for (std::size_t c = 0; c < chains.size(); ++c) {
    (chains[c].parent < 0 ? roots : children[static_cast<std::size_t>(chains[c].parent)]).push_back(static_cast<int>(c));
  }
  for (std::size_t c = 0; c < chains.size(); ++c) {
    const auto& line = lines[c];
    const Vec3 axis = (line.back() - line[line.size() >= 3 ? line.size() - 3 : 0]).normalized();
    const Vec3 e1 = axis.unitOrthogonal();
    const Vec3 e2 = axis.cross(e1);
    const auto angle = [&](int child) {
      const auto& cl = lines[static_cast<std::size_t>(child)];
      const Vec3 d = cl[std::min<std::size_t>(2, cl.size() - 1)] - cl.front();
      return std::atan2(d.dot(e2), d.dot(e1));
    };
    std::stable_sort(children[c].begin(), children[c].end(), [&](int a, int b) { return angle(a) < angle(b); });
  }
  // Breadth-first from the root so that add_branch() names children in the sorted order.
  std::vector<std::pair<int, int>> queue;  // (chain, parent branch id)
  for (const int r : roots) queue.push_back({r, -1});
  std::vector<std::uint32_t> end_node(chains.size(), kNone);
  for (std::size_t q = 0; q < queue.size(); ++q) {
    const auto [c, parent_branch] = queue[q];
    const auto& line = lines[static_cast<std::size_t>(c)];
    const auto& vox = chains[static_cast<std::size_t>(c)].voxels;
    std::vector<std::uint32_t> ids;
    for (std::size_t i = 0; i < line.size(); ++i) {
      if (i == 0 && parent_branch >= 0) {
        ids.push_back(end_node[static_cast<std::size_t>(chains[static_cast<std::size_t>(c)].parent)]);
        continue;
      }
      Vec3 x = line[i];
      const bool endpoint = i == 0 || i + 1 == line.size();
      const std::uint32_t near = vox[std::min(vox.size() - 1, i * (vox.size() - 1) / std::max<std::size_t>(1, line.size() - 1))];
      double radius = std::max(0.5, L.dbf[near] - 0.5) * grid.h;
      if (!endpoint) {
        const Vec3 tangent = (line[i + 1] - line[i - 1]).normalized();
        const double r = refine_on_mesh(rays, x, tangent, radius);
        if (r > 0.0) radius = r;
      }
      ids.push_back(add_node(graph, x, radius));
    }
    const int id = add_branch(graph, parent_branch, ids);
    end_node[static_cast<std::size_t>(c)] = ids.back();
    for (const int child : children[static_cast<std::size_t>(c)]) queue.push_back({child, id});
  }
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  if (report_out != nullptr) *report_out = report;
  return graph;
}

namespace {

std::string shape_of(const AirwayGraph& g, int b) {
  std::vector<std::string> kids;
  for (const int c : g.branches[static_cast<std::size_t>(b)].children) kids.push_back(shape_of(g, c));
  std::sort(kids.begin(), kids.end());
  std::string s = "(";
  for (const auto& k : kids) s += k;
  return s + ")";
}

}  // namespace

std::string graph_shape(const AirwayGraph& graph) {
  std::vector<std::string> roots;
  for (const AirwayBranch& b : graph.branches) {
    if (b.parent < 0) roots.push_back(shape_of(graph, b.id));
  }
  std::sort(roots.begin(), roots.end());
  std::string s;
  for (const auto& r : roots) s += r;
  return s;
}

GraphComparison compare_graphs(const AirwayGraph& extracted, const AirwayGraph& reference) {
  GraphComparison c;
  c.same_topology = graph_shape(extracted) == graph_shape(reference);
  c.branches = extracted.branches.size();
  c.reference_branches = reference.branches.size();
  std::vector<double> radius_errors, away;
  std::vector<const AirwayNode*> ends;  // the reference's bifurcations and blind ends
  for (const AirwayBranch& b : reference.branches) {
    ends.push_back(&reference.nodes[b.nodes.front()]);
    ends.push_back(&reference.nodes[b.nodes.back()]);
  }
  for (const AirwayNode& n : extracted.nodes) {
    const CentrelinePoint near = nearest_centreline_point(reference, n.position);
    const double radius = near.radius;
    c.mean_distance += near.distance / radius;
    radius_errors.push_back(std::fabs(n.radius - radius) / radius);
    c.mean_radius_error += radius_errors.back();
    const bool clear = std::all_of(ends.begin(), ends.end(), [&](const AirwayNode* e) {
      return (e->position - n.position).norm() > 2.0 * e->radius;
    });
    if (clear) away.push_back(radius_errors.back());
  }
  if (!away.empty()) {
    std::sort(away.begin(), away.end());
    c.p95_radius_error_away = away[static_cast<std::size_t>(0.95 * static_cast<double>(away.size() - 1))];
  }
  if (!radius_errors.empty()) {
    c.mean_distance /= static_cast<double>(radius_errors.size());
    c.mean_radius_error /= static_cast<double>(radius_errors.size());
    std::sort(radius_errors.begin(), radius_errors.end());
    c.p95_radius_error = radius_errors[static_cast<std::size_t>(0.95 * static_cast<double>(radius_errors.size() - 1))];
  }
  return c;
}

}  // namespace magvine::anatomy
