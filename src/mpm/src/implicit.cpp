// The implicit MLS-MPM step (mpm.hpp: implicit_step): Newton on the incremental potential of the grid velocities.

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "grid.hpp"
#include "magvine/magnetics/magnetisation.hpp"
#include "magvine/mpm/mpm.hpp"

namespace magvine::mpm {
using namespace detail;  // NOLINT(google-build-using-namespace): the module's own internals (grid.hpp)
namespace {

// Scalar unknowns (D per free node) up to which the Hessian is assembled and factored (a sparse LDLᵀ); beyond,
// matrix-free CG. The assembly keeps a D×D block per node and neighbour within two nodes (125 in 3D: 9 KB a node),
// ~120 MB at the bound, and the factor's fill-in comes on top (11 907 unknowns in 3D: 6.1 M entries, 1.3–1.45 s a
// factorization on one thread).
constexpr std::int64_t kMaxDirectUnknowns = 40000;

/// Visits particle p's stencil nodes: fn(node index in the box, weight w_ip, x_i − x_p).
template <int D, class Fn>
void visit_stencil(const StepContext<D>& c, std::size_t p, Fn&& fn) {
  const Stencil<D> st(c.state.x[p], c.inv_dx);
  for_nodes<D>(st, linear<D>(st.base, c.ws.lo, c.ws.n), c.stride, [&](std::int64_t k, double w, int i, int j, int l) {
    VecD<D> d;
    d[0] = (i - st.fx[0]) * c.dx;
    d[1] = (j - st.fx[1]) * c.dx;
    if constexpr (D == 3) d[2] = (l - st.fx[2]) * c.dx;
    (void)l;
    fn(static_cast<std::size_t>(k), w, d);
  });
}

/// The implicit step's solver: its context, the node and particle vectors, and Newton's pieces.
template <int D>
class Solver {
 public:
  using Scratch = typename MpmWorkspace<D>::ImplicitScratch;

  Solver(StepContext<D>& c, const ImplicitSettings& settings)
      : m_c(c),
        m_s(c.ws.implicit),
        m_settings(settings),
        m_nodes(static_cast<std::int64_t>(c.ws.node.size())),
        m_np(c.model.size()),
        m_scale(1.0 + c.model.damping * c.dt) {}

  /// Newton from the transferred velocities (and the forces that do not depend on them).
  StepStatus solve(ImplicitStats& stats) {
    setup();
    // Start from the transferred velocities with the gradient force and gravity; where that inverts an element, from
    // rest at the free nodes.
    double energy = energy_at(m_s.v);
    if (!std::isfinite(energy)) {
      for (std::int64_t k = 0; k < m_nodes; ++k) {
        if (m_s.unknown[static_cast<std::size_t>(k)]) m_s.v[static_cast<std::size_t>(k)].setZero();
      }
      energy = energy_at(m_s.v);
      if (!std::isfinite(energy)) return {false, "the implicit step found an inverted element at its start"};
    }
    const double limit = m_settings.tolerance * m_c.dx / m_c.dt;  // [m/s]: tolerance cells over the step
    const double rhs0 = std::sqrt(gradient(m_s.v, m_s.grad));
    double rhs = rhs0;
    for (int it = 0; it < m_settings.max_newton; ++it) {
      ++stats.newton;
      // The first iteration factors the Hessian and solves with it; the later ones (whose Hessians differ little) run
      // CG preconditioned by that factor, a few products each. Too many unknowns, or no positive factor: Jacobi CG.
      bool factored = it == 0 && direct_solve();
      if (it == 0 && !factored && m_indefinite) {  // project the tangents and factor again
        m_project = true;
        gradient(m_s.v, m_s.grad);
        factored = direct_solve();
      }
      if (factored) {
        ++stats.factorizations;
      } else {
        stats.cg += conjugate_gradient(std::min(0.5, std::sqrt(rhs / std::max(rhs0, 1e-300))) * 1e-2);
      }
      const double dmax = node_max_norm<D>(m_s.dir);
      if (dmax <= limit) {  // the correction is below the tolerance: take it whole and stop
        node_axpy<D>(m_s.v, 1.0, m_s.dir, m_s.v);
        stats.correction = dmax * m_c.dt / m_c.dx;
        return {};
      }
      double trial_energy = 0.0;
      const double alpha = backtracking_line_search<D>(
          m_s.v, m_s.dir, energy, node_dot<D>(m_s.grad, m_s.dir), [&](const auto& v) { return energy_at(v); },
          [&] { return m_magnitude; }, m_s.trial, trial_energy);
      if (!(alpha > 0.0)) {
        return {false, "the implicit step's line search found no decrease (correction " +
                           std::to_string(dmax * m_c.dt / m_c.dx) + " cells): take a smaller time step"};
      }
      std::swap(m_s.v, m_s.trial);
      energy = trial_energy;
      stats.correction = alpha * dmax * m_c.dt / m_c.dx;
      rhs = std::sqrt(gradient(m_s.v, m_s.grad));
    }
    return {false, "the implicit step's Newton solve did not converge in " + std::to_string(m_settings.max_newton) +
                       " iterations (last correction " + std::to_string(stats.correction) +
                       " cells): take a smaller time step"};
  }

