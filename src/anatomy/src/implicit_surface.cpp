#include "magvine/anatomy/implicit_surface.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <unordered_map>
#include <utility>

namespace magvine::anatomy {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Absolute slack [m] on the box tests, far above rounding of distances of order 1 m (1e-16) and far below any
// geometric feature: a part is dropped or a box skipped only when the bound holds with this margin.
constexpr double kBoundSlack = 1e-12;

// Iso-vertices are kept at least this fraction of an edge away from the edge's grid points, so that no triangle
// degenerates when the surface passes through (or exactly at) a grid point. It moves a vertex by at most
// 1e-3 × spacing, well below the O(h²/R) interpolation error.
constexpr double kEdgeClamp = 1e-3;

double box_half_diagonal(const Aabb& box) { return 0.5 * (box.max - box.min).norm(); }
Vec3 box_centre(const Aabb& box) { return 0.5 * (box.min + box.max); }

}  // namespace

// ---------------------------------------------------------------------------------------------------------------
// Primitive distances.

double signed_distance(const RoundCone& cone, const Vec3& p) {
  // Inigo Quilez, "Round cone - exact" (iquilezles.org/articles/distfunctions), in double precision. When one end
  // sphere contains the other the shape is that sphere.
  const Vec3 ba = cone.b - cone.a;
  const double l2 = ba.squaredNorm();
  const double rr = cone.ra - cone.rb;
  if (rr * rr >= l2) {
    return cone.ra >= cone.rb ? (p - cone.a).norm() - cone.ra : (p - cone.b).norm() - cone.rb;
  }
  const double a2 = l2 - rr * rr;
  const double il2 = 1.0 / l2;
  const Vec3 pa = p - cone.a;
  const double y = pa.dot(ba);
  const double z = y - l2;
  const double x2 = (pa * l2 - ba * y).squaredNorm();
  const double y2 = y * y * l2;
  const double z2 = z * z * l2;
  const double k = (rr > 0.0 ? 1.0 : (rr < 0.0 ? -1.0 : 0.0)) * rr * rr * x2;
  const double sign_z = z > 0.0 ? 1.0 : (z < 0.0 ? -1.0 : 0.0);
  const double sign_y = y > 0.0 ? 1.0 : (y < 0.0 ? -1.0 : 0.0);
  if (sign_z * a2 * z2 > k) return std::sqrt(x2 + z2) * il2 - cone.rb;
  if (sign_y * a2 * y2 < k) return std::sqrt(x2 + y2) * il2 - cone.ra;
  return (std::sqrt(x2 * a2 * il2) + y * rr) * il2 - cone.ra;
}

double signed_distance(const RoundedBox& box, const Vec3& p) {
  // Exact box distance in the box frame, minus the rounding radius.
  const Vec3 local = box.axes.transpose() * (p - box.centre);
  const Vec3 q = local.cwiseAbs() - box.half_extents;
  return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0) - box.rounding;
}

// ---------------------------------------------------------------------------------------------------------------
// LipschitzField

LipschitzField::LipschitzField(std::function<double(const Vec3&)> f, const Aabb& bounds, double lipschitz)
    : m_f(std::move(f)), m_bounds(bounds), m_lipschitz(lipschitz) {
  if (!m_f || !(lipschitz > 0.0)) throw std::invalid_argument("LipschitzField: needs a function and lipschitz > 0");
}

BoxSign LipschitzField::classify(const Aabb& box, const FieldCandidates* /*within*/,
                                 FieldCandidates& candidates) const {
  candidates.clear();
  const double v = m_f(box_centre(box));
  const double reach = m_lipschitz * box_half_diagonal(box) + kBoundSlack;
  if (v > reach) return BoxSign::kOutside;
  if (v < -reach) return BoxSign::kInside;
  return BoxSign::kMixed;
}

double LipschitzField::value(const Vec3& p, std::span<const std::uint32_t> /*candidates*/) const { return m_f(p); }

// ---------------------------------------------------------------------------------------------------------------
// CompositeSdf

