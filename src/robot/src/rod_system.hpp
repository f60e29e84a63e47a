#pragma once
// The rod solver's unknowns and its block-tridiagonal system, shared by the energy terms (terms/*.hpp) and the
// Newton solver (rod.cpp). Private to the robot module.
//
// Unknowns: per edge j a block of six, the increment δx of node j + 1 (offset 0) and the rotation increment δφ of
// edge j's frame (offset 3; R ← exp([δφ]) R). Node 0 and the clamp frame are fixed (block −1).

#include <array>
#include <cstddef>
#include <span>
#include <vector>

#include <Eigen/Geometry>

#include "magvine/core/eigen_types.hpp"
#include "magvine/magnetics/field_sample.hpp"
#include "magvine/robot/rod.hpp"

namespace magvine::robot::detail {

using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;

/// The midpoint of edge j, where its magnetic loads are sampled.
inline Vec3 edge_midpoint(const RodState& s, std::size_t j) { return 0.5 * (s.x[j] + s.x[j + 1]); }

/// The lumped mass of node i of N [kg]: ρA over half of each edge it ends, ρA·h between two edges of h, half at the
/// tip (node 0 is clamped).
inline double lumped_mass(const RodModel& m, std::size_t i) {
  const int j = static_cast<int>(i);
  const double before = j > 0 ? edge_length(m, j - 1) : 0.0;
  const double after = j < m.edges ? edge_length(m, j) : 0.0;
  return m.mass_per_length * 0.5 * (before + after);
}

/// [v]: the cross-product matrix, [v]u = v × u.
inline Mat3 skew(const Vec3& v) {
  Mat3 s;
  s << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return s;
}

/// vee((Q − Qᵀ)/2): the axial vector of Q's skew part (sin(angle)·axis for a rotation).
inline Vec3 skew_axis(const Mat3& q) { return 0.5 * Vec3(q(2, 1) - q(1, 2), q(0, 2) - q(2, 0), q(1, 0) - q(0, 1)); }

/// exp([φ]) (identity at φ = 0).
inline Mat3 exp_rotation(const Vec3& phi) {
  const double angle = phi.norm();
  return angle > 0.0 ? Mat3(Eigen::AngleAxisd(angle, phi / angle).toRotationMatrix()) : Mat3::Identity();
}

/// The symmetric part of a ⊗ b minus (a·b)I: the Hessian of aᵀ[φ]²b/2 in φ (aᵀ[φ]²b = φᵀ(sym(abᵀ) − a·b I)φ).
inline Mat3 cross_squared(const Vec3& a, const Vec3& b) {
  return 0.5 * (a * b.transpose() + b * a.transpose()) - a.dot(b) * Mat3::Identity();
}

/// Where a 3-vector unknown lives: block (edge) and offset (0: the position of node block+1, 3: the rotation of
/// edge block); block −1 is fixed (x_0, the clamp frame).
struct Slot {
  int block;
  int offset;
};
inline Slot position_slot(int node) { return {node - 1, 0}; }  // node 0 is clamped
inline Slot rotation_slot(int edge) { return {edge, 3}; }

/// Gradient and the block-tridiagonal Hessian: diag[i] = H(i, i), sub[i] = H(i, i − 1). Once factored (BlockFactor),
/// only the lower triangle of each diag[i] is the Hessian's: the upper one holds the factor.
struct System {
  VecX gradient;
  std::vector<Mat6> diag;
  std::vector<Mat6> sub;

  /// `with_hessian` false: the gradient only (the finite-difference columns need no blocks).
  explicit System(int blocks, bool with_hessian = true)
      : gradient(VecX::Zero(6 * blocks)),
        diag(with_hessian ? static_cast<std::size_t>(blocks) : 0, Mat6::Zero()),
        sub(with_hessian ? static_cast<std::size_t>(blocks) : 0, Mat6::Zero()) {}