  /// Writes the solved velocities into the node records, with the walls' and obstacles' conditions.
  void store() {
    StepContext<D>& c = m_c;
#pragma omp parallel for schedule(static) if (m_nodes > kParallelMin)
    for (std::int64_t k = 0; k < m_nodes; ++k) {
      const auto u = static_cast<std::size_t>(k);
      VecD<D> v = m_s.v[u];
      if (m_s.unknown[u]) {
        const Index<D> i = box_node<D>(k, c.ws.lo, c.ws.n);
        apply_walls_and_obstacles<D>(c, i, VecD<D>(i.template cast<double>() * c.dx), v);
      }
      std::copy(v.data(), v.data() + D, c.ws.node[u].value);
    }
  }

 private:
  /// The target v* = p/m + Δt (∇Bᵀm/m + g) and the unknowns (nodes with mass, not clamped; a clamped node holds its
  /// clamp's velocity), from the P2G that left out the elastic stress.
  void setup() {
    const StepContext<D>& c = m_c;
    const auto n = static_cast<std::size_t>(m_nodes);
    for (auto* vec :
         {&m_s.target, &m_s.v, &m_s.trial, &m_s.grad, &m_s.dir, &m_s.res, &m_s.pre, &m_s.conj, &m_s.hconj, &m_s.diag}) {
      vec->assign(n, VecD<D>::Zero());
    }
    m_s.unknown.assign(n, 0);
    m_s.f_trial.resize(m_np);
    m_s.stress.resize(m_np);
    m_s.tangent.resize(m_np);
    m_s.field.assign(m_np, VecD<D>::Zero());
    m_s.magnetic.assign(m_np, MatD<D>::Zero());
    // The field at each magnetic particle and its hard-magnetic stress term Δt V0 P_mag Fᵀ (constant over the solve).
    if (c.uniform || c.general) {
#pragma omp parallel for schedule(static) if (m_np > static_cast <std::size_t>(kParallelMin))
      for (std::int64_t pp = 0; pp < static_cast<std::int64_t>(m_np); ++pp) {
        const auto p = static_cast<std::size_t>(pp);
        const VecD<D>& br = c.model.remanence[p];
        if (!(br.squaredNorm() > 0.0)) continue;
        const VecD<D> b = field_at<D>(c, Stencil<D>(c.state.x[p], c.inv_dx));
        m_s.field[p] = b;
        m_s.magnetic[p] = (c.dt * c.model.volume[p]) *
                          magnetics::hard_magnetic_kirchhoff_stress<D>(b, VecD<D>(c.state.f[p] * br));  // eq 3.13
      }
    }
#pragma omp parallel for schedule(static) if (m_nodes > kParallelMin)
    for (std::int64_t k = 0; k < m_nodes; ++k) {
      const auto u = static_cast<std::size_t>(k);
      const double* rec = c.ws.node[u].value;
      const double m = rec[D];
      if (m <= 0.0) continue;
      const Index<D> i = box_node<D>(k, c.ws.lo, c.ws.n);
      const VecD<D> xi = i.template cast<double>() * c.dx;
      if (const VecD<D>* held = clamp_velocity<D>(c, xi)) {
        m_s.v[u] = *held;
        continue;
      }
      const VecD<D> t = node_velocity<D>(c, u, i);
      m_s.target[u] = t;
      m_s.v[u] = t / m_scale;
      m_s.unknown[u] = 1;
    }
  }

