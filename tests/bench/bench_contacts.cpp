// CollisionWorld on the real CT airway lidc0525 (195k triangles, marching cubes, mm in the file): contact queries,
// ray casts and inside/outside tests per second on one thread, and the construction time of the world.
// Target (DESIGN.md): ≥ 500k sphere and capsule contact queries per second against a ~200k-triangle airway.
//
// Query bodies are those of a Ø3 mm vine robot, placed where contacts happen: a uniform random point on the wall
// (triangle picked by area, uniform barycentrics) moved along the inward normal (−n, n the outward normal, into
// tissue) by d ~ U(−0.5 r, 1.2 r), r = 1.5 mm. d < r touches the wall the point came from (d < 0: the axis has
// already crossed it), d ≥ r can only touch a neighbouring wall, so most queries, not all, produce contacts.
// Spheres are centred there; capsules are 2 mm long, centred there, their axis in the tangent plane tilted up to
// ±15° (a vine segment lying along the wall). kBodies bodies are drawn once with a fixed seed and the timed loop
// cycles through them: /random in random order (every query lands elsewhere in the tree; caches cold, since the
// per-triangle tables far exceed L2), /sorted along a Morton curve (coherent sweeps), /hot over 16 of them only
// (the working set stays in cache, so this is the compute cost); spheres also /body: 64-node chains walking along
// the wall 1.5 mm apart, each chain queried 8 times in a row like a robot body over a solver step's iterations,
// and /moving: the same, each pass with every node displaced by its own random offset of up to 0.2 mm (a Newton
// iteration's move). BM_SphereContactsCached runs /body and /moving with one ContactCache per chain node (64, margin
// 0.45 mm, reused from chain to chain): the first pass over a chain refills them, the other seven use them.
// Counters: `hit` = fraction of queries with ≥ 1 contact, `contacts` = contacts per query, `full` = fraction that
// filled the 8-contact span (deepest kept), `triangles` = mesh size.
//
// Rays start at lumen points (kept only where `contains` agrees) in uniform random directions, max 50 mm.
// `contains` is timed on an equal mix of points 0.5–3 mm inside and outside the wall (only those whose nearest wall
// is the one they were moved off); `agree` is the fraction whose answer matches that side, and should be 1.
// Without ../shared/airways (or $MAGVINE_AIRWAYS_DIR) a ~200k-triangle capped tube (Ø18 mm) stands in; the label
// says so.
//
//   cmake --build build --target bench_contacts && build/tests/bench/bench_contacts
//   (filter e.g. --benchmark_filter=Sphere)

#include <benchmark/benchmark.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "magvine/anatomy/breathing.hpp"
#include "magvine/anatomy/collision_world.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/primitives.hpp"
#include "magvine/core/units.hpp"
#include "support/airways.hpp"

namespace {

using magvine::Vec3;
using namespace magvine::anatomy;

constexpr const char* kAirway = "lidc0525_medmpd_p5_airway_mc.stl";
constexpr std::size_t kBodies = 4096;
constexpr double kRadius = 1.5e-3;                      // vine robot Ø3 mm [m]
constexpr double kCapsuleLength = 2e-3;                 // one vine segment [m]
constexpr double kMaxTilt = 15.0 * magvine::kDegToRad;  // capsule axis out of the tangent plane [rad]
constexpr double kRayLength = 50e-3;                    // [m]
constexpr std::size_t kMaxContacts = 8;                 // the caller's span; more distinct contacts keep the deepest

/// The test mesh: the airway when present, otherwise a tube of similar size and triangle count.
struct Scene {
  TriangleMesh mesh;
  std::string label;
  std::vector<double> cumulative_area;  ///< for area-weighted sampling
};

const Scene& scene() {
  static const Scene s = [] {
    Scene out;
    if (const auto path = test::airway_file(kAirway)) {
      out.mesh = import_mesh(*path).mesh;  // mm → m, welded and cleaned
      out.label = "lidc0525";
    } else {
      out.mesh = make_tube({.radius = 9e-3, .length = 0.1, .segments = 256, .rings = 400, .capped = true});
      out.label = "tube (airway absent)";
    }
    double sum = 0.0;
    out.cumulative_area.reserve(out.mesh.triangles.size());
    for (std::size_t t = 0; t < out.mesh.triangles.size(); ++t) {
      sum += 0.5 * area_vector(out.mesh, t).norm();
      out.cumulative_area.push_back(sum);
    }
    return out;
  }();
  return s;
}

const CollisionWorld& world() {
  static const CollisionWorld w(scene().mesh);
  return w;
}

/// A uniform random point on the wall and the outward unit normal there.
struct WallPoint {
  Vec3 point;
  Vec3 normal;
};

class WallSampler {
 public:
  explicit WallSampler(std::uint64_t seed) : m_rng(seed) {}

