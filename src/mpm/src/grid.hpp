#pragma once
// Internal to the MPM module: the grid machinery the explicit step (mpm.cpp) and the implicit step (implicit.cpp)
// share — stencils, the grid box and its slabs, the particle transfers, the grid nodes' boundary conditions.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Eigenvalues>

#include "magvine/mpm/mpm.hpp"

namespace magvine::mpm::detail {

constexpr int kSlabCells = 4;           // a particle writes 3 nodes along an axis: slabs 4 cells apart never share one
constexpr double kMaxJ = 100.0;         // |det F| beyond this is an explosion, not a deformation
constexpr double kMaxCellsPerStep = 1;  // a particle moving a whole cell in one step has broken the CFL bound
constexpr std::int64_t kParallelMin = 4096;  // below this many items a loop runs on one thread (fork cost)

constexpr std::int64_t kBlock = 4096;  // sums run over fixed blocks, then in order: the same for any thread count

/// Σ_k f(k) over [0, n) as per-block partial sums added in block order (deterministic for any thread count).
template <class Fn>
double ordered_sum(std::int64_t n, Fn&& f) {
  const std::int64_t blocks = (n + kBlock - 1) / kBlock;
  std::vector<double> part(static_cast<std::size_t>(blocks), 0.0);
#pragma omp parallel for schedule(static) if (blocks > 1)
  for (std::int64_t b = 0; b < blocks; ++b) {
    double s = 0.0;
    for (std::int64_t k = b * kBlock; k < std::min(n, (b + 1) * kBlock); ++k) s += f(k);
    part[static_cast<std::size_t>(b)] = s;
  }
  double total = 0.0;
  for (double s : part) total += s;
  return total;
}

/// Σ_k a_k · b_k over node vectors (ordered_sum: deterministic for any thread count).
template <int D>
double node_dot(const std::vector<VecD<D>>& a, const std::vector<VecD<D>>& b) {
  return ordered_sum(static_cast<std::int64_t>(a.size()),
                     [&](std::int64_t k) { return a[static_cast<std::size_t>(k)].dot(b[static_cast<std::size_t>(k)]); });
}

/// out = a + s b over node vectors (out may alias a).
template <int D>
void node_axpy(const std::vector<VecD<D>>& a, double s, const std::vector<VecD<D>>& b, std::vector<VecD<D>>& out) {
  const auto n = static_cast<std::int64_t>(a.size());
#pragma omp parallel for schedule(static) if (n > kParallelMin)
  for (std::int64_t k = 0; k < n; ++k) {
    const auto u = static_cast<std::size_t>(k);
    out[u] = a[u] + s * b[u];
  }
}

/// The largest |a_k|.
template <int D>
double node_max_norm(const std::vector<VecD<D>>& a) {
  double m = 0.0;
  for (const VecD<D>& x : a) m = std::max(m, x.norm());
  return m;
}

/// z = A⁻¹ r for node vectors through a sparse factor over the unknown nodes: node k's D entries sit at index[k]·D
/// (index −1: not an unknown, z_k = 0). `solver` is any Eigen sparse solver with rows() and solve().
template <int D, class Solver>
void solve_on_unknowns(const Solver& solver, const std::vector<std::int64_t>& index, const std::vector<VecD<D>>& r,
                       std::vector<VecD<D>>& z) {
  Eigen::VectorXd rhs(solver.rows());
  for (std::size_t k = 0; k < r.size(); ++k) {
    if (index[k] >= 0) rhs.template segment<D>(index[k] * D) = r[k];
  }
  const Eigen::VectorXd x = solver.solve(rhs);
  for (std::size_t k = 0; k < r.size(); ++k) {
    z[k] = index[k] >= 0 ? VecD<D>(x.template segment<D>(index[k] * D)) : VecD<D>::Zero();
  }
}

/// The implicit steps' inexact Newton direction: x ≈ −H⁻¹ grad by conjugate gradients preconditioned by
/// `precondition(r, z)` (z = M⁻¹ r), with `hessian_times(p, q)` (q = H p), to a relative residual `eta` or `max_it`
/// iterations; stops at negative curvature (then the preconditioned steepest descent if it came first). r, z, p, q
/// are scratch of grad's size. Returns the iterations.
template <int D, class HessianTimes, class Precondition>
long preconditioned_cg(const std::vector<VecD<D>>& grad, double eta, long max_it, HessianTimes&& hessian_times,
                       Precondition&& precondition, std::vector<VecD<D>>& x, std::vector<VecD<D>>& r,
                       std::vector<VecD<D>>& z, std::vector<VecD<D>>& p, std::vector<VecD<D>>& q) {
  const std::size_t n = grad.size();
  for (std::size_t k = 0; k < n; ++k) {
    x[k].setZero();
    r[k] = -grad[k];
  }
  precondition(r, z);
  p = z;
  double rz = node_dot<D>(r, z);
  const double r0 = std::sqrt(node_dot<D>(r, r));
  long it = 0;
  while (it < max_it) {
    ++it;
    hessian_times(p, q);
    const double pq = node_dot<D>(p, q);
    if (!(pq > 0.0)) {  // negative curvature: keep what CG has, or descend along the preconditioned gradient
      if (it == 1) x = z;
      break;
    }
    const double a = rz / pq;
    node_axpy<D>(x, a, p, x);
    node_axpy<D>(r, -a, q, r);
    if (std::sqrt(node_dot<D>(r, r)) <= eta * r0) break;
    precondition(r, z);
    const double rz_next = node_dot<D>(r, z);
    const double beta = rz_next / rz;
    rz = rz_next;
    for (std::size_t k = 0; k < n; ++k) p[k] = z[k] + beta * p[k];
  }
  return it;
}

/// Backtracking (Armijo) line search of the implicit steps from v along dir: α = 1, ½, ¼, … (at most 30 halvings)
/// until E(v + α dir) ≤ E(v) + 1e-4 α min(slope, 0) + 1e-13 magnitude() (E's round-off: near the solution the decrease
/// is below what E can resolve). Leaves the last trial point in `trial` and its energy in `found`; returns α, or 0 when
/// no step decreased E.
template <int D, class Energy, class Magnitude>
double backtracking_line_search(const std::vector<VecD<D>>& v, const std::vector<VecD<D>>& dir, double energy,
                                double slope, Energy&& energy_at, Magnitude&& magnitude, std::vector<VecD<D>>& trial,
                                double& found) {
  constexpr double kArmijo = 1e-4;
  constexpr int kMaxHalvings = 30;
  double alpha = 1.0;
  for (int h = 0; h < kMaxHalvings; ++h, alpha *= 0.5) {
    node_axpy<D>(v, alpha, dir, trial);
    found = energy_at(trial);
    if (found <= energy + kArmijo * alpha * std::min(slope, 0.0) + 1e-13 * magnitude()) return alpha;
  }
  return 0.0;
}

/// The tangent ∂P/∂F of elastic_stress at F, column by column (the implicit steps' Hessian); with `project`, its
/// negative eigenvalues set to zero (projected Newton: a compressed Neo-Hookean's tangent is indefinite).
template <int D>
Eigen::Matrix<double, D * D, D * D> stress_tangent(const Material& mat, const MatD<D>& f, Plane plane, bool project) {
  Eigen::Matrix<double, D * D, D * D> t;
  for (int col = 0; col < D * D; ++col) {
    MatD<D> unit = MatD<D>::Zero();
    unit.data()[col] = 1.0;
    const MatD<D> dp = elastic_stress_differential<D>(mat, f, unit, plane);
    t.col(col) = Eigen::Map<const Eigen::Matrix<double, D * D, 1>>(dp.data());
  }
  if (!project) return t;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, D * D, D * D>> eig(0.5 * (t + t.transpose()));
  if (eig.eigenvalues().minCoeff() < 0.0) {
    t = eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).asDiagonal() * eig.eigenvectors().transpose();
  }
  return t;
}