  /// The Jacobi preconditioner, built only where CG runs without a factor (too many unknowns for the direct solve).
  void build_jacobi() {
    const StepContext<D>& c = m_c;
    // Jacobi preconditioner: m (1 + cΔt) + Δt² Σ_p V0 w² (G |b|² + (K + G/3) b_a²), b = Fᵀ D⁻¹ (x_i − x_p): the
    // diagonal of an isotropic linear material's stiffness at the particle, the Neo-Hookean's at rest.
    for_particles_coloured<D>(c.ws, m_np, [&](std::size_t p) {
      const Material& mat = c.model.materials[c.model.material[p]];
      const double vol = c.model.volume[p] * c.dt * c.dt;
      const MatD<D> ft = c.state.f[p].transpose();
      visit_stencil<D>(c, p, [&](std::size_t k, double w, const VecD<D>& d) {
        const VecD<D> b = (c.d_inv * w) * (ft * d);
        m_s.diag[k] += vol * (mat.shear_modulus * b.squaredNorm() * VecD<D>::Ones() +
                              (mat.bulk_modulus + mat.shear_modulus / 3.0) * b.cwiseAbs2());
      });
    });
#pragma omp parallel for schedule(static) if (m_nodes > kParallelMin)
    for (std::int64_t k = 0; k < m_nodes; ++k) {
      const auto u = static_cast<std::size_t>(k);
      const double m = c.ws.node[u].value[D];
      m_s.diag[u] =
          m_s.unknown[u] ? VecD<D>((m * m_scale * VecD<D>::Ones() + m_s.diag[u]).cwiseInverse()) : VecD<D>::Zero();
    }
    m_jacobi = true;
  }

  /// C_p = D⁻¹ Σ_i v_i (x_i − x_p)ᵀ w_ip: the velocity gradient G2P will form from node velocities v.
  MatD<D> affine(std::size_t p, const std::vector<VecD<D>>& v) const {
    MatD<D> b = MatD<D>::Zero();
    visit_stencil<D>(m_c, p, [&](std::size_t k, double w, const VecD<D>& d) { b += (w * v[k]) * d.transpose(); });
    return m_c.d_inv * b;
  }

  /// Adds Σ_p w_ip D⁻¹ S_p (x_i − x_p) to `out` at each node (S_p = m_s.stress[p]): the nodal force of a stress-like
  /// matrix per particle. `out` is cleared first.
  void scatter_stress(std::vector<VecD<D>>& out) {
    std::fill(out.begin(), out.end(), VecD<D>::Zero());
    const StepContext<D>& c = m_c;
    for_particles_coloured<D>(c.ws, m_np, [&](std::size_t p) {
      const MatD<D> s = c.d_inv * m_s.stress[p];
      visit_stencil<D>(c, p, [&](std::size_t k, double w, const VecD<D>& d) { out[k] += w * (s * d); });
    });
  }

  /// E(v), +∞ where some F̂ is inverted; leaves F̂ per particle in f_trial, and the sum of its terms' magnitudes in
  /// m_magnitude.
  double energy_at(const std::vector<VecD<D>>& v) {
    const StepContext<D>& c = m_c;
    const auto np = static_cast<std::int64_t>(m_np);
    const double elastic = ordered_sum(np, [&](std::int64_t pp) {
      const auto p = static_cast<std::size_t>(pp);
      const MatD<D> f = (MatD<D>::Identity() + c.dt * affine(p, v)) * c.state.f[p];
      m_s.f_trial[p] = f;
      if (!(f.determinant() > 0.0)) return std::numeric_limits<double>::infinity();
      const VecD<D> f_br = f * c.model.remanence[p];
      return c.model.volume[p] * (strain_energy_density<D>(c.model.materials[c.model.material[p]], f, c.model.plane) +
                                  magnetics::hard_magnetic_energy_density<D>(m_s.field[p], f_br));
    });
    const double kinetic = ordered_sum(m_nodes, [&](std::int64_t k) {
      const auto u = static_cast<std::size_t>(k);
      if (!m_s.unknown[u]) return 0.0;
      const double m = c.ws.node[u].value[D];
      return m * (0.5 * m_scale * v[u].squaredNorm() - v[u].dot(m_s.target[u]));
    });
    m_magnitude = std::abs(elastic) + ordered_sum(m_nodes, [&](std::int64_t k) {
                    const auto u = static_cast<std::size_t>(k);
                    if (!m_s.unknown[u]) return 0.0;
                    const double m = c.ws.node[u].value[D];
                    return m * (0.5 * m_scale * v[u].squaredNorm() + std::abs(v[u].dot(m_s.target[u])));
                  });
    return elastic + kinetic;
  }