  WallPoint sample() {
    const Scene& s = scene();
    for (;;) {
      const double a = std::uniform_real_distribution<double>(0.0, s.cumulative_area.back())(m_rng);
      const auto it = std::upper_bound(s.cumulative_area.begin(), s.cumulative_area.end(), a);
      const auto t = static_cast<std::size_t>(std::min<std::ptrdiff_t>(
          it - s.cumulative_area.begin(), static_cast<std::ptrdiff_t>(s.cumulative_area.size()) - 1));
      const Vec3 n = area_vector(s.mesh, t);
      if (!(n.norm() > 0.0)) continue;
      double u = unit(), v = unit();
      if (u + v > 1.0) {
        u = 1.0 - u;
        v = 1.0 - v;
      }
      const Vec3& p0 = corner(s.mesh, t, 0);
      const Vec3 p = p0 + u * (corner(s.mesh, t, 1) - p0) + v * (corner(s.mesh, t, 2) - p0);
      return {p, n.normalized()};
    }
  }

  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(m_rng); }
  double unit() { return uniform(0.0, 1.0); }

  Vec3 direction() {
    std::normal_distribution<double> n01;
    for (;;) {
      const Vec3 d(n01(m_rng), n01(m_rng), n01(m_rng));
      if (d.norm() > 1e-6) return d.normalized();
    }
  }

 private:
  std::mt19937_64 m_rng;
};

/// Axis point of a body near the wall: wall point moved inward (−n) by U(−0.5 r, 1.2 r).
Vec3 near_wall(WallSampler& rng, const WallPoint& w) {
  return w.point - rng.uniform(-0.5 * kRadius, 1.2 * kRadius) * w.normal;
}

/// The nearest wall point to p (the wall lies within 5 mm of every point asked about here).
NearTriangle nearest_wall(const Vec3& p) {
  std::array<NearTriangle, 1> near;
  if (world().triangles_within(p, 5e-3, near) == 0) throw std::runtime_error("bench_contacts: no wall within 5 mm");
  return near[0];
}

/// Robot-like bodies: kChains chains of kChainNodes sphere centres 1.5 mm apart, each walking along the wall in a
/// fixed direction (every step re-projected onto the nearest wall point, CollisionWorld::triangles_within), each centre
/// near the wall as above. The /body order visits every chain kIterations times in a row, as a solver's Newton
/// iterations query the nodes of one robot body.
constexpr std::size_t kChains = 64;
constexpr std::size_t kChainNodes = 64;
constexpr std::size_t kIterations = 8;
constexpr double kNodeSpacing = 1.5e-3;  // [m]

const std::vector<Vec3>& body_centres() {
  static const std::vector<Vec3> c = [] {
    WallSampler rng(16);
    std::vector<Vec3> out;
    out.reserve(kChains * kChainNodes);
    for (std::size_t chain = 0; chain < kChains; ++chain) {
      WallPoint w = rng.sample();
      Vec3 heading = rng.direction();
      for (std::size_t node = 0; node < kChainNodes; ++node) {
        out.push_back(near_wall(rng, w));
        Vec3 tangent = heading - heading.dot(w.normal) * w.normal;
        if (!(tangent.norm() > 1e-9)) tangent = w.normal.unitOrthogonal();
        const NearTriangle next = nearest_wall(w.point + kNodeSpacing * tangent.normalized());
        const Vec3 n = area_vector(scene().mesh, next.triangle);
        heading = next.point - w.point;
        w = {next.point, n.norm() > 0.0 ? Vec3(n.normalized()) : w.normal};
      }
    }
    return out;
  }();
  return c;
}

