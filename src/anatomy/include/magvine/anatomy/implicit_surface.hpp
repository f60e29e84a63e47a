#pragma once
/// Meshing of implicit surfaces: a signed-distance-like field (negative inside the lumen, positive in tissue) becomes
/// a watertight, manifold, indexed triangle mesh with outward normals (pointing from negative to positive values).
///
/// Method: marching tetrahedra on a regular grid. Every grid cube is split into the same 6 Kuhn tetrahedra (all
/// sharing the cube's (0,0,0)–(1,1,1) diagonal), so neighbouring cubes split their common faces identically, no case
/// is ambiguous and the surface is closed and manifold by construction. A value exactly at the iso-level counts as
/// outside (a nudge to +0). Iso-vertices sit on grid edges and are welded by edge, so the mesh is indexed. The grid
/// is evaluated sparsely: it is visited in blocks, and a field bounds itself over each block so that blocks away from
/// the surface are skipped and, for a composite field, only the primitives that matter in a block are evaluated.

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "magvine/anatomy/triangle_mesh.hpp"

namespace magvine::anatomy {

/// What a field's bound over a box says.
enum class BoxSign {
  kOutside,  ///< the value is certainly > 0 on the whole closed box: no surface in it
  kInside,   ///< the value is certainly < 0 on the whole closed box: no surface in it
  kMixed,    ///< the surface may cross the box
};

/// Indices of the parts of a field that can matter in a box (a composite field's primitives); opaque to the mesher.
using FieldCandidates = std::vector<std::uint32_t>;

/// A scalar field, negative inside. Contract: value() at a point must not depend on which box (and candidate list)
/// it is evaluated with, bit for bit, because neighbouring blocks evaluate their shared grid points separately.
class ImplicitField {
 public:
  virtual ~ImplicitField() = default;
  /// A box containing every point where the field is negative [m].
  virtual Aabb bounds() const = 0;
  /// Bounds the field over `box`. `within` is the candidate list of an enclosing box already classified kMixed,
  /// or null for "all parts". On kMixed, `candidates` receives the parts value() needs inside `box`.
  virtual BoxSign classify(const Aabb& box, const FieldCandidates* within, FieldCandidates& candidates) const = 0;
  /// Field value at `p` [m, or the field's own unit], a point of a box classify() called kMixed with `candidates`.
  virtual double value(const Vec3& p, std::span<const std::uint32_t> candidates) const = 0;
};

/// Any function with a Lipschitz bound L (|f(p) − f(q)| ≤ L·|p − q|; a signed distance has L = 1): the box test
/// evaluates the centre and compares with L × half-diagonal.
class LipschitzField final : public ImplicitField {
 public:
  /// `f`: field, negative inside; `bounds`: box holding all negative values [m]; `lipschitz` > 0.
  LipschitzField(std::function<double(const Vec3&)> f, const Aabb& bounds, double lipschitz = 1.0);
  Aabb bounds() const override { return m_bounds; }
  BoxSign classify(const Aabb& box, const FieldCandidates* within, FieldCandidates& candidates) const override;
  double value(const Vec3& p, std::span<const std::uint32_t> candidates) const override;