  /// ∇E at v into g (zero at the fixed nodes), with F̂ from the last energy_at(v), and the tangent ∂P/∂F there for
  /// hessian_times; returns |g|².
  double gradient(const std::vector<VecD<D>>& v, std::vector<VecD<D>>& g) {
    const StepContext<D>& c = m_c;
#pragma omp parallel for schedule(static) if (m_np > static_cast <std::size_t>(kParallelMin))
    for (std::int64_t pp = 0; pp < static_cast<std::int64_t>(m_np); ++pp) {
      const auto p = static_cast<std::size_t>(pp);
      const Material& mat = c.model.materials[c.model.material[p]];
      const MatD<D>& f = m_s.f_trial[p];
      m_s.stress[p] = (c.dt * c.model.volume[p]) * elastic_stress<D>(mat, f, c.model.plane) * c.state.f[p].transpose() +
                      m_s.magnetic[p];
      // ∂P/∂F at F̂, column by column (the Hessian products and the factor reuse it). Once a step's Hessian proved
      // indefinite (a compressed Neo-Hookean's tangent is), each tangent's negative eigenvalues are set to zero: the
      // Hessian stays positive definite and the factor gives a descent direction (projected Newton; the gradient is
      // exact either way).
      m_s.tangent[p] = stress_tangent<D>(mat, f, c.model.plane, m_project);
    }
    scatter_stress(g);
    return ordered_sum(m_nodes, [&](std::int64_t k) {
      const auto u = static_cast<std::size_t>(k);
      if (!m_s.unknown[u]) {
        g[u].setZero();
        return 0.0;
      }
      g[u] += c.ws.node[u].value[D] * (m_scale * v[u] - m_s.target[u]);
      return g[u].squaredNorm();
    });
  }

  /// out = H x, the Hessian of E at the last gradient's F̂ times x: m (1 + cΔt) x_i + Δt Σ_p V0 dP[Δt δC_p F_p]
  /// F_pᵀ ∇w_ip, δC_p the affine field of x.
  void hessian_times(const std::vector<VecD<D>>& x, std::vector<VecD<D>>& out) {
    const StepContext<D>& c = m_c;
#pragma omp parallel for schedule(static) if (m_np > static_cast <std::size_t>(kParallelMin))
    for (std::int64_t pp = 0; pp < static_cast<std::int64_t>(m_np); ++pp) {
      const auto p = static_cast<std::size_t>(pp);
      const MatD<D>& f0 = c.state.f[p];
      const MatD<D> df = c.dt * affine(p, x) * f0;
      Eigen::Matrix<double, D * D, 1> dp =
          m_s.tangent[p] * Eigen::Map<const Eigen::Matrix<double, D * D, 1>>(df.data());
      m_s.stress[p] = (c.dt * c.model.volume[p]) * Eigen::Map<const MatD<D>>(dp.data()) * f0.transpose();
    }
    scatter_stress(out);
#pragma omp parallel for schedule(static) if (m_nodes > kParallelMin)
    for (std::int64_t k = 0; k < m_nodes; ++k) {
      const auto u = static_cast<std::size_t>(k);
      out[u] = m_s.unknown[u] ? VecD<D>(out[u] + c.ws.node[u].value[D] * m_scale * x[u]) : VecD<D>::Zero();
    }
  }