template <int D>
using Index = Eigen::Matrix<std::int64_t, D, 1>;
/// Quadratic B-spline weights and the base node of a particle (eq 3.2).
template <int D>
struct Stencil {
  Index<D> base;
  VecD<D> fx;  // x/δx − base, in [0.5, 1.5)
  std::array<std::array<double, 3>, D> w;

  Stencil(const VecD<D>& x, double inv_dx) {
    for (int a = 0; a < D; ++a) {
      const double s = x[a] * inv_dx;
      base[a] = static_cast<std::int64_t>(std::floor(s - 0.5));
      fx[a] = s - static_cast<double>(base[a]);
      w[a][0] = 0.5 * (1.5 - fx[a]) * (1.5 - fx[a]);
      w[a][1] = 0.75 - (fx[a] - 1.0) * (fx[a] - 1.0);
      w[a][2] = 0.5 * (fx[a] - 0.5) * (fx[a] - 0.5);
    }
  }
};

/// Strides of a box's linear index (the last axis fastest).
template <int D>
Index<D> strides(const Index<D>& n) {
  Index<D> s;
  s[D - 1] = 1;
  for (int a = D - 2; a >= 0; --a) s[a] = s[a + 1] * n[a + 1];
  return s;
}

/// The nine (i, j) rows of a 3D stencil: fn(i, j, row index of node (i, j, 0), w_i w_j); the kernels below walk the
/// three nodes along k of each row themselves.
template <class Fn>
void for_rows(const Stencil<3>& s, std::int64_t first, const Index<3>& st, Fn&& fn) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      fn(i, j, static_cast<std::size_t>(first + i * st[0] + j * st[1]), s.w[0][i] * s.w[1][j]);
}