void CompositeSdf::add_lumen_part(Part part, int group) {
  if (m_groups_used.empty() || m_groups_used.back() != group) {
    if (std::find(m_groups_used.begin(), m_groups_used.end(), group) != m_groups_used.end()) {
      throw std::invalid_argument("CompositeSdf: the parts of a blend group must be added one after the other");
    }
    m_groups_used.push_back(group);
  }
  part.role = Part::Role::kLumen;
  part.group = group;
  part.blend = std::max(0.0, part.blend);
  m_parts.push_back(part);
}

void CompositeSdf::add_lumen(const RoundCone& cone, double blend, int group) {
  Part part;
  part.kind = Part::Kind::kCone;
  part.cone = cone;
  part.blend = blend;
  add_lumen_part(part, group);
}

void CompositeSdf::add_lumen(const RoundedBox& box, double blend, int group) {
  Part part;
  part.kind = Part::Kind::kBox;
  part.box = box;
  part.blend = blend;
  add_lumen_part(part, group);
}

void CompositeSdf::add_obstacle(const RoundCone& cone) {
  Part part;
  part.kind = Part::Kind::kCone;
  part.role = Part::Role::kObstacle;
  part.cone = cone;
  m_parts.push_back(part);
}

void CompositeSdf::add_obstacle(const RoundedBox& box) {
  Part part;
  part.kind = Part::Kind::kBox;
  part.role = Part::Role::kObstacle;
  part.box = box;
  m_parts.push_back(part);
}

void CompositeSdf::add_clip(const Vec3& point, const Vec3& normal) {
  Part part;
  part.kind = Part::Kind::kPlane;
  part.role = Part::Role::kClip;
  part.point = point;
  part.normal = normal.normalized();
  m_parts.push_back(part);
}

double CompositeSdf::part_distance(const Part& part, const Vec3& p) const {
  switch (part.kind) {
    case Part::Kind::kCone: return signed_distance(part.cone, p);
    case Part::Kind::kBox: return signed_distance(part.box, p);
    case Part::Kind::kPlane: return (p - part.point).dot(part.normal);
  }
  return kInf;
}

