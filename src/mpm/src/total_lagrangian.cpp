// Total-Lagrangian MPM (total_lagrangian.hpp): the reference grid, the explicit step and the implicit step.

#include "magvine/mpm/total_lagrangian.hpp"

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <string>

#include "grid.hpp"
#include "magvine/core/error.hpp"
#include "magvine/magnetics/magnetisation.hpp"

namespace magvine::mpm {
using namespace detail;  // NOLINT(google-build-using-namespace): the module's own internals (grid.hpp)

template <int D>
struct TlWorkspace<D>::Impl {
  // Newton's vectors, per grid node.
  std::vector<VecD<D>> target, v, trial, grad, dir, res, pre, conj, hconj, diag;
  std::vector<unsigned char> unknown;
  // Per particle: the trial F, a stress-like matrix per pass, B, the magnetic Piola stress, the tangent ∂P/∂F.
  std::vector<MatD<D>> f_trial, stress, magnetic;
  std::vector<VecD<D>> field;           // B at each particle (both steps)
  std::vector<MatD<D>> field_gradient;  // ∇B at each particle
  std::vector<VecD<D>> pull, force;     // per particle the gradient force; per node a force sum
  std::vector<Eigen::Matrix<double, D * D, D * D>> tangent;
  // The Hessian: each unknown node's number (−1: fixed or empty), its D×D blocks per unknown and neighbour slot, which
  // slots some particle couples (the pattern, fixed with the reference grid), and the factor.
  std::vector<std::int64_t> index;
  std::int64_t unknowns = 0;
  std::vector<MatD<D>> blocks;
  std::vector<unsigned char> coupled;
  MpmWorkspace<D> euler;  // the node field cache of a general field (sample_field)
  bool analysed = false;
  bool factored = false;   // the factor below is of some recent step's Hessian
  bool refactor = true;    // the next Newton iteration assembles and factors afresh
  double factor_dt = 0.0;  // the step the factor was made for (another step needs a new one)
  std::uint64_t grid = 0;  // the TlGrid::id the pattern and factor belong to (0: none)
  // The factor, in the node order (banded along the box's first axis: little fill for a body long along x) or in AMD's
  // order (a compact body); the first factorization of a grid tries both and keeps the one with the smaller L.
  using Natural = Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>>;
  using Amd = Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::AMDOrdering<int>>;
  std::unique_ptr<Natural> natural = std::make_unique<Natural>();
  std::unique_ptr<Amd> amd = std::make_unique<Amd>();
  bool use_amd = false;
  /// f applied to the factor in use (the one place that chooses between the two orderings).
  template <typename F>
  decltype(auto) with_factor(F&& f) {
    return use_amd ? f(*amd) : f(*natural);
  }
  /// Factors a (its pattern analysed already); the factor's success and whether its D is positive.
  bool factorize(const Eigen::SparseMatrix<double>& a, bool& indefinite) {
    return with_factor([&](auto& f) {
      f.factorize(a);
      indefinite = f.info() == Eigen::Success && !(f.vectorD().minCoeff() > 0.0);
      return f.info() == Eigen::Success && !indefinite;
    });
  }
};

template <int D>
TlWorkspace<D>::TlWorkspace() : impl(std::make_unique<Impl>()) {}
template <int D>
TlWorkspace<D>::~TlWorkspace() = default;
template <int D>
TlWorkspace<D>::TlWorkspace(TlWorkspace&&) noexcept = default;
template <int D>
TlWorkspace<D>& TlWorkspace<D>::operator=(TlWorkspace&&) noexcept = default;

namespace {

constexpr int kRefactorCg = 12;    // a CG solve longer than this asks for a fresh factor at the next Newton iteration
constexpr double kForcing = 1e-1;  // CG stops at this times min(0.5, √(|g|/|g0|)) of its first residual
constexpr int kReach = 5;          // two nodes of one stencil lie at most two apart on each axis
// Scalar unknowns up to which the Hessian is assembled and factored; beyond, Jacobi-preconditioned CG (as implicit.cpp).
constexpr std::int64_t kMaxDirectUnknowns = 40000;

/// The quadratic B-spline (eq 3.2) and its derivative at t = x/δx − node, |t| < 1.5.
inline void bspline(double t, double& w, double& dw) {
  const double a = std::abs(t);
  if (a < 0.5) {
    w = 0.75 - a * a;
    dw = -2.0 * t;
  } else if (a < 1.5) {
    const double r = 1.5 - a;
    w = 0.5 * r * r;
    dw = t > 0.0 ? -r : r;
  } else {
    w = 0.0;
    dw = 0.0;
  }
}

/// F_p = Σ_i x_i ∇_X w_ipᵀ.
template <int D>
MatD<D> deformation(const TlGrid<D>& g, const std::vector<VecD<D>>& x, std::size_t p) {
  MatD<D> f = MatD<D>::Zero();
  const std::size_t e0 = p * TlGrid<D>::kStencil;
  for (int s = 0; s < TlGrid<D>::kStencil; ++s) f += x[g.node[e0 + s]] * g.gradient[e0 + s].transpose();
  return f;
}

/// out_i = Σ_(p, e touching i) fn(p, e), e = p·kStencil + s, over every particle in order of the reference grid's
/// slabs (kSlabCells thick along the first axis), the even slabs then the odd ones in parallel: slabs of one colour
/// never share a node, and each node's sum runs in the same order for any thread count.
template <int D, class Fn>
void scatter(const TlGrid<D>& g, std::vector<VecD<D>>& out, Fn&& fn) {
  std::fill(out.begin(), out.end(), VecD<D>::Zero());
  const auto slabs = static_cast<std::int64_t>(g.slab_start.size()) - 1;
  for (std::int64_t colour = 0; colour < 2; ++colour) {
#pragma omp parallel for schedule(dynamic, 1) if (g.particles > static_cast <std::size_t>(kParallelMin))
    for (std::int64_t sl = colour; sl < slabs; sl += 2) {
      for (std::uint32_t i = g.slab_start[static_cast<std::size_t>(sl)];
           i < g.slab_start[static_cast<std::size_t>(sl) + 1]; ++i) {
        const std::size_t p = g.slab_order[i];
        const std::size_t e0 = p * TlGrid<D>::kStencil;
        for (int k = 0; k < TlGrid<D>::kStencil; ++k) out[g.node[e0 + k]] += fn(p, e0 + k);
      }
    }
  }
}

/// B and ∇B at each magnetic particle (zero elsewhere) [T, T/m]. A general field is sampled once per field version at
/// the nodes of a fixed Eulerian lattice of the grid's spacing (implicit.cpp's and mpm.cpp's node field cache, in
/// `euler`) and interpolated to the particles with the quadratic B-spline, as the updated-Lagrangian step does.
template <int D>
void sample_field(const MpmModel<D>& model, const AppliedField& field, const MpmState<D>& state,
                  MpmWorkspace<D>& euler, std::vector<VecD<D>>& b, std::vector<MatD<D>>& g) {
  const std::size_t np = model.size();
  b.assign(np, VecD<D>::Zero());
  g.assign(np, MatD<D>::Zero());
  if (field.kind == AppliedField::Kind::kNone) return;
  const double inv_dx = 1.0 / model.cell;
  if (field.kind == AppliedField::Kind::kGeneral) {
    Index<D> lo = Index<D>::Constant(std::numeric_limits<std::int64_t>::max());
    Index<D> hi = Index<D>::Constant(std::numeric_limits<std::int64_t>::min());
    for (const VecD<D>& x : state.x) {
      const Stencil<D> st(x, inv_dx);
      lo = lo.cwiseMin(st.base);
      hi = hi.cwiseMax(st.base);
    }
    euler.lo = lo;
    euler.n = hi - lo + Index<D>::Constant(3);
    refresh_field<D>(field, model.cell, euler);
  }
  const Index<D> stride = field.kind == AppliedField::Kind::kGeneral ? strides<D>(euler.field_n) : Index<D>::Zero();
#pragma omp parallel for schedule(static) if (np > static_cast <std::size_t>(kParallelMin))
  for (std::int64_t pp = 0; pp < static_cast<std::int64_t>(np); ++pp) {
    const auto p = static_cast<std::size_t>(pp);
    if (!(model.remanence[p].squaredNorm() > 0.0)) continue;
    if (field.kind == AppliedField::Kind::kUniform) {
      b[p] = from3<D>(field.uniform);
      continue;
    }
    const Stencil<D> st(state.x[p], inv_dx);
    for_nodes<D>(st, linear<D>(st.base, euler.field_lo, euler.field_n), stride,
                 [&](std::int64_t k, double w, int, int, int) {
                   b[p] += w * euler.field_b[static_cast<std::size_t>(k)];
                   g[p] += w * euler.field_g[static_cast<std::size_t>(k)];
                 });
  }
}

/// The gradient force on each particle's moment, V0 (F B̃r)/μ0 in ∇B (eq 3.15–3.16) [N; N/m in 2D].
template <int D>
VecD<D> particle_pull(const MpmModel<D>& model, std::size_t p, const MatD<D>& f, const MatD<D>& grad_b) {
  if (!(grad_b.squaredNorm() > 0.0)) return VecD<D>::Zero();
  return magnetics::gradient_force<D>(
      grad_b, magnetics::hard_magnetic_moment<D>(VecD<D>(f * model.remanence[p]), model.volume[p]));
}

/// Each particle's x, v and F from the nodes (one pass over its stencil), and the smallest failing particle (or
/// kNoFailure). C, the updated-Lagrangian step's affine field, is left as it is: nothing here reads it.
template <int D>
std::int64_t finish_particles(const MpmModel<D>& model, const TlGrid<D>& g, MpmState<D>& state, double dt) {
  const auto np = static_cast<std::int64_t>(g.particles);
  std::int64_t bad = kNoFailure;
#pragma omp parallel for schedule(static) reduction(min : bad) if (np > kParallelMin)
  for (std::int64_t pp = 0; pp < np; ++pp) {
    const auto p = static_cast<std::size_t>(pp);
    VecD<D> x = VecD<D>::Zero(), v = VecD<D>::Zero();
    MatD<D> f = MatD<D>::Zero();
    const std::size_t e0 = p * TlGrid<D>::kStencil;
    for (int s = 0; s < TlGrid<D>::kStencil; ++s) {
      const std::uint32_t k = g.node[e0 + s];
      x += g.weight[e0 + s] * state.grid_x[k];
      v += g.weight[e0 + s] * state.grid_v[k];
      f += state.grid_x[k] * g.gradient[e0 + s].transpose();
    }
    state.x[p] = x;
    state.v[p] = v;
    state.f[p] = f;
    const double j = f.determinant();
    const bool fails = !(j > 0.0 && j < kMaxJ) || !state.x[p].allFinite() || !state.v[p].allFinite() ||
                       state.v[p].norm() * dt > kMaxCellsPerStep * g.cell ||
                       (state.x[p].array() < model.domain_min.array()).any() ||
                       (state.x[p].array() > model.domain_max.array()).any();
    if (fails) bad = std::min(bad, pp);
  }
  return bad;
}

template <int D>
void check_state(const MpmModel<D>& model, const TlGrid<D>& g, const MpmState<D>& state, double dt) {
  if (state.grid_x.size() != g.rest.size() || state.grid_v.size() != g.rest.size() || state.x.size() != g.particles ||
      state.v.size() != g.particles || state.f.size() != g.particles || model.size() != g.particles) {
    throw std::logic_error("total-Lagrangian step: the state was not prepared by make_tl_grid for this grid and model");
  }
  if (!(dt > 0.0 && std::isfinite(dt))) throw std::logic_error("total-Lagrangian step: dt must be positive and finite");
}

/// The implicit step's Newton solve (the same scheme as implicit.cpp's, on the reference grid).
template <int D>
class TlSolver {
 public:
  using Impl = typename TlWorkspace<D>::Impl;
  static constexpr int kStencil = TlGrid<D>::kStencil;
  static constexpr int kOffsets = D == 2 ? 25 : 125;