/// body_centres() in the /body visiting order, each pass of a chain with every node moved by its own random offset
/// of length up to kJitter (uniform in the ball).
constexpr double kJitter = 0.2e-3;  // [m]

const std::vector<Vec3>& moving_centres() {
  static const std::vector<Vec3> c = [] {
    WallSampler rng(17);
    const std::vector<Vec3>& body = body_centres();
    std::vector<Vec3> out;
    out.reserve(kChains * kIterations * kChainNodes);
    for (std::size_t chain = 0; chain < kChains; ++chain) {
      for (std::size_t pass = 0; pass < kIterations; ++pass) {
        for (std::size_t node = 0; node < kChainNodes; ++node) {
          out.push_back(body[chain * kChainNodes + node] + kJitter * std::cbrt(rng.unit()) * rng.direction());
        }
      }
    }
    return out;
  }();
  return c;
}

const std::vector<Vec3>& sphere_centres() {
  static const std::vector<Vec3> c = [] {
    WallSampler rng(11);
    std::vector<Vec3> out;
    out.reserve(kBodies);
    while (out.size() < kBodies) out.push_back(near_wall(rng, rng.sample()));
    return out;
  }();
  return c;
}

struct Segment {
  Vec3 a;
  Vec3 b;
};

const std::vector<Segment>& capsules() {
  static const std::vector<Segment> c = [] {
    WallSampler rng(12);
    std::vector<Segment> out;
    out.reserve(kBodies);
    while (out.size() < kBodies) {
      const WallPoint w = rng.sample();
      const Vec3 m = near_wall(rng, w);
      // Random tangent direction, tilted out of the tangent plane by up to kMaxTilt.
      Vec3 tangent = rng.direction();
      tangent -= tangent.dot(w.normal) * w.normal;
      if (!(tangent.norm() > 1e-6)) continue;
      tangent.normalize();
      const double tilt = rng.uniform(-kMaxTilt, kMaxTilt);
      const Vec3 axis = std::cos(tilt) * tangent + std::sin(tilt) * w.normal;
      out.push_back({m - 0.5 * kCapsuleLength * axis, m + 0.5 * kCapsuleLength * axis});
    }
    return out;
  }();
  return c;
}

/// Lumen points 0.5–3 mm inside the wall that `contains` confirms, and random unit directions.
struct Rays {
  std::vector<Vec3> origins;
  std::vector<Vec3> directions;
};

const Rays& rays() {
  static const Rays r = [] {
    WallSampler rng(13);
    Rays out;
    while (out.origins.size() < kBodies) {
      const WallPoint w = rng.sample();
      const Vec3 p = w.point - rng.uniform(0.5e-3, 3e-3) * w.normal;
      if (!world().contains(p)) continue;
      out.origins.push_back(p);
      out.directions.push_back(rng.direction());
    }
    return out;
  }();
  return r;
}

/// Points 0.5–3 mm off the wall, alternately inside and outside, with the side they were placed on. Only points
/// whose nearest wall is the one they came from (distance ≥ 0.99 × offset) are kept: an offset point that passed
/// another wall (a thin branch, a neighbouring branch) has no known side.
struct SidedPoints {
  std::vector<Vec3> points;
  std::vector<bool> inside;
};