 private:
  std::function<double(const Vec3&)> m_f;
  Aabb m_bounds;
  double m_lipschitz;
};

/// Round cone (tapered capsule): the union of spheres of radius ra at a and rb at b and the cone tangent to both.
/// With ra = rb it is a capsule.
struct RoundCone {
  Vec3 a = Vec3::Zero();  ///< first end centre [m]
  Vec3 b = Vec3::Zero();  ///< second end centre [m]
  double ra = 0.0;        ///< radius at a [m]
  double rb = 0.0;        ///< radius at b [m]
};

/// Box with rounded edges and corners, in its own frame: |local| ≤ half_extents, then inflated by `rounding`.
struct RoundedBox {
  Vec3 centre = Vec3::Zero();               ///< [m]
  Mat3 axes = Mat3::Identity();             ///< columns: the box's local x, y, z axes in world (orthonormal)
  Vec3 half_extents = Vec3::Zero();         ///< of the core box before rounding [m], each ≥ 0
  double rounding = 0.0;                    ///< rounding radius added around the core box [m]
};

/// Exact signed distance to a round cone [m] (Quilez's formulation, see implicit_surface.cpp).
double signed_distance(const RoundCone& cone, const Vec3& p);
/// Exact signed distance to a rounded box [m].
double signed_distance(const RoundedBox& box, const Vec3& p);

/// A lumen made of exact-distance primitives: blend groups of lumen parts, minus `obstacles` (sharp difference),
/// intersected with half-spaces (flat cuts, e.g. an airway entry):
///   f = max( min_G U_G(p), max_j −o_j(p), max_h (p − q_h)·n_h ),
///   U_G = m − (Σ_i g_i − max_i g_i),  m = min_{i∈G} d_i,  g_i = (k_i/4)·max(0, 1 − (d_i − m)/k_i)²,
/// where k_i is part i's blend radius. For two parts with equal k, U_G is the quadratic polynomial smooth minimum
/// (Quilez, "smooth minimum", 2013): m − k·h²/4. Written this way it is symmetric in the parts and exactly
/// unchanged by parts with d_i ≥ m + k_i (g_i = 0), so per-block candidate lists give bit-identical values. The
/// blend only lowers U_G, by at most Σ k_i/4 over the parts that meet. Groups combine with a sharp minimum, so
/// parts blend only with the parts of their own groups: a branch is put in the group of its parent's junction and
/// in the group of its own, and branches that merely pass near each other do not grow bridges.
class CompositeSdf final : public ImplicitField {
 public:
  /// Adds a lumen part to blend group `group` with blend radius `blend` ≥ 0 [m] (0: sharp union). A part may be
  /// added to several groups (add it once per group). The parts of one group must be added one after the other
  /// (std::invalid_argument otherwise).
  void add_lumen(const RoundCone& cone, double blend, int group = 0);
  void add_lumen(const RoundedBox& box, double blend, int group = 0);
  /// Carves a solid obstacle out of the lumen (sharp).
  void add_obstacle(const RoundCone& cone);
  void add_obstacle(const RoundedBox& box);
  /// Keeps only the side (p − point)·normal ≤ 0 (normal need not be unit; it is normalised).
  void add_clip(const Vec3& point, const Vec3& normal);

  /// Field value using all parts (slow for many parts; the mesher uses candidate lists) [m].
  double value_at(const Vec3& p) const;

  Aabb bounds() const override;
  BoxSign classify(const Aabb& box, const FieldCandidates* within, FieldCandidates& candidates) const override;
  double value(const Vec3& p, std::span<const std::uint32_t> candidates) const override;

 private:
  struct Part {
    enum class Kind { kCone, kBox, kPlane } kind = Kind::kCone;
    enum class Role { kLumen, kObstacle, kClip } role = Role::kLumen;
    RoundCone cone;
    RoundedBox box;
    Vec3 point = Vec3::Zero();   // plane
    Vec3 normal = Vec3::UnitZ();  // plane, unit
    double blend = 0.0;
    int group = 0;
  };
  void add_lumen_part(Part part, int group);
  double part_distance(const Part& part, const Vec3& p) const;
  std::vector<Part> m_parts;
  std::vector<int> m_groups_used;  // lumen groups in the order they were opened
};

/// Meshing parameters.
struct ImplicitMeshOptions {
  double spacing = 0.4e-3;  ///< grid spacing h [m]; edge lengths are about h
  int block_cells = 8;      ///< cells per block edge (sparse evaluation unit), ≥ 2
  int super_blocks = 4;     ///< blocks per super-block edge (coarse culling level), ≥ 1
};

/// Counters from one meshing run.
struct ImplicitMeshStats {
  std::size_t grid_cells = 0;         ///< cells of the full (virtual) grid
  std::size_t blocks_total = 0;       ///< blocks of the full grid
  std::size_t blocks_evaluated = 0;   ///< blocks classified kMixed and evaluated
  std::size_t field_evaluations = 0;  ///< value() calls
};

/// Meshes the zero level set of `field` on a grid with spacing options.spacing covering field.bounds() plus a margin
/// of two cells. The result is closed, manifold, indexed, oriented with normals towards positive values, and
/// deterministic (same field and options → identical mesh). Features thinner than about one spacing may be lost or
/// pinched: choose the spacing below half the thinnest wall or lumen. Throws std::invalid_argument for spacing ≤ 0
/// or a grid of more than 2^21 cells along an axis.
TriangleMesh mesh_implicit(const ImplicitField& field, const ImplicitMeshOptions& options,
                           ImplicitMeshStats* stats = nullptr);

}  // namespace magvine::anatomy