  TlSolver(const MpmModel<D>& model, const TlGrid<D>& grid, const MpmState<D>& state, Impl& s, double dt,
           const ImplicitSettings& settings)
      : m_model(model),
        m_grid(grid),
        m_state(state),
        m_s(s),
        m_dt(dt),
        m_settings(settings),
        m_nodes(static_cast<std::int64_t>(grid.rest.size())),
        m_np(grid.particles),
        m_scale(1.0 + model.damping * dt) {}

  StepStatus solve(const AppliedField& field, ImplicitStats& stats) {
    setup(field);
    if (std::none_of(m_s.unknown.begin(), m_s.unknown.end(), [](unsigned char u) { return u != 0; })) return {};
    double energy = energy_at(m_s.v);
    if (!std::isfinite(energy)) {
      for (std::int64_t k = 0; k < m_nodes; ++k) {
        if (m_s.unknown[static_cast<std::size_t>(k)]) m_s.v[static_cast<std::size_t>(k)].setZero();
      }
      energy = energy_at(m_s.v);
      if (!std::isfinite(energy)) return {false, "the implicit step found an inverted element at its start"};
    }
    const double limit = m_settings.tolerance * m_grid.cell / m_dt;  // [m/s]: tolerance cells over the step
    const double rhs0 = std::sqrt(gradient(m_s.v, m_s.grad));
    double rhs = rhs0;
    for (int it = 0; it < m_settings.max_newton; ++it) {
      ++stats.newton;
      bool solved = false;
      if (m_s.refactor || !m_s.factored || m_s.factor_dt != m_dt) {
        solved = factor_and_solve();
        if (!solved && m_indefinite && !m_project) {  // project the tangents and factor again
          m_project = true;
          gradient(m_s.v, m_s.grad);
          solved = factor_and_solve();
        }
        if (solved) ++stats.factorizations;
      }
      if (!solved) {
        const long cg = conjugate_gradient(std::min(0.5, std::sqrt(rhs / std::max(rhs0, 1e-300))) * kForcing);
        stats.cg += cg;
        if (cg > kRefactorCg) m_s.refactor = true;
      }
      const double dmax = node_max_norm<D>(m_s.dir);
      if (dmax <= limit) {
        node_axpy<D>(m_s.v, 1.0, m_s.dir, m_s.v);
        stats.correction = dmax * m_dt / m_grid.cell;
        return {};
      }
      double trial_energy = 0.0;
      const double alpha = backtracking_line_search<D>(
          m_s.v, m_s.dir, energy, node_dot<D>(m_s.grad, m_s.dir), [&](const auto& v) { return energy_at(v); },
          [&] { return m_magnitude; }, m_s.trial, trial_energy);
      if (!(alpha > 0.0)) {
        m_s.refactor = true;
        return {false, "the implicit step's line search found no decrease (correction " +
                           std::to_string(dmax * m_dt / m_grid.cell) + " cells): take a smaller time step"};
      }
      if (alpha < 1.0) m_s.refactor = true;  // a damped step: the factor no longer describes the Hessian well
      std::swap(m_s.v, m_s.trial);
      energy = trial_energy;
      stats.correction = alpha * dmax * m_dt / m_grid.cell;
      rhs = std::sqrt(gradient(m_s.v, m_s.grad));
    }
    m_s.refactor = true;
    return {false, "the implicit step's Newton solve did not converge in " + std::to_string(m_settings.max_newton) +
                       " iterations (last correction " + std::to_string(stats.correction) +
                       " cells): take a smaller time step"};
  }