  /// dir = −H⁻¹ grad with H assembled (from the tangents of the last gradient) and factored by a sparse LDLᵀ; false
  /// (dir untouched) where there are too many unknowns or H is not positive definite, which leaves it to CG.
  bool direct_solve() {
    const StepContext<D>& c = m_c;
    constexpr int kReach = 5;  // two nodes of one particle's stencil lie at most two apart on each axis
    constexpr int kOffsets = D == 2 ? 25 : 125;
    auto& index = m_index;
    index.assign(static_cast<std::size_t>(m_nodes), -1);
    std::int64_t unknowns = 0;
    for (std::int64_t k = 0; k < m_nodes; ++k) {
      if (m_s.unknown[static_cast<std::size_t>(k)]) index[static_cast<std::size_t>(k)] = unknowns++;
    }
    if (unknowns == 0 || unknowns * D > kMaxDirectUnknowns) return false;  // `unknowns` counts nodes here
    auto& blocks = m_blocks;
    blocks.assign(static_cast<std::size_t>(unknowns * kOffsets), MatD<D>::Zero());
    // The offset slot of node j seen from node i (both in one stencil, so within two nodes on every axis).
    const auto slot = [&](std::int64_t ki, std::int64_t kj) {
      const Index<D> gi = box_node<D>(ki, c.ws.lo, c.ws.n), gj = box_node<D>(kj, c.ws.lo, c.ws.n);
      std::int64_t o = 0;
      for (int a = 0; a < D; ++a) o = o * kReach + (gj[a] - gi[a] + 2);
      return o;
    };
    // H_ij += Δt² V0 Σ_kl ∂P_ak/∂F_bl b_i[k] b_j[l], b_i = F_pᵀ ∇w_ip: per particle, Q_i = Σ_k T(a + Dk, ·) b_i[k]
    // once per node, then H_ij(a, b) = Σ_l Q_i(a, b + Dl) b_j[l] per pair.
    constexpr int kStencil = D == 2 ? 9 : 27;
    for_particles_coloured<D>(c.ws, m_np, [&](std::size_t p) {
      std::array<std::int64_t, kStencil> node;
      std::array<VecD<D>, kStencil> b;
      int n = 0;
      const MatD<D> ft = c.state.f[p].transpose();
      visit_stencil<D>(c, p, [&](std::size_t k, double w, const VecD<D>& d) {
        node[n] = static_cast<std::int64_t>(k);
        b[n++] = (c.d_inv * w) * (ft * d);
      });
      const auto& t = m_s.tangent[p];
      const double scale = c.dt * c.dt * c.model.volume[p];
      for (int i = 0; i < kStencil; ++i) {
        const std::int64_t row = index[static_cast<std::size_t>(node[i])];
        if (row < 0) continue;
        Eigen::Matrix<double, D, D* D> q = Eigen::Matrix<double, D, D * D>::Zero();
        for (int k = 0; k < D; ++k) q += b[i][k] * t.template middleRows<D>(D * k);
        q *= scale;
        for (int j = 0; j < kStencil; ++j) {
          if (index[static_cast<std::size_t>(node[j])] < 0) continue;
          MatD<D>& h = blocks[static_cast<std::size_t>(row * kOffsets + slot(node[i], node[j]))];
          for (int l = 0; l < D; ++l) h += b[j][l] * q.template middleCols<D>(D * l);
        }
      }
    });
    // The lower triangle, column by column (node order, so rows arrive sorted); the mass on the diagonal blocks.
    const std::int64_t n_dof = unknowns * D;
    Eigen::SparseMatrix<double> a(n_dof, n_dof);
    Eigen::VectorXi per_column = Eigen::VectorXi::Constant(n_dof, D * kOffsets);
    a.reserve(per_column);
    const Index<D> st = c.stride;
    for (std::int64_t k = 0; k < m_nodes; ++k) {
      const std::int64_t col_node = index[static_cast<std::size_t>(k)];
      if (col_node < 0) continue;
      const Index<D> g = box_node<D>(k, c.ws.lo, c.ws.n);
      const double mass = c.ws.node[static_cast<std::size_t>(k)].value[D] * m_scale;
      for (int b_ = 0; b_ < D; ++b_) {
        const std::int64_t col = col_node * D + b_;
        for (std::int64_t o = 0; o < kOffsets; ++o) {
          Index<D> off;
          std::int64_t rest = o, kj = k;
          bool inside = true;
          for (int ax = D - 1; ax >= 0; --ax) {
            off[ax] = rest % kReach - 2;
            rest /= kReach;
            inside = inside && g[ax] + off[ax] >= c.ws.lo[ax] && g[ax] + off[ax] < c.ws.lo[ax] + c.ws.n[ax];
            kj += off[ax] * st[ax];
          }
          if (!inside) continue;
          const std::int64_t row_node = index[static_cast<std::size_t>(kj)];
          if (row_node < col_node) continue;
          // H_(row, col) = H_(col, row)ᵀ: the block stored at the column node for the row node's slot.
          const MatD<D>& h = blocks[static_cast<std::size_t>(col_node * kOffsets + o)];
          for (int a_ = row_node == col_node ? b_ : 0; a_ < D; ++a_) {
            double value = h(b_, a_);
            if (row_node == col_node && a_ == b_) value += mass;
            if (value != 0.0) a.insert(row_node * D + a_, col) = value;
          }
        }
      }
    }
    a.makeCompressed();
    m_ldlt.compute(a);
    m_indefinite = m_ldlt.info() == Eigen::Success && !(m_ldlt.vectorD().minCoeff() > 0.0);
    if (m_ldlt.info() != Eigen::Success || m_indefinite) return false;
    solve_on_unknowns<D>(m_ldlt, index, m_s.grad, m_s.dir);
    for (auto& d : m_s.dir) d = -d;
    m_factored = true;
    return true;
  }