double CompositeSdf::value_at(const Vec3& p) const {
  FieldCandidates all(m_parts.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<std::uint32_t>(i);
  return value(p, all);
}

Aabb CompositeSdf::bounds() const {
  // The lumen lies inside the union of the lumen parts (blending only adds material within k/4 of two parts that
  // meet, and k/4 < the part's own reach is covered by padding with the blend radius).
  Aabb box{Vec3::Constant(kInf), Vec3::Constant(-kInf)};
  bool any = false;
  for (const Part& part : m_parts) {
    if (part.role != Part::Role::kLumen) continue;
    any = true;
    Vec3 lo;
    Vec3 hi;
    if (part.kind == Part::Kind::kCone) {
      lo = (part.cone.a - Vec3::Constant(part.cone.ra)).cwiseMin(part.cone.b - Vec3::Constant(part.cone.rb));
      hi = (part.cone.a + Vec3::Constant(part.cone.ra)).cwiseMax(part.cone.b + Vec3::Constant(part.cone.rb));
    } else {
      // Extent of a rotated box: Σ |axis column| × half extent, plus rounding.
      const Vec3 reach = part.box.axes.cwiseAbs() * part.box.half_extents + Vec3::Constant(part.box.rounding);
      lo = part.box.centre - reach;
      hi = part.box.centre + reach;
    }
    lo -= Vec3::Constant(part.blend);
    hi += Vec3::Constant(part.blend);
    box.min = box.min.cwiseMin(lo);
    box.max = box.max.cwiseMax(hi);
  }
  if (!any) return Aabb{};
  return box;
}

BoxSign CompositeSdf::classify(const Aabb& box, const FieldCandidates* within, FieldCandidates& candidates) const {
  candidates.clear();
  const Vec3 c = box_centre(box);
  const double rho = box_half_diagonal(box);
  const std::size_t count = within != nullptr ? within->size() : m_parts.size();
  const auto part_index = [&](std::size_t k) -> std::uint32_t {
    return within != nullptr ? (*within)[k] : static_cast<std::uint32_t>(k);
  };

  // Each part's value at the centre; every exact distance lies within ±rho of it over the box.
  std::vector<double> centre_value(count);
  double union_hi = kInf;  // upper bound of min_G U_G over the box: U_G ≤ m_G ≤ any member's distance
  for (std::size_t k = 0; k < count; ++k) {
    const Part& part = m_parts[part_index(k)];
    centre_value[k] = part_distance(part, c);
    if (part.role == Part::Role::kLumen) union_hi = std::min(union_hi, centre_value[k] + rho);
  }
  if (union_hi == kInf) return BoxSign::kOutside;  // no lumen part can reach this box

  // Per blend group (its parts are contiguous): parts with d_i ≥ m_G + k_i everywhere in the box have g_i = 0
  // there and are dropped (the part attaining m_G never is, so m_G stays exact); a group whose lower bound exceeds
  // union_hi never attains the minimum over groups and is dropped whole.
  std::vector<char> keep(count, 0);
  double union_lo = kInf;
  for (std::size_t k = 0; k < count;) {
    const Part& first = m_parts[part_index(k)];
    if (first.role != Part::Role::kLumen) {
      ++k;
      continue;
    }
    // The group's parts among the considered ones: k .. end, skipping obstacles and clips in between.
    std::size_t end = k;
    double group_hi = kInf;
    for (std::size_t j = k; j < count; ++j) {
      const Part& part = m_parts[part_index(j)];
      if (part.role != Part::Role::kLumen) continue;
      if (part.group != first.group) break;
      group_hi = std::min(group_hi, centre_value[j] + rho);
      end = j + 1;
    }
    double group_lo = kInf;
    double blend_sum = 0.0;
    for (std::size_t j = k; j < end; ++j) {
      const Part& part = m_parts[part_index(j)];
      if (part.role != Part::Role::kLumen) continue;
      const double lo = centre_value[j] - rho;
      if (lo >= group_hi + part.blend * (1.0 + 1e-9) + kBoundSlack) continue;
      keep[j] = 1;
      group_lo = std::min(group_lo, lo);
      blend_sum += 0.25 * part.blend;
    }
    group_lo -= blend_sum;  // U_G ≥ m_G − Σ k_i/4 over the parts that can blend here
    if (group_lo > union_hi + kBoundSlack) {
      for (std::size_t j = k; j < end; ++j) {
        if (m_parts[part_index(j)].role == Part::Role::kLumen) keep[j] = 0;
      }
    } else {
      union_lo = std::min(union_lo, group_lo);
    }
    k = end;
  }

  // Obstacles and clips enter through an exact max: drop those that stay below the union on the whole box.
  double field_lo = union_lo;
  double field_hi = union_hi;
  for (std::size_t k = 0; k < count; ++k) {
    const Part& part = m_parts[part_index(k)];
    if (part.role == Part::Role::kLumen) continue;
    const double v = part.role == Part::Role::kObstacle ? -centre_value[k] : centre_value[k];
    field_lo = std::max(field_lo, v - rho);
    field_hi = std::max(field_hi, v + rho);
    keep[k] = v + rho + kBoundSlack > union_lo ? 1 : 0;
  }
  if (field_lo > kBoundSlack) return BoxSign::kOutside;
  if (field_hi < -kBoundSlack) return BoxSign::kInside;
  for (std::size_t k = 0; k < count; ++k) {
    if (keep[k] != 0) candidates.push_back(part_index(k));
  }
  return BoxSign::kMixed;
}

double CompositeSdf::value(const Vec3& p, std::span<const std::uint32_t> candidates) const {
  // Distances of all candidates (stack buffer for the usual few, heap beyond).
  constexpr std::size_t kBuffer = 64;
  std::array<double, kBuffer> stack_distance{};
  std::vector<double> heap_distance;
  double* distance = stack_distance.data();
  if (candidates.size() > kBuffer) {
    heap_distance.resize(candidates.size());
    distance = heap_distance.data();
  }
  double cut = -kInf;
  for (std::size_t k = 0; k < candidates.size(); ++k) {
    const Part& part = m_parts[candidates[k]];
    distance[k] = part_distance(part, p);
    if (part.role == Part::Role::kObstacle) cut = std::max(cut, -distance[k]);
    if (part.role == Part::Role::kClip) cut = std::max(cut, distance[k]);
  }
  // Blend groups: U_G = m − (Σ g_i − max g_i), summed in candidate (= part index) order so that parts with
  // g_i = 0, present or not, leave the sum bit-identical; then the exact minimum over groups.
  double u = kInf;
  for (std::size_t k = 0; k < candidates.size();) {
    const Part& first = m_parts[candidates[k]];
    if (first.role != Part::Role::kLumen) {
      ++k;
      continue;
    }
    std::size_t end = k;
    double m = kInf;
    for (std::size_t j = k; j < candidates.size(); ++j) {
      const Part& part = m_parts[candidates[j]];
      if (part.role != Part::Role::kLumen) continue;
      if (part.group != first.group) break;
      m = std::min(m, distance[j]);
      end = j + 1;
    }
    double sum = 0.0;
    double largest = 0.0;
    for (std::size_t j = k; j < end; ++j) {
      const Part& part = m_parts[candidates[j]];
      if (part.role != Part::Role::kLumen || !(part.blend > 0.0)) continue;
      const double s = 1.0 - (distance[j] - m) / part.blend;
      if (s <= 0.0) continue;
      const double g = 0.25 * part.blend * s * s;
      sum += g;
      largest = std::max(largest, g);
    }
    u = std::min(u, m - (sum - largest));
    k = end;
  }
  return std::max(u, cut);
}

// ---------------------------------------------------------------------------------------------------------------
// Marching tetrahedra

namespace {

// The 6 Kuhn tetrahedra of a cube: paths 0 → e_p → e_p + e_q → (1,1,1) for the 6 axis orders (p, q, r). Cube
// corner c has offset (c & 1, (c >> 1) & 1, (c >> 2) & 1). Orientation: det(e_p, e_q, e_r) = parity of (p, q, r).
struct KuhnTet {
  std::array<int, 4> corner;
  int orientation;  // +1: det(v1 − v0, v2 − v0, v3 − v0) > 0
};

constexpr std::array<KuhnTet, 6> make_kuhn_tets() {
  constexpr std::array<std::array<int, 3>, 6> orders{{{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}}};
  std::array<KuhnTet, 6> tets{};
  for (std::size_t t = 0; t < 6; ++t) {
    const auto& o = orders[t];
    const int c1 = 1 << o[0];
    const int c2 = c1 | (1 << o[1]);
    tets[t].corner = {0, c1, c2, 7};
    int inversions = 0;
    for (int i = 0; i < 3; ++i) {
      for (int j = i + 1; j < 3; ++j) inversions += o[static_cast<std::size_t>(i)] > o[static_cast<std::size_t>(j)] ? 1 : 0;
    }
    tets[t].orientation = inversions % 2 == 0 ? 1 : -1;
  }
  return tets;
}

constexpr std::array<KuhnTet, 6> kKuhnTets = make_kuhn_tets();

// Parity (+1 / −1) of a permutation of {0, 1, 2, 3}.
int permutation_sign(const std::array<int, 4>& perm) {
  int inversions = 0;
  for (int i = 0; i < 4; ++i) {
    for (int j = i + 1; j < 4; ++j) inversions += perm[static_cast<std::size_t>(i)] > perm[static_cast<std::size_t>(j)] ? 1 : 0;
  }
  return inversions % 2 == 0 ? 1 : -1;
}

class TetMesher {
 public:
  TetMesher(const Vec3& origin, double h) : m_origin(origin), m_h(h) {}

  // Processes one cube with global lower corner (i, j, k), corner values and global point ids.
  void cube(const std::array<std::int64_t, 3>& lower, const std::array<double, 8>& value,
            const std::array<std::uint64_t, 8>& id) {
    for (const KuhnTet& tet : kKuhnTets) tetrahedron(lower, tet, value, id);
  }

  TriangleMesh take() { return std::move(m_mesh); }

 private:
  Vec3 position(const std::array<std::int64_t, 3>& lower, int corner) const {
    return {m_origin.x() + m_h * static_cast<double>(lower[0] + (corner & 1)),
            m_origin.y() + m_h * static_cast<double>(lower[1] + ((corner >> 1) & 1)),
            m_origin.z() + m_h * static_cast<double>(lower[2] + ((corner >> 2) & 1))};
  }

  // Welded vertex on the grid edge between cube corners a and b (one inside, one outside).
  std::uint32_t edge_vertex(const std::array<std::int64_t, 3>& lower, int a, int b, const std::array<double, 8>& value,
                            const std::array<std::uint64_t, 8>& id) {
    // Kuhn edges join corners whose offsets are ordered componentwise, so the lower id is the componentwise-lower
    // point and (lower id, offset code) names the edge uniquely.
    if (id[static_cast<std::size_t>(a)] > id[static_cast<std::size_t>(b)]) std::swap(a, b);
    const int code = b ^ a;  // offset of b from a, since a's bits are a subset of b's
    const std::uint64_t key = id[static_cast<std::size_t>(a)] * 8U + static_cast<std::uint64_t>(code);
    const auto [it, inserted] = m_edges.try_emplace(key, static_cast<std::uint32_t>(m_mesh.vertices.size()));
    if (inserted) {
      const double fa = value[static_cast<std::size_t>(a)];
      const double fb = value[static_cast<std::size_t>(b)];
      double t = fa / (fa - fb);  // zero of the linear interpolant from a to b; signs differ, so fa ≠ fb
      t = std::clamp(t, kEdgeClamp, 1.0 - kEdgeClamp);
      const Vec3 pa = position(lower, a);
      const Vec3 pb = position(lower, b);
      m_mesh.vertices.push_back(pa + t * (pb - pa));
    }
    return it->second;
  }

  void tetrahedron(const std::array<std::int64_t, 3>& lower, const KuhnTet& tet, const std::array<double, 8>& value,
                   const std::array<std::uint64_t, 8>& id) {
    // Inside = negative; a value of exactly 0 counts as outside.
    const auto is_inside = [&](int v) {
      return value[static_cast<std::size_t>(tet.corner[static_cast<std::size_t>(v)])] < 0.0;
    };
    int inside = 0;
    for (int v = 0; v < 4; ++v) inside += is_inside(v) ? 1 : 0;
    if (inside == 0 || inside == 4) return;
    // Order the tet's vertices as (apex group, rest): the lone vertex first when it is alone (1 inside or 1
    // outside), else the two inside ones first. Then make the ordering positively oriented by swapping its last
    // two entries, which always belong to the same group.
    const bool lone_outside = inside == 3;
    std::array<int, 4> perm{};
    std::size_t next = 0;
    for (int v = 0; v < 4; ++v) {
      if (is_inside(v) != lone_outside) perm[next++] = v;
    }
    for (int v = 0; v < 4; ++v) {
      if (is_inside(v) == lone_outside) perm[next++] = v;
    }
    if (permutation_sign(perm) * tet.orientation < 0) std::swap(perm[2], perm[3]);
    std::array<int, 4> c{};
    for (std::size_t v = 0; v < 4; ++v) c[v] = tet.corner[static_cast<std::size_t>(perm[v])];
    const auto e = [&](int p, int q) {
      return edge_vertex(lower, c[static_cast<std::size_t>(p)], c[static_cast<std::size_t>(q)], value, id);
    };
    // With (c0, c1, c2, c3) positively oriented, the triangle on edges (c0c1, c0c2, c0c3) has its normal pointing
    // away from c0 whatever the edge parameters t: det(a, b − a, c − a) = t1·t2·t3·det(c1 − c0, c2 − c0, c3 − c0).
    if (inside == 1) {
      m_mesh.triangles.push_back({e(0, 1), e(0, 2), e(0, 3)});  // away from the inside apex: outward
    } else if (inside == 3) {
      m_mesh.triangles.push_back({e(0, 1), e(0, 3), e(0, 2)});  // apex outside: reversed, towards it
    } else {
      // Inside {c0, c1}, outside {c2, c3}: quad on edges c0c2, c0c3, c1c3, c1c2 (cyclic), outward for a positive
      // ordering (checked on the unit tet; the sign cannot change since a triangle of the quad never degenerates,
      // and each triangle is exact for some linear field with these edge parameters).
      m_mesh.triangles.push_back({e(0, 2), e(0, 3), e(1, 3)});
      m_mesh.triangles.push_back({e(0, 2), e(1, 3), e(1, 2)});
    }
  }

  Vec3 m_origin;
  double m_h;
  TriangleMesh m_mesh;
  std::unordered_map<std::uint64_t, std::uint32_t> m_edges;
};

}  // namespace

TriangleMesh mesh_implicit(const ImplicitField& field, const ImplicitMeshOptions& options, ImplicitMeshStats* stats) {
  const double h = options.spacing;
  if (!(h > 0.0) || !std::isfinite(h)) throw std::invalid_argument("mesh_implicit: spacing must be > 0");
  if (options.block_cells < 2 || options.super_blocks < 1) {
    throw std::invalid_argument("mesh_implicit: block_cells must be >= 2 and super_blocks >= 1");
  }
  const Aabb bounds = field.bounds();
  const std::int64_t bc = options.block_cells;
  const std::int64_t sb = options.super_blocks;
  constexpr std::int64_t kPad = 2;  // cells of margin around the bounds, so the outer grid layer is outside
  constexpr std::int64_t kMaxCells = std::int64_t{1} << 21;

  // Grid: cells per axis rounded up to whole blocks.
  std::array<std::int64_t, 3> blocks{};
  std::array<std::int64_t, 3> cells{};
  std::array<std::int64_t, 3> points{};
  const Vec3 origin = bounds.min - Vec3::Constant(static_cast<double>(kPad) * h);
  for (int a = 0; a < 3; ++a) {
    const double extent = bounds.max[a] - bounds.min[a];
    if (!std::isfinite(extent) || extent < 0.0) throw std::invalid_argument("mesh_implicit: field bounds are invalid");
    const double need = std::ceil(extent / h) + 2.0 * kPad;
    if (need > static_cast<double>(kMaxCells)) throw std::invalid_argument("mesh_implicit: grid too large; increase spacing");
    const auto n = static_cast<std::int64_t>(need);
    blocks[static_cast<std::size_t>(a)] = (n + bc - 1) / bc;
    cells[static_cast<std::size_t>(a)] = blocks[static_cast<std::size_t>(a)] * bc;
    points[static_cast<std::size_t>(a)] = cells[static_cast<std::size_t>(a)] + 1;
  }
  ImplicitMeshStats local_stats;
  local_stats.grid_cells = static_cast<std::size_t>(cells[0] * cells[1] * cells[2]);
  local_stats.blocks_total = static_cast<std::size_t>(blocks[0] * blocks[1] * blocks[2]);

  const auto point_position = [&](std::int64_t i, std::int64_t j, std::int64_t k) {
    return Vec3(origin.x() + h * static_cast<double>(i), origin.y() + h * static_cast<double>(j),
                origin.z() + h * static_cast<double>(k));
  };
  const auto point_id = [&](std::int64_t i, std::int64_t j, std::int64_t k) {
    return static_cast<std::uint64_t>(i + points[0] * (j + points[1] * k));
  };
  const auto box_of = [&](std::int64_t i0, std::int64_t j0, std::int64_t k0, std::int64_t i1, std::int64_t j1,
                          std::int64_t k1) { return Aabb{point_position(i0, j0, k0), point_position(i1, j1, k1)}; };

  TetMesher mesher(origin, h);
  const std::int64_t np = bc + 1;
  std::vector<double> values(static_cast<std::size_t>(np * np * np));
  FieldCandidates super_candidates;
  FieldCandidates block_candidates;
  const std::array<std::int64_t, 3> supers{(blocks[0] + sb - 1) / sb, (blocks[1] + sb - 1) / sb,
                                           (blocks[2] + sb - 1) / sb};

  for (std::int64_t sk = 0; sk < supers[2]; ++sk) {
    for (std::int64_t sj = 0; sj < supers[1]; ++sj) {
      for (std::int64_t si = 0; si < supers[0]; ++si) {
        // Super-block range in blocks.
        const std::int64_t b0[3] = {si * sb, sj * sb, sk * sb};
        const std::int64_t b1[3] = {std::min(b0[0] + sb, blocks[0]), std::min(b0[1] + sb, blocks[1]),
                                    std::min(b0[2] + sb, blocks[2])};
        const Aabb super_box = box_of(b0[0] * bc, b0[1] * bc, b0[2] * bc, b1[0] * bc, b1[1] * bc, b1[2] * bc);
        const BoxSign super_sign = field.classify(super_box, nullptr, super_candidates);
        const bool super_on_boundary = b0[0] == 0 || b0[1] == 0 || b0[2] == 0 || b1[0] == blocks[0] ||
                                       b1[1] == blocks[1] || b1[2] == blocks[2];
        if (super_sign == BoxSign::kInside && super_on_boundary) {
          throw std::logic_error("mesh_implicit: field is negative outside its bounds()");
        }
        if (super_sign != BoxSign::kMixed) continue;
        for (std::int64_t bk = b0[2]; bk < b1[2]; ++bk) {
          for (std::int64_t bj = b0[1]; bj < b1[1]; ++bj) {
            for (std::int64_t bi = b0[0]; bi < b1[0]; ++bi) {
              const std::int64_t i0 = bi * bc;
              const std::int64_t j0 = bj * bc;
              const std::int64_t k0 = bk * bc;
              const Aabb box = box_of(i0, j0, k0, i0 + bc, j0 + bc, k0 + bc);
              const BoxSign sign = field.classify(box, &super_candidates, block_candidates);
              const bool on_grid_boundary = bi == 0 || bj == 0 || bk == 0 || bi + 1 == blocks[0] ||
                                            bj + 1 == blocks[1] || bk + 1 == blocks[2];
              if (sign == BoxSign::kInside && on_grid_boundary) {
                throw std::logic_error("mesh_implicit: field is negative outside its bounds()");
              }
              if (sign != BoxSign::kMixed) continue;
              ++local_stats.blocks_evaluated;
              // Values at the block's grid points.
              for (std::int64_t c = 0; c < np; ++c) {
                for (std::int64_t b = 0; b < np; ++b) {
                  for (std::int64_t a = 0; a < np; ++a) {
                    const std::int64_t gi = i0 + a;
                    const std::int64_t gj = j0 + b;
                    const std::int64_t gk = k0 + c;
                    double v = field.value(point_position(gi, gj, gk), block_candidates);
                    const bool outer = gi == 0 || gj == 0 || gk == 0 || gi == cells[0] || gj == cells[1] ||
                                       gk == cells[2];
                    if (outer && v < 0.0) {
                      throw std::logic_error("mesh_implicit: field is negative outside its bounds()");
                    }
                    values[static_cast<std::size_t>(a + np * (b + np * c))] = v;
                  }
                }
              }
              local_stats.field_evaluations += static_cast<std::size_t>(np * np * np);
              // Cells.
              for (std::int64_t c = 0; c < bc; ++c) {
                for (std::int64_t b = 0; b < bc; ++b) {
                  for (std::int64_t a = 0; a < bc; ++a) {
                    std::array<double, 8> v{};
                    std::array<std::uint64_t, 8> id{};
                    int negatives = 0;
                    for (int corner = 0; corner < 8; ++corner) {
                      const std::int64_t da = corner & 1;
                      const std::int64_t db = (corner >> 1) & 1;
                      const std::int64_t dc = (corner >> 2) & 1;
                      v[static_cast<std::size_t>(corner)] =
                          values[static_cast<std::size_t>((a + da) + np * ((b + db) + np * (c + dc)))];
                      id[static_cast<std::size_t>(corner)] = point_id(i0 + a + da, j0 + b + db, k0 + c + dc);
                      negatives += v[static_cast<std::size_t>(corner)] < 0.0 ? 1 : 0;
                    }
                    if (negatives == 0 || negatives == 8) continue;
                    mesher.cube({i0 + a, j0 + b, k0 + c}, v, id);
                  }
                }
              }
            }
          }
        }
      }
    }
  }
  if (stats != nullptr) *stats = local_stats;
  return mesher.take();
}

}  // namespace magvine::anatomy