  /// The solved node velocities (the clamps' where held) and positions x_i + Δt v_i into the state.
  void store(MpmState<D>& state) const {
    for (std::int64_t k = 0; k < m_nodes; ++k) {
      const auto u = static_cast<std::size_t>(k);
      if (!(m_grid.mass[u] > 0.0)) continue;
      state.grid_v[u] = m_s.v[u];
      state.grid_x[u] += m_dt * m_s.v[u];
    }
  }

 private:
  void setup(const AppliedField& field) {
    if (m_s.grid != m_grid.id) {  // another grid: its pattern and factor start afresh
      m_s.grid = m_grid.id;
      m_s.index.clear();
      m_s.analysed = false;
      m_s.factored = false;
      m_s.refactor = true;
    }
    const auto n = static_cast<std::size_t>(m_nodes);
    for (auto* vec :
         {&m_s.target, &m_s.v, &m_s.trial, &m_s.grad, &m_s.dir, &m_s.res, &m_s.pre, &m_s.conj, &m_s.hconj, &m_s.diag}) {
      vec->assign(n, VecD<D>::Zero());
    }
    m_s.unknown.assign(n, 0);
    m_s.f_trial.resize(m_np);
    m_s.stress.resize(m_np);
    m_s.tangent.resize(m_np);
    m_s.magnetic.assign(m_np, MatD<D>::Zero());
    sample_field<D>(m_model, field, m_state, m_s.euler, m_s.field, m_s.field_gradient);
    std::vector<VecD<D>>& pull = m_s.pull;
    pull.assign(m_np, VecD<D>::Zero());
    for (std::size_t p = 0; p < m_np; ++p) {
      if (!(m_model.remanence[p].squaredNorm() > 0.0)) continue;
      m_s.magnetic[p] = magnetics::hard_magnetic_piola_stress<D>(m_s.field[p], m_model.remanence[p]);  // eq 3.13
      pull[p] = particle_pull<D>(m_model, p, m_state.f[p], m_s.field_gradient[p]);
    }
    std::vector<VecD<D>>& force = m_s.force;
    force.resize(n);
    scatter<D>(m_grid, force, [&](std::size_t p, std::size_t e) { return VecD<D>(m_grid.weight[e] * pull[p]); });
    for (std::size_t u = 0; u < n; ++u) {
      const double m = m_grid.mass[u];
      if (!(m > 0.0)) continue;
      if (m_grid.clamp[u] >= 0) {
        m_s.v[u] = m_model.clamps[static_cast<std::size_t>(m_grid.clamp[u])].velocity;
        continue;
      }
      m_s.target[u] = m_state.grid_v[u] + m_dt * (force[u] / m + m_model.gravity);
      m_s.v[u] = m_s.target[u] / m_scale;
      m_s.unknown[u] = 1;
    }
  }