const SidedPoints& sided_points() {
  static const SidedPoints s = [] {
    WallSampler rng(14);
    SidedPoints out;
    while (out.points.size() < kBodies) {
      const bool in = out.points.size() % 2 == 0;
      const WallPoint w = rng.sample();
      const double offset = rng.uniform(0.5e-3, 3e-3);
      const Vec3 p = w.point + (in ? -offset : offset) * w.normal;
      if (nearest_wall(p).distance < 0.99 * offset) continue;
      out.points.push_back(p);
      out.inside.push_back(in);
    }
    return out;
  }();
  return s;
}

/// In which order the timed loop visits the precomputed bodies.
enum class Order {
  kRandom,  ///< a fixed random permutation: every query lands elsewhere in the tree (cold caches)
  kSorted,  ///< along a Morton curve: consecutive queries are neighbours (spatially coherent sweeps)
  kHot,     ///< kHotBodies of them cycled: the working set stays in cache, so this is the compute cost
  kBody,    ///< body_centres(): each chain kIterations times in a row, then the next chain
  kMoving,  ///< moving_centres() in their order: as kBody, each pass moved a little
};

constexpr std::uint32_t kHotBodies = 16;  // ~6k triangles touched, ~1 MB: about L2

/// 30-bit Morton code of p in the mesh's bounding box (10 bits per axis).
std::uint32_t morton(const Vec3& p, const Aabb& box) {
  const Vec3 u = ((p - box.min).array() / (box.max - box.min).array()).cwiseMax(0.0).cwiseMin(1.0);
  std::uint32_t code = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const auto q = static_cast<std::uint32_t>(u[axis] * 1023.0);
    for (std::uint32_t bit = 0; bit < 10; ++bit) {
      code |= ((q >> bit) & 1u) << (3 * bit + static_cast<std::uint32_t>(axis));
    }
  }
  return code;
}

/// Visiting order of bodies whose positions are `keys`.
std::vector<std::uint32_t> visit_order(const std::vector<Vec3>& keys, Order order) {
  if (order == Order::kMoving) {
    std::vector<std::uint32_t> out(keys.size());
    for (std::uint32_t k = 0; k < out.size(); ++k) out[k] = k;
    return out;
  }
  if (order == Order::kBody) {
    std::vector<std::uint32_t> out;
    for (std::size_t chain = 0; chain < keys.size() / kChainNodes; ++chain) {
      for (std::size_t pass = 0; pass < kIterations; ++pass) {
        for (std::size_t node = 0; node < kChainNodes; ++node) {
          out.push_back(static_cast<std::uint32_t>(chain * kChainNodes + node));
        }
      }
    }
    return out;
  }
  std::vector<std::uint32_t> out(keys.size());
  for (std::uint32_t k = 0; k < out.size(); ++k) out[k] = k;
  std::shuffle(out.begin(), out.end(), std::mt19937_64(15));
  if (order == Order::kHot) out.resize(std::min<std::size_t>(out.size(), kHotBodies));
  if (order == Order::kSorted) {
    const Aabb box = bounding_box(scene().mesh);
    std::vector<std::uint32_t> code(keys.size());
    for (std::size_t k = 0; k < keys.size(); ++k) code[k] = morton(keys[k], box);
    std::stable_sort(out.begin(), out.end(), [&](std::uint32_t a, std::uint32_t b) { return code[a] < code[b]; });
  }
  return out;
}

void common_counters(benchmark::State& state) {
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
  state.SetLabel(scene().label);
  state.counters["triangles"] = static_cast<double>(world().stats().triangles);
}

double per_iteration(const benchmark::State& state, double total) {
  return state.iterations() > 0 ? total / static_cast<double>(state.iterations()) : 0.0;
}

const std::vector<Vec3>& centres_for(Order order) {
  if (order == Order::kBody) return body_centres();
  if (order == Order::kMoving) return moving_centres();
  return sphere_centres();
}