/// Visits the 3^D stencil nodes as (linear index, weight, offset per axis 0..2) for a box with strides `st` whose
/// first node is the stencil's base at linear index `first`; the last axis fastest.
template <int D, typename Fn>
void for_nodes(const Stencil<D>& s, std::int64_t first, const Index<D>& st, Fn&& fn) {
  if constexpr (D == 2) {
    for (int i = 0; i < 3; ++i) {
      const std::int64_t ki = first + i * st[0];
      for (int j = 0; j < 3; ++j) fn(ki + j, s.w[0][i] * s.w[1][j], i, j, 0);
    }
  } else {
    for_rows(s, first, st, [&](int i, int j, std::size_t row, double wij) {
      for (int k = 0; k < 3; ++k) fn(static_cast<std::int64_t>(row) + k, wij * s.w[2][k], i, j, k);
    });
  }
}

template <int D>
std::int64_t linear(const Index<D>& i, const Index<D>& lo, const Index<D>& n) {
  std::int64_t k = 0;
  for (int a = 0; a < D; ++a) k = k * n[a] + (i[a] - lo[a]);
  return k;
}

/// The node at linear index k of a box (first node lo, counts n; the inverse of linear).
template <int D>
Index<D> box_node(std::int64_t k, const Index<D>& lo, const Index<D>& n) {
  Index<D> i;
  for (int a = D - 1; a >= 0; --a) {
    i[a] = lo[a] + k % n[a];
    k /= n[a];
  }
  return i;
}

template <int D>
Vec3 to3(const VecD<D>& x) {
  if constexpr (D == 2)
    return Vec3(x[0], x[1], 0.0);
  else
    return x;
}

template <int D>
VecD<D> from3(const Vec3& x) {
  if constexpr (D == 2)
    return VecD<D>(x[0], x[1]);
  else
    return x;
}

/// The constants of one step and the arrays its particle kernels read and write.
template <int D>
struct StepContext {
  const MpmModel<D>& model;
  MpmState<D>& state;
  MpmWorkspace<D>& ws;
  double dt = 0.0;
  double dx = 0.0;
  double inv_dx = 0.0;
  double d_inv = 0.0;  // D⁻¹ of the quadratic B-spline, 4/δx²
  bool uniform = false;
  bool general = false;
  VecD<D> b_uniform = VecD<D>::Zero();
  Index<D> stride = Index<D>::Zero();        // of the grid box
  Index<D> field_stride = Index<D>::Zero();  // of the field box (general fields)
  bool stress = true;  // P2G adds the elastic and magnetic stresses (the implicit step leaves them to its Newton solve)
};

/// Sets up a step's grid: the context's constants, the moving clamps' boxes at the state's time, the grid box (every
/// node some particle's stencil touches) cleared, the sampled obstacles and the field at its nodes, and the particles
/// bucketed into slabs along the box's longest axis. Fails on a non-finite position.
template <int D>
StepStatus prepare_grid(StepContext<D>& c, const AppliedField& field);