  /// F̂_p at node velocities v: F_p(x + Δt v).
  MatD<D> trial_deformation(std::size_t p, const std::vector<VecD<D>>& v) const {
    MatD<D> f = MatD<D>::Zero();
    const std::size_t e0 = p * kStencil;
    for (int s = 0; s < kStencil; ++s) {
      const std::uint32_t k = m_grid.node[e0 + s];
      f += (m_state.grid_x[k] + m_dt * v[k]) * m_grid.gradient[e0 + s].transpose();
    }
    return f;
  }

  double energy_at(const std::vector<VecD<D>>& v) {
    const auto np = static_cast<std::int64_t>(m_np);
    const double elastic = ordered_sum(np, [&](std::int64_t pp) {
      const auto p = static_cast<std::size_t>(pp);
      const MatD<D> f = trial_deformation(p, v);
      m_s.f_trial[p] = f;
      if (!(f.determinant() > 0.0)) return std::numeric_limits<double>::infinity();
      const Material& mat = m_model.materials[m_model.material[p]];
      const VecD<D> f_br = f * m_model.remanence[p];
      return m_model.volume[p] * (strain_energy_density<D>(mat, f, m_model.plane) +
                                  magnetics::hard_magnetic_energy_density<D>(m_s.field[p], f_br));
    });
    const double kinetic = ordered_sum(m_nodes, [&](std::int64_t k) {
      const auto u = static_cast<std::size_t>(k);
      if (!m_s.unknown[u]) return 0.0;
      return m_grid.mass[u] * (0.5 * m_scale * v[u].squaredNorm() - v[u].dot(m_s.target[u]));
    });
    m_magnitude = std::abs(elastic) + ordered_sum(m_nodes, [&](std::int64_t k) {
                    const auto u = static_cast<std::size_t>(k);
                    if (!m_s.unknown[u]) return 0.0;
                    return m_grid.mass[u] * (0.5 * m_scale * v[u].squaredNorm() + std::abs(v[u].dot(m_s.target[u])));
                  });
    return elastic + kinetic;
  }

  /// ∇E at v (zero at the fixed nodes) with F̂ from the last energy_at(v), and the tangents there; returns |g|².
  double gradient(const std::vector<VecD<D>>& v, std::vector<VecD<D>>& g) {
#pragma omp parallel for schedule(static) if (m_np > static_cast <std::size_t>(kParallelMin))
    for (std::int64_t pp = 0; pp < static_cast<std::int64_t>(m_np); ++pp) {
      const auto p = static_cast<std::size_t>(pp);
      const Material& mat = m_model.materials[m_model.material[p]];
      const MatD<D>& f = m_s.f_trial[p];
      m_s.stress[p] = (m_dt * m_model.volume[p]) * (elastic_stress<D>(mat, f, m_model.plane) + m_s.magnetic[p]);
      m_s.tangent[p] = stress_tangent<D>(mat, f, m_model.plane, m_project);
    }
    scatter_stress(g);
    return ordered_sum(m_nodes, [&](std::int64_t k) {
      const auto u = static_cast<std::size_t>(k);
      if (!m_s.unknown[u]) {
        g[u].setZero();
        return 0.0;
      }
      g[u] += m_grid.mass[u] * (m_scale * v[u] - m_s.target[u]);
      return g[u].squaredNorm();
    });
  }

  /// out_i = Σ_p S_p ∇_X w_ip (S_p = m_s.stress[p]).
  void scatter_stress(std::vector<VecD<D>>& out) {
    scatter<D>(m_grid, out,
              [&](std::size_t p, std::size_t e) { return VecD<D>(m_s.stress[p] * m_grid.gradient[e]); });
  }