void BM_SphereContacts(benchmark::State& state, Order order) {
  const CollisionWorld& w = world();
  const std::vector<Vec3>& c = centres_for(order);
  const std::vector<std::uint32_t> o = visit_order(c, order);
  std::array<Contact, kMaxContacts> out{};
  std::size_t i = 0, hits = 0, contacts = 0, full = 0;
  for (auto _ : state) {
    const std::size_t n = w.sphere_contacts(c[o[i]], kRadius, out);
    benchmark::DoNotOptimize(out.data());
    contacts += n;
    hits += n > 0 ? 1 : 0;
    full += n == out.size() ? 1 : 0;
    i = i + 1 == o.size() ? 0 : i + 1;
  }
  common_counters(state);
  state.counters["hit"] = per_iteration(state, static_cast<double>(hits));
  state.counters["contacts"] = per_iteration(state, static_cast<double>(contacts));
  state.counters["full"] = per_iteration(state, static_cast<double>(full));
}

/// The wall barrier's query (robot/terms/wall_barrier.hpp) without its NearCache: the triangles within r + d̂ of a
/// node centre, nearest first, the nearest 32 kept (the barrier keeps them all), with r = 1.5 mm and d̂ = 0.2 mm.
/// Counter `near` = triangles within reach per query.
void BM_TrianglesWithin(benchmark::State& state, Order order) {
  const CollisionWorld& w = world();
  const std::vector<Vec3>& c = centres_for(order);
  const std::vector<std::uint32_t> o = visit_order(c, order);
  std::array<NearTriangle, 32> out{};
  std::size_t i = 0, near = 0;
  for (auto _ : state) {
    near += w.triangles_within(c[o[i]], kRadius + 0.2e-3, out);
    benchmark::DoNotOptimize(out.data());
    i = i + 1 == o.size() ? 0 : i + 1;
  }
  common_counters(state);
  state.counters["near"] = per_iteration(state, static_cast<double>(near));
}

/// As BM_SphereContacts (/body or /moving), each chain node with its own ContactCache.
constexpr double kCacheMargin = 0.45e-3;  // [m]: above 2·kJitter, the farthest two passes of a node lie apart
constexpr std::size_t kCacheCapacity = 256;

void BM_SphereContactsCached(benchmark::State& state, Order order) {
  const CollisionWorld& w = world();
  const std::vector<Vec3>& c = centres_for(order);
  const std::vector<std::uint32_t> o = visit_order(c, order);
  std::vector<ContactCache> caches;
  for (std::size_t k = 0; k < kChainNodes; ++k) caches.emplace_back(kCacheMargin, kCacheCapacity);
  std::array<Contact, kMaxContacts> out{};
  std::size_t i = 0, hits = 0, contacts = 0, full = 0;
  for (auto _ : state) {
    const std::size_t n = w.sphere_contacts(c[o[i]], kRadius, out, caches[i % kChainNodes]);
    benchmark::DoNotOptimize(out.data());
    contacts += n;
    hits += n > 0 ? 1 : 0;
    full += n == out.size() ? 1 : 0;
    i = i + 1 == o.size() ? 0 : i + 1;
  }
  common_counters(state);
  state.counters["hit"] = per_iteration(state, static_cast<double>(hits));
  state.counters["contacts"] = per_iteration(state, static_cast<double>(contacts));
  state.counters["full"] = per_iteration(state, static_cast<double>(full));
}

void BM_CapsuleContacts(benchmark::State& state, Order order) {
  const CollisionWorld& w = world();
  const std::vector<Segment>& c = capsules();
  std::vector<Vec3> mid;
  for (const Segment& s : c) mid.push_back(0.5 * (s.a + s.b));
  const std::vector<std::uint32_t> o = visit_order(mid, order);
  std::array<Contact, kMaxContacts> out{};
  std::size_t i = 0, hits = 0, contacts = 0, full = 0;
  for (auto _ : state) {
    const Segment& s = c[o[i]];
    const std::size_t n = w.capsule_contacts(s.a, s.b, kRadius, out);
    benchmark::DoNotOptimize(out.data());
    contacts += n;
    hits += n > 0 ? 1 : 0;
    full += n == out.size() ? 1 : 0;
    i = i + 1 == o.size() ? 0 : i + 1;
  }
  common_counters(state);
  state.counters["hit"] = per_iteration(state, static_cast<double>(hits));
  state.counters["contacts"] = per_iteration(state, static_cast<double>(contacts));
  state.counters["full"] = per_iteration(state, static_cast<double>(full));
}