/// Ensures the field box (ws.field_*) covers the grid box (ws.lo, ws.n) with a margin and matches the field's version;
/// evaluates B and ∇B at the new nodes, in parallel.
template <int D>
void refresh_field(const AppliedField& field, double dx, MpmWorkspace<D>& ws);

/// P2G of every particle (mass, momentum with the affine part, the stresses unless `c.stress` is false, the node
/// moments in a non-uniform field), in parallel: the even slabs, then the odd ones, so no two threads write one node.
template <int D>
void scatter_all(const StepContext<D>& c);

/// No particle failed a check.
constexpr std::int64_t kNoFailure = std::numeric_limits<std::int64_t>::max();

/// G2P of every particle from the node velocities (the nodes' first D entries); the smallest failing particle's
/// index, or kNoFailure.
template <int D>
std::int64_t gather_all(const StepContext<D>& c);

/// Runs fn(first, last) over each slab's run of particle indices, in two colours of slabs (even, then odd) spread over
/// the threads: fn may add to the nodes of its particles' stencils without a race, and each node's sum runs in the
/// same order for any thread count.
template <int D, class Fn>
void for_slabs_coloured(const MpmWorkspace<D>& ws, std::size_t np, Fn&& fn) {
  const std::uint32_t* order = ws.slab_order.data();
  const auto slabs = static_cast<std::int64_t>(ws.slab_count.size() - 1);
  for (std::int64_t colour = 0; colour < 2; ++colour) {
#pragma omp parallel for schedule(dynamic, 1) if (np > static_cast <std::size_t>(kParallelMin))
    for (std::int64_t s = colour; s < slabs; s += 2) {
      const auto u = static_cast<std::size_t>(s);
      fn(order + ws.slab_count[u], order + ws.slab_count[u + 1]);
    }
  }
}

/// The same for fn(p), one particle at a time.
template <int D, class Fn>
void for_particles_coloured(const MpmWorkspace<D>& ws, std::size_t np, Fn&& fn) {
  for_slabs_coloured<D>(ws, np, [&](const std::uint32_t* p, const std::uint32_t* end) {
    for (; p != end; ++p) fn(static_cast<std::size_t>(*p));
  });
}

/// A free node's velocity before the damping and the boundaries: momentum over mass, plus Δt times the gradient force
/// over mass (eq 3.16: f_i = ∇B_iᵀ m_i, non-uniform fields) and gravity (eq 3.18). k is the node's index in the box,
/// i its grid index; its mass must be positive.
template <int D>
VecD<D> node_velocity(const StepContext<D>& c, std::size_t k, const Index<D>& i);

/// B at a particle (its stencil st): the uniform field, or the node field interpolated (non-uniform fields) [T].
template <int D>
inline VecD<D> field_at(const StepContext<D>& c, const Stencil<D>& st) {
  if (!c.general) return c.b_uniform;
  VecD<D> b = VecD<D>::Zero();
  for_nodes<D>(st, linear<D>(st.base, c.ws.field_lo, c.ws.field_n), c.field_stride,
               [&](std::int64_t k, double w, int, int, int) { b += w * c.ws.field_b[static_cast<std::size_t>(k)]; });
  return b;
}

/// The velocity a clamp gives the node at xi, or null where no clamp holds it.
template <int D>
const VecD<D>* clamp_velocity(const StepContext<D>& c, const VecD<D>& xi);

/// The domain walls' and the obstacles' conditions on the velocity v of node i (at xi = i δx).
template <int D>
void apply_walls_and_obstacles(const StepContext<D>& c, const Index<D>& i, const VecD<D>& xi, VecD<D>& v);

/// The status of a step whose particle `bad` failed its checks (kNoFailure: ok), naming the cause: non-finite,
/// inverted, exploded, moving more than a cell in dt, or (none of those) out of the domain.
template <int D>
StepStatus particle_failure(const MpmState<D>& state, std::int64_t bad, double dt, double dx);

/// The status of a step whose G2P found particle `bad` failing (kNoFailure: ok), naming the cause.
template <int D>
StepStatus failure_of(const StepContext<D>& c, std::int64_t bad);

}  // namespace magvine::mpm::detail