  /// out = H x: m (1 + cΔt) x_i + Δt² Σ_p V0 (∂P/∂F : Σ_j x_j ∇w_jpᵀ) ∇w_ip.
  void hessian_times(const std::vector<VecD<D>>& x, std::vector<VecD<D>>& out) {
#pragma omp parallel for schedule(static) if (m_np > static_cast <std::size_t>(kParallelMin))
    for (std::int64_t pp = 0; pp < static_cast<std::int64_t>(m_np); ++pp) {
      const auto p = static_cast<std::size_t>(pp);
      const MatD<D> df = m_dt * deformation<D>(m_grid, x, p);
      const Eigen::Matrix<double, D * D, 1> dp =
          m_s.tangent[p] * Eigen::Map<const Eigen::Matrix<double, D * D, 1>>(df.data());
      m_s.stress[p] = (m_dt * m_model.volume[p]) * Eigen::Map<const MatD<D>>(dp.data());
    }
    scatter_stress(out);
    for (std::int64_t k = 0; k < m_nodes; ++k) {
      const auto u = static_cast<std::size_t>(k);
      out[u] = m_s.unknown[u] ? VecD<D>(out[u] + m_grid.mass[u] * m_scale * x[u]) : VecD<D>::Zero();
    }
  }

  /// The offset slot of node kj seen from node ki (both in one stencil).
  std::int64_t slot(std::int64_t ki, std::int64_t kj) const {
    const Index<D> gi = box_node<D>(ki, m_grid.lo, m_grid.n), gj = box_node<D>(kj, m_grid.lo, m_grid.n);
    std::int64_t o = 0;
    for (int a = 0; a < D; ++a) o = o * kReach + (gj[a] - gi[a] + 2);
    return o;
  }

  /// The unknowns' numbering and the pattern of coupled slots, once per grid (neither changes with the body's motion).
  bool prepare_pattern() {
    if (!m_s.index.empty()) return m_s.unknowns > 0 && m_s.unknowns * D <= kMaxDirectUnknowns;
    m_s.index.assign(static_cast<std::size_t>(m_nodes), -1);
    m_s.unknowns = 0;
    for (std::int64_t k = 0; k < m_nodes; ++k) {
      if (m_s.unknown[static_cast<std::size_t>(k)]) m_s.index[static_cast<std::size_t>(k)] = m_s.unknowns++;
    }
    if (m_s.unknowns == 0 || m_s.unknowns * D > kMaxDirectUnknowns) return false;
    m_s.coupled.assign(static_cast<std::size_t>(m_s.unknowns * kOffsets), 0);
    for (std::size_t p = 0; p < m_np; ++p) {
      const std::size_t e0 = p * kStencil;
      for (int i = 0; i < kStencil; ++i) {
        const std::int64_t row = m_s.index[m_grid.node[e0 + i]];
        if (row < 0) continue;
        for (int j = 0; j < kStencil; ++j) {
          if (m_s.index[m_grid.node[e0 + j]] < 0) continue;
          m_s.coupled[static_cast<std::size_t>(row * kOffsets + slot(m_grid.node[e0 + i], m_grid.node[e0 + j]))] = 1;
        }
      }
    }
    return true;
  }

  /// Assembles H at the current tangents, factors it (the pattern analysed once) and solves dir = −H⁻¹ grad; false
  /// (dir untouched) where there are too many unknowns or H is not positive definite.
  bool factor_and_solve() {
    m_indefinite = false;
    if (!prepare_pattern()) return false;
    const std::int64_t unknowns = m_s.unknowns;
    auto& blocks = m_s.blocks;
    blocks.assign(static_cast<std::size_t>(unknowns * kOffsets), MatD<D>::Zero());
    // H_ij += Δt² V0 Σ_kl ∂P_ak/∂F_bl g_i[k] g_j[l], g = ∇_X w: Q_i = Σ_k T(a + Dk, ·) g_i[k] once per node, then
    // H_ij(a, b) = Σ_l Q_i(a, b + Dl) g_j[l] per pair (implicit.cpp's assembly with ∇_X w for Fᵀ∇w).
    for (std::size_t p = 0; p < m_np; ++p) {
      const std::size_t e0 = p * kStencil;
      const auto& t = m_s.tangent[p];
      const double scale = m_dt * m_dt * m_model.volume[p];
      for (int i = 0; i < kStencil; ++i) {
        const std::int64_t row = m_s.index[m_grid.node[e0 + i]];
        if (row < 0) continue;
        const VecD<D>& gi = m_grid.gradient[e0 + i];
        Eigen::Matrix<double, D, D * D> q = Eigen::Matrix<double, D, D * D>::Zero();
        for (int k = 0; k < D; ++k) q += gi[k] * t.template middleRows<D>(D * k);
        q *= scale;
        for (int j = 0; j < kStencil; ++j) {
          if (m_s.index[m_grid.node[e0 + j]] < 0) continue;
          const VecD<D>& gj = m_grid.gradient[e0 + j];
          MatD<D>& h = blocks[static_cast<std::size_t>(row * kOffsets + slot(m_grid.node[e0 + i], m_grid.node[e0 + j]))];
          for (int l = 0; l < D; ++l) h += gj[l] * q.template middleCols<D>(D * l);
        }
      }
    }
    // The lower triangle column by column, every coupled entry (zero or not: the pattern must not change).
    const std::int64_t n_dof = unknowns * D;
    Eigen::SparseMatrix<double> a(n_dof, n_dof);
    a.reserve(Eigen::VectorXi::Constant(n_dof, D * kOffsets));
    const Index<D> st = strides<D>(m_grid.n);
    for (std::int64_t k = 0; k < m_nodes; ++k) {
      const std::int64_t col_node = m_s.index[static_cast<std::size_t>(k)];
      if (col_node < 0) continue;
      const double mass = m_grid.mass[static_cast<std::size_t>(k)] * m_scale;
      for (int b_ = 0; b_ < D; ++b_) {
        const std::int64_t col = col_node * D + b_;
        for (std::int64_t o = 0; o < kOffsets; ++o) {
          if (!m_s.coupled[static_cast<std::size_t>(col_node * kOffsets + o)]) continue;
          std::int64_t rest = o, kj = k;
          for (int ax = D - 1; ax >= 0; --ax) {
            kj += (rest % kReach - 2) * st[ax];
            rest /= kReach;
          }
          const std::int64_t row_node = m_s.index[static_cast<std::size_t>(kj)];
          if (row_node < col_node) continue;
          const MatD<D>& h = blocks[static_cast<std::size_t>(col_node * kOffsets + o)];
          for (int a_ = row_node == col_node ? b_ : 0; a_ < D; ++a_) {
            double value = h(b_, a_);
            if (row_node == col_node && a_ == b_) value += mass;
            a.insert(row_node * D + a_, col) = value;
          }
        }
      }
    }
    a.makeCompressed();
    m_s.factored = false;
    if (!m_s.analysed) {  // both orderings once; keep the one whose factor is smaller
      m_s.natural = std::make_unique<typename Impl::Natural>();
      m_s.amd = std::make_unique<typename Impl::Amd>();
      m_s.natural->analyzePattern(a);
      m_s.amd->analyzePattern(a);
      m_s.natural->factorize(a);
      m_s.amd->factorize(a);
      const auto size = [](const auto& f) {
        return f.info() == Eigen::Success ? f.matrixL().nestedExpression().nonZeros()
                                          : std::numeric_limits<Eigen::Index>::max();
      };
      m_s.use_amd = size(*m_s.amd) < size(*m_s.natural);
      if (m_s.use_amd)
        m_s.natural = std::make_unique<typename Impl::Natural>();
      else
        m_s.amd = std::make_unique<typename Impl::Amd>();
      m_s.analysed = true;
    }
    if (!m_s.factorize(a, m_indefinite)) return false;
    m_s.factored = true;
    m_s.refactor = false;
    m_s.factor_dt = m_dt;
    precondition(m_s.grad, m_s.dir);
    for (auto& d : m_s.dir) d = -d;
    return true;
  }