void BM_RayCast(benchmark::State& state, Order order) {
  const CollisionWorld& w = world();
  const Rays& r = rays();
  const std::vector<std::uint32_t> o = visit_order(r.origins, order);
  std::size_t i = 0, hits = 0;
  double distance = 0.0;
  for (auto _ : state) {
    const auto hit = w.ray_cast(r.origins[o[i]], r.directions[o[i]], kRayLength);
    benchmark::DoNotOptimize(hit);
    if (hit) {
      ++hits;
      distance += hit->distance;
    }
    i = i + 1 == o.size() ? 0 : i + 1;
  }
  common_counters(state);
  state.counters["hit"] = per_iteration(state, static_cast<double>(hits));
  state.counters["mean_dist_mm"] = hits > 0 ? 1e3 * distance / static_cast<double>(hits) : 0.0;
}

void BM_Contains(benchmark::State& state) {
  const CollisionWorld& w = world();
  const SidedPoints& p = sided_points();
  const std::vector<std::uint32_t> o = visit_order(p.points, Order::kRandom);
  std::size_t i = 0, agree = 0;
  for (auto _ : state) {
    const bool in = w.contains(p.points[o[i]]);
    benchmark::DoNotOptimize(in);
    agree += in == p.inside[o[i]] ? 1 : 0;
    i = i + 1 == o.size() ? 0 : i + 1;
  }
  common_counters(state);
  state.counters["agree"] = per_iteration(state, static_cast<double>(agree));
}

/// A breathing airway's two poses (the default field at two phases) for the refit benchmarks.
struct BreathingPoses {
  std::array<std::vector<Vec3>, 2> moved;
};
const BreathingPoses& breathing_poses() {
  static const BreathingPoses poses = [] {
    const TriangleMesh& mesh = scene().mesh;
    BreathingParams b;
    const Aabb box = bounding_box(mesh);
    b.entry = Vec3(0.5 * (box.min.x() + box.max.x()), 0.5 * (box.min.y() + box.max.y()), box.max.z());
    b.carina = b.entry - 0.1 * (box.max.z() - box.min.z()) * Vec3::UnitZ();
    BreathingPoses out;
    for (std::size_t k = 0; k < 2; ++k) {
      out.moved[k].resize(mesh.vertices.size());
      for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        out.moved[k][i] = mesh.vertices[i] + breathing_displacement(b, mesh.vertices[i], 0.9 + 1.3 * k);
      }
    }
    return out;
  }();
  return poses;
}

/// The per-step refit of a breathing airway (CollisionWorld::refit, issue 31 item 4; target ≤ 1 ms for ~200 k
/// triangles): the world refitted to two poses in turn (the displacement field's evaluation is the caller's, not
/// timed). The triangles' records are filled lazily by the queries after it (BM_RefitThenContacts).
void BM_Refit(benchmark::State& state) {
  const TriangleMesh& mesh = scene().mesh;
  CollisionWorld w(mesh);
  const BreathingPoses& poses = breathing_poses();
  std::size_t k = 0;
  for (auto _ : state) {
    w.refit(poses.moved[k]);
    k ^= 1;
    benchmark::DoNotOptimize(&w);
  }
  state.SetLabel(scene().label);
  state.counters["triangles"] = static_cast<double>(mesh.triangles.size());
}