  void add_gradient(const Slot& s, const Vec3& g) {
    if (s.block >= 0) gradient.segment<3>(6 * s.block + s.offset) += g;
  }
};

/// Gradient of one strain element: `stress` = dW/ds, and ds = Σ P_k dq_k.
template <std::size_t K>
void add_stress(System* sys, const Vec3& stress, const std::array<Slot, K>& slots, const std::array<Mat3, K>& pieces) {
  for (std::size_t k = 0; k < K; ++k) sys->add_gradient(slots[k], pieces[k].transpose() * stress);
}

/// Adds the block H(a, b) of one element to the block-tridiagonal store (a lower-triangle pair lands in `sub`;
/// the upper pair is the transpose of its lower one and skipped; pairs with the clamp are dropped).
inline void add_block(System& sys, const Slot& a, const Slot& b, const Mat3& h) {
  if (a.block < 0 || b.block < 0 || a.block < b.block) return;
  if (a.block == b.block) {
    sys.diag[static_cast<std::size_t>(a.block)].block<3, 3>(a.offset, b.offset) += h;
  } else {
    sys.sub[static_cast<std::size_t>(a.block)].block<3, 3>(a.offset, b.offset) += h;
  }
}

/// Adds the pair H(a, b) = h and H(b, a) = hᵀ of a symmetric element Hessian (a ≠ b).
inline void add_block_pair(System& sys, const Slot& a, const Slot& b, const Mat3& h) {
  add_block(sys, a, b, h);
  add_block(sys, b, a, h.transpose());
}

/// How an edge element sees its two nodes: through the edge vector x_{j+1} − x_j (stretch) or the midpoint (magnets).
enum class EdgeVector { difference, midpoint };

/// The Hessian of an element on (x_j, x_{j+1}, δφ_j) whose energy depends on the nodes through one vector u, given
/// H_uu, H_uφ (rows u) and H_φφ.
inline void add_edge_element(System& sys, int j, EdgeVector u, const Mat3& uu, const Mat3& uphi, const Mat3& phiphi) {
  const double a = u == EdgeVector::difference ? -1.0 : 0.5;  // du/dx_j
  const double b = u == EdgeVector::difference ? 1.0 : 0.5;   // du/dx_{j+1}
  const Slot xa = position_slot(j);
  const Slot xb = position_slot(j + 1);
  const Slot phi = rotation_slot(j);
  add_block(sys, xa, xa, a * a * uu);
  add_block(sys, xb, xb, b * b * uu);
  add_block(sys, xb, xa, a * b * uu);  // sub block (x_j's block is the lower index)
  add_block_pair(sys, xb, phi, b * uphi);
  add_block(sys, phi, xa, a * uphi.transpose());
  add_block(sys, phi, phi, phiphi);
}

/// Central differences of a local gradient g(φ) of one frame's rotation increment (the rotational inertia and the
/// tip moment: one block each, cheap), symmetrised: with world-frame rotation increments the derivative of the
/// gradient differs from the Hessian by an antisymmetric part.
template <class Gradient>
Mat3 local_rotation_hessian(const Gradient& gradient) {
  constexpr double step = 1e-6;
  Mat3 h;
  for (int k = 0; k < 3; ++k) h.col(k) = (gradient(step * Vec3::Unit(k)) - gradient(-step * Vec3::Unit(k))) / (2.0 * step);
  return 0.5 * (h + h.transpose());
}

/// The field at the edge midpoints of one state, sampled on first use: the gradient and the Hessian share one sample
/// per midpoint instead of sampling it again (the field is a pure function of the point). Whoever moves the state
/// resets it.
struct FieldSamples {
  std::vector<magnetics::FieldSample> value;
  std::vector<unsigned char> known;

  /// Forgets every sample (no allocation once sized).
  void reset(std::size_t edges) {
    value.resize(edges);
    known.assign(edges, 0);
  }

  /// B and ∂B/∂x at the midpoint of edge j of `s`.
  const magnetics::FieldSample& at(const RodField& field, const RodState& s, std::size_t j) {
    if (known[j] == 0) {
      value[j] = field(edge_midpoint(s, j));
      known[j] = 1;
    }
    return value[j];
  }
};

/// The inertial terms of one backward-Euler step (step_rod_dynamics), written as an incremental potential: with
/// predictions x̃_i = x_i + Δt v_i and R̃_j = exp(Δt [w_j]) R_j (terms/inertia.hpp).
struct Inertia {
  double dt = 0.0;
  std::vector<Vec3> x;       ///< predicted nodes (x̃_0 unused: clamped)
  std::vector<Mat3> frames;  ///< predicted frames
  std::vector<double> mass;  ///< lumped node masses
  double rotational = 0.0;   ///< J per edge [kg·m²]
};

/// What every energy term reads: the model, the field, the state, the load factor λ of the ramp (which scales the
/// model's loads: magnets, gravity, tip loads; not the wall, anchors and node forces of `constraints`), and the
/// optional parts. `samples`, when given, holds (or receives) the field at this state's edge midpoints.
struct TermContext {
  const RodModel& model;
  const RodField& field;
  const RodState& state;
  double load = 1.0;
  const Inertia* inertia = nullptr;
  const RodConstraints* constraints = nullptr;
  FieldSamples* samples = nullptr;
  /// The iterate a line-search trial moves from (the wall barrier refuses trials whose nodes cross the wall on the
  /// way); null for the iterate itself.
  const RodState* from = nullptr;
  double edge_length = uniform_edge_length(model);  ///< h, once per context (not per edge)
  double tip_length = robot::edge_length(model, model.edges - 1);  ///< the last edge's

  int edges() const { return model.edges; }
  /// The length of edge j.
  double h(int j) const { return j == model.edges - 1 ? tip_length : edge_length; }

  /// The entries of one list of the constraints (RodConstraints::anchors, friction); none without them.
  template <class T>
  std::span<const T> entries(std::vector<T> RodConstraints::*list) const {
    if (constraints == nullptr) return {};
    return (constraints->*list);
  }
};

}  // namespace magvine::robot::detail