  /// z = M⁻¹ r: the stored factor where there is one, else Jacobi (the diagonal of H).
  void precondition(const std::vector<VecD<D>>& r, std::vector<VecD<D>>& z) {
    const auto n = static_cast<std::size_t>(m_nodes);
    if (!m_s.factored) {
      if (!m_jacobi) build_jacobi();
      for (std::size_t k = 0; k < n; ++k) z[k] = m_s.diag[k].cwiseProduct(r[k]);
      return;
    }
    m_s.with_factor([&](const auto& f) { solve_on_unknowns<D>(f, m_s.index, r, z); });
  }

  /// The inverse diagonal of H at the current tangents.
  void build_jacobi() {
    std::vector<VecD<D>> d(static_cast<std::size_t>(m_nodes));
    scatter<D>(m_grid, d, [&](std::size_t p, std::size_t e) {
      const VecD<D>& g = m_grid.gradient[e];
      const auto& t = m_s.tangent[p];
      VecD<D> out;
      for (int a = 0; a < D; ++a) {
        double s = 0.0;
        for (int k = 0; k < D; ++k)
          for (int l = 0; l < D; ++l) s += t(a + D * k, a + D * l) * g[k] * g[l];
        out[a] = std::max(s, 0.0) * m_dt * m_dt * m_model.volume[p];
      }
      return out;
    });
    for (std::int64_t k = 0; k < m_nodes; ++k) {
      const auto u = static_cast<std::size_t>(k);
      m_s.diag[u] = m_s.unknown[u] ? VecD<D>((m_grid.mass[u] * m_scale * VecD<D>::Ones() + d[u]).cwiseInverse())
                                   : VecD<D>::Zero();
    }
    m_jacobi = true;
  }

  long conjugate_gradient(double eta) {
    return preconditioned_cg<D>(
        m_s.grad, eta, m_settings.max_cg, [&](const auto& x, auto& out) { hessian_times(x, out); },
        [&](const auto& r, auto& z) { precondition(r, z); }, m_s.dir, m_s.res, m_s.pre, m_s.conj, m_s.hconj);
  }