/// A body's contact queries after each refit: 200 spheres of 2 mm at the inside points nearest one of them (a
/// stretch of airway, as a vine's nodes are), refit + queries (`refit` 1) against the same queries on a world that
/// does not move (`refit` 0): the difference less BM_Refit is what filling the touched triangles' records costs.
void BM_RefitThenContacts(benchmark::State& state) {
  const bool refit = state.range(0) != 0;
  const TriangleMesh& mesh = scene().mesh;
  CollisionWorld w(mesh);
  const BreathingPoses& poses = breathing_poses();
  const SidedPoints& p = sided_points();
  std::vector<Vec3> inside;
  for (std::size_t i = 0; i < p.points.size(); ++i) {
    if (p.inside[i]) inside.push_back(p.points[i]);
  }
  const Vec3 seed = inside.front();
  std::sort(inside.begin(), inside.end(),
            [&](const Vec3& a, const Vec3& b) { return (a - seed).squaredNorm() < (b - seed).squaredNorm(); });
  inside.resize(std::min<std::size_t>(200, inside.size()));
  if (!refit) w.refit(poses.moved[0]);  // the same pose the refitting runs start from, its records filled once
  std::array<Contact, 8> out{};
  std::size_t k = 0;
  std::size_t contacts = 0;
  for (auto _ : state) {
    if (refit) {
      w.refit(poses.moved[k]);
      k ^= 1;
    }
    for (const Vec3& x : inside) contacts += w.sphere_contacts(x, 2e-3, out);
  }
  benchmark::DoNotOptimize(contacts);
  state.SetLabel(scene().label);
  state.counters["queries"] = static_cast<double>(inside.size());
}

void BM_BuildWorld(benchmark::State& state) {
  const TriangleMesh& mesh = scene().mesh;
  for (auto _ : state) {
    const CollisionWorld w(mesh);
    benchmark::DoNotOptimize(&w);
  }
  const CollisionWorldStats& s = world().stats();
  state.SetLabel(scene().label);
  state.counters["triangles"] = static_cast<double>(s.triangles);
  state.counters["ridge_edges"] = static_cast<double>(s.ridge_edges);
  state.counters["boundary_edges"] = static_cast<double>(s.boundary_edges);
  state.counters["degenerate"] = static_cast<double>(s.degenerate_triangles);
}

BENCHMARK_CAPTURE(BM_SphereContacts, random, Order::kRandom)->Unit(benchmark::kNanosecond);
BENCHMARK_CAPTURE(BM_SphereContacts, sorted, Order::kSorted)->Unit(benchmark::kNanosecond);
BENCHMARK_CAPTURE(BM_SphereContacts, hot, Order::kHot)->Unit(benchmark::kNanosecond);
BENCHMARK_CAPTURE(BM_SphereContacts, body, Order::kBody)->Unit(benchmark::kNanosecond);
BENCHMARK_CAPTURE(BM_SphereContacts, moving, Order::kMoving)->Unit(benchmark::kNanosecond);
BENCHMARK_CAPTURE(BM_TrianglesWithin, random, Order::kRandom)->Unit(benchmark::kNanosecond);
BENCHMARK_CAPTURE(BM_TrianglesWithin, body, Order::kBody)->Unit(benchmark::kNanosecond);
BENCHMARK_CAPTURE(BM_TrianglesWithin, moving, Order::kMoving)->Unit(benchmark::kNanosecond);
BENCHMARK_CAPTURE(BM_SphereContactsCached, body, Order::kBody)->Unit(benchmark::kNanosecond);
BENCHMARK_CAPTURE(BM_SphereContactsCached, moving, Order::kMoving)->Unit(benchmark::kNanosecond);
BENCHMARK_CAPTURE(BM_CapsuleContacts, random, Order::kRandom)->Unit(benchmark::kNanosecond);
BENCHMARK_CAPTURE(BM_CapsuleContacts, sorted, Order::kSorted)->Unit(benchmark::kNanosecond);
BENCHMARK_CAPTURE(BM_CapsuleContacts, hot, Order::kHot)->Unit(benchmark::kNanosecond);
BENCHMARK_CAPTURE(BM_RayCast, random, Order::kRandom)->Unit(benchmark::kNanosecond);
BENCHMARK_CAPTURE(BM_RayCast, hot, Order::kHot)->Unit(benchmark::kNanosecond);
BENCHMARK(BM_Contains)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_BuildWorld)->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK(BM_Refit)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RefitThenContacts)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