  /// z = M⁻¹ r: the factored Hessian of the step's first Newton iteration where there is one, else Jacobi.
  void precondition(const std::vector<VecD<D>>& r, std::vector<VecD<D>>& z) {
    const auto n = static_cast<std::size_t>(m_nodes);
    if (!m_factored) {
      if (!m_jacobi) build_jacobi();
      for (std::size_t k = 0; k < n; ++k) z[k] = m_s.diag[k].cwiseProduct(r[k]);
      return;
    }
    solve_on_unknowns<D>(m_ldlt, m_index, r, z);
  }

  long conjugate_gradient(double eta) {
    return preconditioned_cg<D>(
        m_s.grad, eta, m_settings.max_cg, [&](const auto& x, auto& out) { hessian_times(x, out); },
        [&](const auto& r, auto& z) { precondition(r, z); }, m_s.dir, m_s.res, m_s.pre, m_s.conj, m_s.hconj);
  }


  StepContext<D>& m_c;
  Scratch& m_s;
  const ImplicitSettings& m_settings;
  std::int64_t m_nodes;
  std::size_t m_np;
  double m_scale;                     // 1 + cΔt
  double m_magnitude = 0.0;           // Σ |terms| of the last energy_at: its round-off scale
  bool m_factored = false;            // m_ldlt holds this step's factored Hessian
  bool m_jacobi = false;              // m_s.diag holds the Jacobi preconditioner
  bool m_indefinite = false;          // the last factorization found the Hessian indefinite
  bool m_project = false;             // the tangents' negative eigenvalues are set to zero (after an indefinite one)
  std::vector<std::int64_t> m_index;  // direct solve: each node's unknown number (−1: fixed or empty)
  std::vector<MatD<D>> m_blocks;      // direct solve: the Hessian's D×D blocks, per unknown and neighbour slot
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower> m_ldlt;
};

}  // namespace

template <int D>
StepStatus implicit_step(const MpmModel<D>& model, const AppliedField& field, MpmState<D>& state, MpmWorkspace<D>& ws,
                         double dt, const ImplicitSettings& settings, ImplicitStats* stats) {
  StepContext<D> c{model, state, ws};
  c.dt = dt;
  c.stress = false;  // the Newton solve adds the stresses at the end of the step
  if (StepStatus ready = prepare_grid<D>(c, field); !ready.ok) return ready;
  scatter_all<D>(c);
  ImplicitStats local;
  ImplicitStats& counted = stats ? *stats : local;
  counted = {};
  Solver<D> solver(c, settings);
  const StepStatus solved = solver.solve(counted);
  if (!solved.ok) return {false, solved.cause + " at t = " + std::to_string(state.time) + " s"};
  solver.store();
  const std::int64_t bad = gather_all<D>(c);
  state.time += dt;
  return failure_of<D>(c, bad);
}

template StepStatus implicit_step<2>(const MpmModel<2>&, const AppliedField&, MpmState<2>&, MpmWorkspace<2>&, double,
                                     const ImplicitSettings&, ImplicitStats*);
template StepStatus implicit_step<3>(const MpmModel<3>&, const AppliedField&, MpmState<3>&, MpmWorkspace<3>&, double,
                                     const ImplicitSettings&, ImplicitStats*);

}  // namespace magvine::mpm