  const MpmModel<D>& m_model;
  const TlGrid<D>& m_grid;
  const MpmState<D>& m_state;
  Impl& m_s;
  double m_dt;
  const ImplicitSettings& m_settings;
  std::int64_t m_nodes;
  std::size_t m_np;
  double m_scale;            // 1 + cΔt
  double m_magnitude = 0.0;  // Σ |terms| of the last energy_at: its round-off scale
  bool m_jacobi = false;
  bool m_indefinite = false;
  bool m_project = false;
};

}  // namespace

template <int D>
TlGrid<D> make_tl_grid(const MpmModel<D>& model, MpmState<D>& state) {
  if (!model.obstacles.empty()) {
    throw InputError("total-Lagrangian MPM takes no obstacles yet (obstacle '" + model.obstacles.front().name +
                     "'): use the updated-Lagrangian solver");
  }
  constexpr int kS = TlGrid<D>::kStencil;
  if (model.size() == 0) throw InputError("total-Lagrangian MPM: the model has no particles");
  if (!(model.cell > 0.0 && std::isfinite(model.cell))) throw InputError("total-Lagrangian MPM: the cell must be > 0");
  if (state.x.size() != model.size() || state.v.size() != model.size()) {
    throw std::logic_error("make_tl_grid: the state's particles do not match the model's");
  }
  static std::atomic<std::uint64_t> next_id{1};
  TlGrid<D> g;
  g.id = next_id++;
  g.cell = model.cell;
  g.particles = model.size();
  const double inv_dx = 1.0 / model.cell;
  // The box: every node some particle's stencil touches.
  Index<D> lo = Index<D>::Constant(std::numeric_limits<std::int64_t>::max());
  Index<D> hi = Index<D>::Constant(std::numeric_limits<std::int64_t>::min());
  for (const VecD<D>& x : state.x) {
    if (!x.allFinite() || (x.array() < model.domain_min.array()).any() || (x.array() > model.domain_max.array()).any()) {
      throw InputError("total-Lagrangian MPM: a particle lies outside the domain (or is not finite)");
    }
    const Stencil<D> st(x, inv_dx);
    lo = lo.cwiseMin(st.base);
    hi = hi.cwiseMax(st.base + Index<D>::Constant(2));
  }
  g.lo = lo;
  g.n = hi - lo + Index<D>::Ones();
  std::int64_t count = 1;
  for (int a = 0; a < D; ++a) count *= g.n[a];
  if (count > std::int64_t{1} << 31) {
    throw InputError("total-Lagrangian MPM: the body's reference grid would have " + std::to_string(count) +
                     " nodes (at most 2^31): enlarge the cell");
  }
  const auto nodes = static_cast<std::size_t>(count);
  g.rest.resize(nodes);
  for (std::size_t k = 0; k < nodes; ++k) {
    g.rest[k] = box_node<D>(static_cast<std::int64_t>(k), g.lo, g.n).template cast<double>() * model.cell;
  }
  g.mass.assign(nodes, 0.0);
  g.node.resize(g.particles * kS);
  g.weight.resize(g.particles * kS);
  g.gradient.resize(g.particles * kS);
  for (std::size_t p = 0; p < g.particles; ++p) {
    const Stencil<D> st(state.x[p], inv_dx);
    std::array<std::array<double, 3>, D> w, dw;
    for (int a = 0; a < D; ++a)
      for (int k = 0; k < 3; ++k) bspline(st.fx[a] - k, w[a][k], dw[a][k]);
    int s = 0;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        for (int l = 0; l < (D == 3 ? 3 : 1); ++l, ++s) {
          Index<D> node;
          node[0] = st.base[0] + i;
          node[1] = st.base[1] + j;
          if constexpr (D == 3) node[2] = st.base[2] + l;
          const std::size_t e = p * kS + static_cast<std::size_t>(s);
          const auto k = static_cast<std::uint32_t>(linear<D>(node, g.lo, g.n));
          VecD<D> grad;
          double weight;
          if constexpr (D == 2) {
            weight = w[0][i] * w[1][j];
            grad = VecD<D>(dw[0][i] * w[1][j], w[0][i] * dw[1][j]) * inv_dx;
          } else {
            weight = w[0][i] * w[1][j] * w[2][l];
            grad = VecD<D>(dw[0][i] * w[1][j] * w[2][l], w[0][i] * dw[1][j] * w[2][l], w[0][i] * w[1][j] * dw[2][l]) *
                   inv_dx;
          }
          g.node[e] = k;
          g.weight[e] = weight;
          g.gradient[e] = grad;
          g.mass[k] += weight * model.mass[p];
        }
  }
  // A node only grazed by stencils (weight ~ε², from a particle at round-off from a cell's edge) would carry a mass
  // and a stiffness of order ε² and a velocity Newton cannot resolve: it is left out (massless, never moved).
  const double heaviest = *std::max_element(g.mass.begin(), g.mass.end());
  for (double& m : g.mass) {
    if (m < 1e-12 * heaviest) m = 0.0;
  }
  // The particles bucketed into slabs of kSlabCells cells along the first axis by their stencil's base (scatter).
  const auto slab_of = [&](std::size_t p) {
    return static_cast<std::size_t>((Stencil<D>(state.x[p], inv_dx).base[0] - g.lo[0]) / kSlabCells);
  };
  const std::size_t slabs = static_cast<std::size_t>(g.n[0] / kSlabCells) + 1;
  g.slab_start.assign(slabs + 1, 0);
  for (std::size_t p = 0; p < g.particles; ++p) ++g.slab_start[slab_of(p) + 1];
  for (std::size_t sl = 0; sl < slabs; ++sl) g.slab_start[sl + 1] += g.slab_start[sl];
  std::vector<std::uint32_t> fill(g.slab_start.begin(), g.slab_start.end() - 1);
  g.slab_order.resize(g.particles);
  for (std::size_t p = 0; p < g.particles; ++p) g.slab_order[fill[slab_of(p)]++] = static_cast<std::uint32_t>(p);
  g.clamp.assign(nodes, -1);
  for (std::size_t k = 0; k < nodes; ++k) {
    for (std::size_t c = 0; c < model.clamps.size() && g.clamp[k] < 0; ++c) {
      const auto& cl = model.clamps[c];
      if ((g.rest[k].array() >= cl.min.array()).all() && (g.rest[k].array() <= cl.max.array()).all())
        g.clamp[k] = static_cast<int>(c);
    }
  }
  // The state: nodes at their reference positions, moving with the particles' mass-weighted velocity.
  state.grid_x = g.rest;
  state.grid_v.assign(nodes, VecD<D>::Zero());
  for (std::size_t e = 0; e < g.particles * kS; ++e) {
    const std::size_t p = e / kS;
    state.grid_v[g.node[e]] += g.weight[e] * model.mass[p] * state.v[p];
  }
  for (std::size_t k = 0; k < nodes; ++k) {
    if (g.mass[k] > 0.0) state.grid_v[k] /= g.mass[k];
  }
  state.f.assign(g.particles, MatD<D>::Identity());
  return g;
}

template <int D>
StepStatus tl_step(const MpmModel<D>& model, const TlGrid<D>& grid, const AppliedField& field, MpmState<D>& state,
                   TlWorkspace<D>& ws, double dt) {
  check_state<D>(model, grid, state, dt);
  const std::size_t np = grid.particles;
  auto& s = *ws.impl;
  const std::vector<VecD<D>>& b = s.field;
  const std::vector<MatD<D>>& grad_b = s.field_gradient;
  std::vector<VecD<D>>& pull = s.pull;
  std::vector<MatD<D>>& stress = s.stress;
  pull.assign(np, VecD<D>::Zero());
  stress.resize(np);
  sample_field<D>(model, field, state, s.euler, s.field, s.field_gradient);
#pragma omp parallel for schedule(static) if (np > static_cast <std::size_t>(kParallelMin))
  for (std::int64_t pp = 0; pp < static_cast<std::int64_t>(np); ++pp) {
    const auto p = static_cast<std::size_t>(pp);
    const MatD<D>& f = state.f[p];  // F of the node positions, as the last step (or make_tl_grid) left it
    MatD<D> piola = elastic_stress<D>(model.materials[model.material[p]], f, model.plane);
    if (model.remanence[p].squaredNorm() > 0.0) {
      piola += magnetics::hard_magnetic_piola_stress<D>(b[p], model.remanence[p]);  // eq 3.13
      pull[p] = particle_pull<D>(model, p, f, grad_b[p]);
    }
    stress[p] = model.volume[p] * piola;
  }
  std::vector<VecD<D>>& force = s.force;
  force.resize(grid.rest.size());
  scatter<D>(grid, force, [&](std::size_t p, std::size_t e) {
    return VecD<D>(grid.weight[e] * pull[p] - stress[p] * grid.gradient[e]);
  });
  const double damp = 1.0 / (1.0 + model.damping * dt);
  for (std::size_t k = 0; k < grid.rest.size(); ++k) {
    const double m = grid.mass[k];
    if (!(m > 0.0)) continue;
    VecD<D>& v = state.grid_v[k];
    if (grid.clamp[k] >= 0) {
      v = model.clamps[static_cast<std::size_t>(grid.clamp[k])].velocity;
    } else {
      v = (v + dt * (force[k] / m + model.gravity)) * damp;
    }
    state.grid_x[k] += dt * v;
  }
  const std::int64_t bad = finish_particles<D>(model, grid, state, dt);
  state.time += dt;
  return particle_failure<D>(state, bad, dt, grid.cell);
}

template <int D>
StepStatus tl_implicit_step(const MpmModel<D>& model, const TlGrid<D>& grid, const AppliedField& field,
                            MpmState<D>& state, TlWorkspace<D>& ws, double dt, const ImplicitSettings& settings,
                            ImplicitStats* stats) {
  check_state<D>(model, grid, state, dt);
  ImplicitStats local;
  ImplicitStats& counted = stats ? *stats : local;
  counted = {};
  TlSolver<D> solver(model, grid, state, *ws.impl, dt, settings);
  const StepStatus solved = solver.solve(field, counted);
  if (!solved.ok) return {false, solved.cause + " at t = " + std::to_string(state.time) + " s"};
  solver.store(state);
  const std::int64_t bad = finish_particles<D>(model, grid, state, dt);
  state.time += dt;
  return particle_failure<D>(state, bad, dt, grid.cell);
}

template <int D>
StepStatus ImplicitStepper<D>::step(const MpmModel<D>& model, const AppliedField& field, MpmState<D>& state,
                                    MpmWorkspace<D>& ws, TlWorkspace<D>& tl_ws, double remaining,
                                    const ImplicitSettings& settings, ImplicitStats* stats) {
  for (;;) {
    const double dt = m_length.next(remaining);
    m_saved = state;
    ImplicitStats counted;
    const StepStatus st = m_grid != nullptr
                              ? tl_implicit_step<D>(model, *m_grid, field, state, tl_ws, dt, settings, &counted)
                              : implicit_step(model, field, state, ws, dt, settings, &counted);
    if (stats != nullptr) {
      stats->newton += counted.newton;
      stats->cg += counted.cg;
      stats->factorizations += counted.factorizations;
      stats->correction = counted.correction;
    }
    if (!m_length.record(st.ok, dt)) {
      if (st.ok) return st;
      StepStatus failed = st;
      failed.cause += " (after " + std::to_string(ImplicitStepLength::kMaxHalvings) + " halvings of the step)";
      return failed;
    }
    state = m_saved;
  }
}

template class ImplicitStepper<2>;
template class ImplicitStepper<3>;
template struct TlWorkspace<2>;
template struct TlWorkspace<3>;
template TlGrid<2> make_tl_grid<2>(const MpmModel<2>&, MpmState<2>&);
template TlGrid<3> make_tl_grid<3>(const MpmModel<3>&, MpmState<3>&);
template StepStatus tl_step<2>(const MpmModel<2>&, const TlGrid<2>&, const AppliedField&, MpmState<2>&,
                               TlWorkspace<2>&, double);
template StepStatus tl_step<3>(const MpmModel<3>&, const TlGrid<3>&, const AppliedField&, MpmState<3>&,
                               TlWorkspace<3>&, double);
template StepStatus tl_implicit_step<2>(const MpmModel<2>&, const TlGrid<2>&, const AppliedField&, MpmState<2>&,
                                        TlWorkspace<2>&, double, const ImplicitSettings&, ImplicitStats*);
template StepStatus tl_implicit_step<3>(const MpmModel<3>&, const TlGrid<3>&, const AppliedField&, MpmState<3>&,
                                        TlWorkspace<3>&, double, const ImplicitSettings&, ImplicitStats*);

}  // namespace magvine::mpm
