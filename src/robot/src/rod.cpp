#include "magvine/robot/rod.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include <Eigen/Eigenvalues>

#include "magvine/core/error.hpp"
#include "magvine/core/multiversion.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/magnetisation.hpp"
#include "magvine/robot/inflated_beam.hpp"
#include "rod_terms.hpp"

namespace magvine::robot {
namespace {

using detail::FieldSamples;
using detail::Inertia;
using detail::Mat6;
using detail::System;
using detail::TermContext;
using detail::Vec6;
using detail::exp_rotation;
using detail::joint_energy;
using detail::joint_strain;
using detail::rest_strain;
using detail::skew_axis;

constexpr double kMaxTurn = 0.5;  // [rad] largest frame rotation of one Newton step
// [relative] the damping past which a step the line search keeps rejecting ends the solve ("line search failed")
constexpr double kMaxRetryDamping = 1e-1;

/// Energy at load factor λ (the sum of the terms of rod_terms.hpp); adds its gradient to `sys` when given.
/// `samples`, when given, holds (or receives) the field at this state's edge midpoints; `from`, for a line-search
/// trial, is the iterate it moves from (TermContext::from).
double evaluate(const RodModel& m, const RodField& field, const RodState& s, double load, System* sys,
                const Inertia* inertia = nullptr, const RodConstraints* constraints = nullptr,
                FieldSamples* samples = nullptr, const RodState* from = nullptr) {
  const TermContext c{m, field, s, load, inertia, constraints, samples, from};
  return detail::rod_terms_energy(c, sys);
}

RodState apply(const RodState& s, const VecX& delta, double t);

/// The reference the analytic Hessian is tested against (rod_hessian with HessianMethod::finite_differences; the
/// solver used it before the analytic one). Fills the Hessian blocks of `sys` from central differences of the
/// analytic gradient: an unknown of block j
/// changes only the gradient of blocks j − 1 .. j + 1, so unknowns three blocks apart are perturbed together (36
/// gradient evaluations for any N). It carries every second-order term, the axial force's and the bending
/// moment's geometric stiffness and the field's curvature included; a Gauss–Newton matrix without them made Newton
/// crawl (hundreds of iterations) at large deflections. Symmetrised: with world-frame rotation increments the
/// derivative of the gradient differs from the Hessian by an antisymmetric part.
void finite_difference_hessian(const RodModel& m, const RodField& field, const RodState& s, double load,
                               System& sys, const Inertia* inertia, const RodConstraints* constraints) {
  const int n = m.edges;
  const double step_x = 1e-6 * m.length / n;  // relative to the edge: a strain step of 1e-6
  const double step_phi = 1e-6;
  std::vector<Mat6> diag(static_cast<std::size_t>(n), Mat6::Zero());
  std::vector<Mat6> lower(static_cast<std::size_t>(n), Mat6::Zero());  // H(j, j − 1)
  std::vector<Mat6> upper(static_cast<std::size_t>(n), Mat6::Zero());  // H(j − 1, j)
  System plus(n, false);
  System minus(n, false);
  VecX delta(6 * n);
  // Rotation columns move no node: the field at the midpoints is the base state's, sampled once here.
  FieldSamples samples;
  const bool magnetic = detail::Magnetic::active(TermContext{m, field, s, load});
  if (magnetic) {
    samples.reset(static_cast<std::size_t>(n));
    for (std::size_t j = 0; j < static_cast<std::size_t>(n); ++j) samples.at(field, s, j);
  }
  for (int colour = 0; colour < 3; ++colour) {
    for (int k = 0; k < 6; ++k) {
      const double step = k < 3 ? step_x : step_phi;
      delta.setZero();
      for (int j = colour; j < n; j += 3) delta[6 * j + k] = 1.0;
      plus.gradient.setZero();
      minus.gradient.setZero();
      FieldSamples* cached = k >= 3 && magnetic ? &samples : nullptr;
      evaluate(m, field, apply(s, delta, step), load, &plus, inertia, constraints, cached);
      evaluate(m, field, apply(s, delta, -step), load, &minus, inertia, constraints, cached);
      const VecX column = (plus.gradient - minus.gradient) / (2.0 * step);
      for (int j = colour; j < n; j += 3) {
        const auto ju = static_cast<std::size_t>(j);
        diag[ju].col(k) = column.segment<6>(6 * j);
        if (j > 0) upper[ju].col(k) = column.segment<6>(6 * (j - 1));
        if (j + 1 < n) lower[ju + 1].col(k) = column.segment<6>(6 * (j + 1));
      }
    }
  }
  for (std::size_t j = 0; j < diag.size(); ++j) {
    sys.diag[j] = 0.5 * (diag[j] + diag[j].transpose());
    if (j > 0) sys.sub[j] = 0.5 * (lower[j] + upper[j].transpose());
  }
}

/// The analytic Hessian of `evaluate` (rotation increments R ← exp([δφ])R, positions x ← x + δx), into sys.diag and
/// sys.sub: each term's own (rod_terms.hpp). Checked against finite_difference_hessian (central differences of the
/// whole gradient) in test_rod and term by term in test_rod_terms. `cache`, when given, holds (or receives) the field
/// at this state's edge midpoints.
void analytic_hessian(const RodModel& m, const RodField& field, const RodState& s, double load, System& sys,
                      const Inertia* inertia, const RodConstraints* constraints, FieldSamples* cache = nullptr) {
  const TermContext c{m, field, s, load, inertia, constraints, cache};
  detail::rod_terms_hessian(c, sys);
}

/// The LDLᵀ factor of a symmetric 6 × 6 block A (L unit lower triangular), read from the lower triangle of `a`: L
/// stored in the upper triangle of `packed` (L(i, j) at (j, i) for i > j), 1/D in `diagonal` (the substitutions
/// multiply instead of divide); false when A is not positive definite (a pivot D_j ≤ 0). No square roots: the
/// pivots form a chain (each column needs the previous one's), and a square root on it cost as much again as the
/// division. The loops have constant bounds (the triangle selected inside) so that they unroll completely (3×
/// faster than loops bounded by j).
bool ldlt(const Mat6& a, Mat6& packed, Vec6& diagonal) {
  Vec6 pivot;
  Vec6 w;
  for (int j = 0; j < 6; ++j) {
    double d = a(j, j);
    for (int k = 0; k < 6; ++k) {
      if (k >= j) continue;
      w[k] = packed(k, j) * pivot[k];  // L(j, k)·D_k
      d -= packed(k, j) * w[k];
    }
    if (!(d > 0.0)) return false;
    pivot[j] = d;
    diagonal[j] = 1.0 / d;
    for (int i = 0; i < 6; ++i) {
      if (i <= j) continue;
      double v = a(i, j);
      for (int k = 0; k < 6; ++k) {
        if (k < j) v -= packed(k, i) * w[k];
      }
      packed(j, i) = v * diagonal[j];
    }
  }
  return true;
}

/// v ← A⁻¹v = L⁻ᵀD⁻¹L⁻¹v for a factor of `ldlt`: forward, scale, then back substitution.
void ldlt_solve(const Mat6& packed, const Vec6& diagonal, Vec6& v) {
  for (int j = 0; j < 6; ++j) {
    for (int i = 0; i < 6; ++i) {
      if (i > j) v[i] -= packed(j, i) * v[j];
    }
  }
  v = v.cwiseProduct(diagonal);
  for (int j = 5; j >= 0; --j) {
    double r = v[j];
    for (int k = 0; k < 6; ++k) {
      if (k > j) r -= packed(j, k) * v[k];
    }
    v[j] = r;
  }
}

/// Block LDLᵀ (block Thomas) factorisation of H + μ|diag H| for the block-tridiagonal H of a System: the pivots
/// P_i = H_ii − H_i,i−1 P_{i−1}⁻¹ H_i,i−1ᵀ, each kept as its factor L_i D_i L_iᵀ (which also checks that it is positive
/// definite). P_{i−1}⁻¹ is never formed: with U = H_i,i−1 L_{i−1}⁻ᵀ (six substitutions) the update is
/// P_i = H_ii − U D_{i−1}⁻¹ Uᵀ, its lower triangle only. L_i lives in the upper triangle of the symmetric block H_ii,
/// which nothing else reads, and 1/D_i here: the factor costs 6 numbers per edge besides H. (An explicit inverse and
/// H_i,i−1 P_{i−1}⁻¹ per pivot took twice the arithmetic and 72 numbers per edge; at 100 edges the solver's buffers
/// then outgrew what the allocator keeps between solves, and every cold solve paid page faults for them.)
class BlockFactor {
 public:
  /// False when a pivot block is not positive definite (H + μ|diag H| is not). Writes the upper triangles of sys.diag.
  bool factor(System& sys, double mu) {
    m_sys = &sys;
    const auto n = sys.diag.size();
    m_diagonal.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      // Marquardt: damping in proportion to each unknown's own stiffness, so stiff stretch and soft bending are
      // damped alike (a multiple of I either stalls the bending or does nothing to the stretch).
      Mat6 p = sys.diag[i];
      if (mu > 0.0) p.diagonal() += mu * sys.diag[i].diagonal().cwiseAbs().cwiseMax(1e-300);
      if (i > 0) {
        const Mat6& l = sys.diag[i - 1];  // L_{i−1}(j, k) at (k, j)
        // U = H_i,i−1 L_{i−1}⁻ᵀ: the substitution works on U's columns, which are contiguous (Eigen is
        // column-major); then U D⁻¹ Uᵀ as one fixed-size product (the upper triangle it also fills is never read).
        Mat6 u = sys.sub[i];
        for (int j = 0; j < 6; ++j) {
          for (int k = 0; k < 6; ++k) {
            if (k < j) u.col(j) -= l(k, j) * u.col(k);
          }
        }
        p.noalias() -= (u * m_diagonal[i - 1].asDiagonal()) * u.transpose();
      }
      if (!ldlt(p, sys.diag[i], m_diagonal[i])) return false;
    }
    return true;
  }

  /// out = (H + μ|diag H|)⁻¹ rhs (out may be rhs); false if not finite. Forward: y_i = P_i⁻¹(rhs_i − H_i,i−1 y_{i−1});
  /// back: out_i = y_i − P_i⁻¹ H_i+1,iᵀ out_{i+1}.
  bool solve(const VecX& rhs, VecX& out) const {
    const auto n = m_diagonal.size();
    out.resize(static_cast<Eigen::Index>(6 * n));
    for (std::size_t i = 0; i < n; ++i) {
      const auto at = static_cast<Eigen::Index>(6 * i);
      Vec6 y = rhs.segment<6>(at);
      if (i > 0) y.noalias() -= m_sys->sub[i] * out.segment<6>(at - 6);
      ldlt_solve(m_sys->diag[i], m_diagonal[i], y);
      out.segment<6>(at) = y;
    }
    for (std::size_t i = n - 1; i-- > 0;) {
      const auto at = static_cast<Eigen::Index>(6 * i);
      Vec6 r = m_sys->sub[i + 1].transpose() * out.segment<6>(at + 6);
      ldlt_solve(m_sys->diag[i], m_diagonal[i], r);
      out.segment<6>(at) -= r;
    }
    return out.allFinite();
  }

 private:
  const System* m_sys = nullptr;
  std::vector<Vec6> m_diagonal;  ///< 1/D_i of each pivot (L_i: System::diag, see ldlt)
};

/// vᵀHv for the block-tridiagonal H, from the lower triangles of its diagonal blocks (the upper ones may hold a
/// factor).
double quadratic_form(const System& sys, const VecX& v) {
  double sum = 0.0;
  for (std::size_t i = 0; i < sys.diag.size(); ++i) {
    const auto at = static_cast<Eigen::Index>(6 * i);
    const Mat6& d = sys.diag[i];
    for (int b = 0; b < 6; ++b) {
      sum += d(b, b) * v[at + b] * v[at + b];
      for (int a = b + 1; a < 6; ++a) sum += 2.0 * d(a, b) * v[at + a] * v[at + b];
    }
    if (i > 0) sum += 2.0 * v.segment<6>(at).dot(sys.sub[i] * v.segment<6>(at - 6));
  }
  return sum;
}

/// out = the state s moved by t·δ (nodes linearly, frames by exp([t δφ_j])); out's storage is reused.
void apply(const RodState& s, const VecX& delta, double t, RodState& out) {
  out.x.resize(s.x.size());
  out.frames.resize(s.frames.size());
  out.x[0] = s.x[0];
  for (std::size_t j = 0; j < s.frames.size(); ++j) {
    out.x[j + 1] = s.x[j + 1] + t * delta.segment<3>(static_cast<Eigen::Index>(6 * j));
    out.frames[j] = exp_rotation(t * delta.segment<3>(static_cast<Eigen::Index>(6 * j + 3))) * s.frames[j];
  }
}

RodState apply(const RodState& s, const VecX& delta, double t) {
  RodState out;
  apply(s, delta, t, out);
  return out;
}

/// The nodes `x` of the step t·δ from `s` rebuilt from the clamp along the new frames (those of `trial`, the step
/// applied by `apply`): each edge gets the body-frame vector the step predicts to first order,
/// R_jᵀe_j + t(R_jᵀ(δx_{j+1} − δx_j) + R_jᵀ[e_j]δφ_j), instead of the linearly moved nodes, whose edges a large
/// rotation stretches.
void rebuild_positions(const RodState& trial, const RodState& s, const VecX& delta, double t, std::vector<Vec3>& x) {
  x.resize(trial.x.size());
  x[0] = trial.x[0];
  const auto dx = [&](std::size_t node) {
    return node == 0 ? Vec3::Zero().eval() : Vec3(delta.segment<3>(static_cast<Eigen::Index>(6 * (node - 1))));
  };
  for (std::size_t j = 0; j < trial.frames.size(); ++j) {
    const Mat3& r = s.frames[j];
    const Vec3 e = s.x[j + 1] - s.x[j];
    const Vec3 dphi = delta.segment<3>(static_cast<Eigen::Index>(6 * j + 3));
    const Vec3 local = r.transpose() * (e + t * (dx(j + 1) - dx(j) + e.cross(dphi)));
    x[j + 1] = x[j] + trial.frames[j] * local;
  }
}

/// The bending stiffness that sets the scale of forces (EI/L²) and torques (EI/L): EI for a rod; for a vine the
/// smaller of its wall EI and M_c·L (the moment it can carry), but not below its flat film's EI.
double bending_scale(const RodModel& m) {
  if (!m.inflated) return std::max(m.bending_stiffness_2, m.bending_stiffness_3);
  const double carried = collapse_moment(m.inflated->radius, m.inflated->pressure) * m.length;
  return std::max(std::min(m.bending_stiffness_3, carried), m.inflated->flat_bending_stiffness);
}

/// Gradient norm in units of EI/L² (forces) and EI/L (torques), max over components.
double scaled_norm(const RodModel& m, const VecX& g) {
  const double ei = bending_scale(m);
  double worst = 0.0;
  for (Eigen::Index i = 0; i < g.size(); ++i) {
    const double scale = (i % 6) < 3 ? ei / (m.length * m.length) : ei / m.length;
    worst = std::max(worst, std::abs(g[i]) / scale);
  }
  return worst;
}

/// The scaled gradient that round-off alone produces: the strains' round-off times the axial and shear stiffness,
/// in units of EI/L². A slender rod (EA L²/EI = 12 (L/t)²) cannot converge below it. An edge vector is a difference
/// of two positions, each rounded to ε·|x|, so a strain carries ε·|x|/h of round-off: 1e3·ε is allowed wherever
/// |x|/h ≤ 250 (a body within 0.25 m of the origin at 1 mm edges), 4ε·|x|/h beyond (h the mean edge; the factor
/// covers a tip edge half as long). A patient's CT frame puts the airway 1.4 m from its origin; there a 1.5 mm-edge
/// vine's gradient bounced at 4–6.5e-6 against the old floor of 4.4e-6 for dozens of iterations of a converged
/// solve (traced in the needle's punctures, which still fail for another reason: docs/ct.md).
double noise_floor(const RodModel& m, const RodState& s) {
  const double ei = bending_scale(m);
  double reach = 0.0;  // the largest coordinate [m]
  for (const Vec3& x : s.x) reach = std::max(reach, x.cwiseAbs().maxCoeff());
  const double strain_roundoff =
      std::numeric_limits<double>::epsilon() * std::max(1e3, 4.0 * reach * m.edges / m.length);
  return strain_roundoff * std::max(m.axial_stiffness, m.shear_stiffness) * m.length * m.length / ei;
}

}  // namespace

void check_rod_model(const RodModel& m) {
  const auto positive = [](const char* field, double v) {
    if (!(v > 0.0) || !std::isfinite(v)) {
      throw InputError(std::string("rod: ") + field + " = " + std::to_string(v) + " (must be > 0)");
    }
  };
  positive("length", m.length);
  positive("bending_stiffness_2", m.bending_stiffness_2);
  positive("bending_stiffness_3", m.bending_stiffness_3);
  positive("torsional_stiffness", m.torsional_stiffness);
  positive("axial_stiffness", m.axial_stiffness);
  positive("shear_stiffness", m.shear_stiffness);
  if (m.edges < 1) throw InputError("rod: edges = " + std::to_string(m.edges) + " (must be >= 1)");
  if (!(m.tip_edge_length >= 0.0) || !(m.tip_edge_length < m.length) ||
      (m.tip_edge_length > 0.0 && m.edges < 2)) {
    throw InputError("rod: tip_edge_length must be in [0, length) and needs at least two edges");
  }
  if (!(m.mass_per_length >= 0.0) || !std::isfinite(m.mass_per_length)) {
    throw InputError("rod: mass_per_length must be finite and >= 0");
  }
  if (!m.base_position.allFinite() || !m.gravity.allFinite() || !m.tip_force.allFinite() || !m.tip_moment.allFinite()) {
    throw InputError("rod: base position, gravity, tip force and tip moment must be finite");
  }
  if (!m.moment_per_length.empty() && m.moment_per_length.size() != static_cast<std::size_t>(m.edges)) {
    throw InputError("rod: moment_per_length needs one entry per edge");
  }
  if (!m.rest_strain.empty() && m.rest_strain.size() != static_cast<std::size_t>(m.edges)) {
    throw InputError("rod: rest_strain needs one entry per edge");
  }
  for (const Vec3& w : m.rest_strain) {
    if (!w.allFinite()) throw InputError("rod: rest_strain must be finite");
  }
  if (!(m.base_frame.transpose() * m.base_frame).isApprox(Mat3::Identity(), 1e-9)) {
    throw InputError("rod: base_frame must be orthonormal");
  }
  if (m.inflated) {
    const InflatedBending& v = *m.inflated;
    positive("radius", v.radius);
    if (!(v.pressure >= 0.0) || !std::isfinite(v.pressure)) throw InputError("vine: pressure must be >= 0");
    if (!(v.flat_bending_stiffness >= 0.0)) throw InputError("vine: flat_bending_stiffness must be >= 0");
    if (v.pressure == 0.0 && v.flat_bending_stiffness == 0.0) {
      throw InputError("vine: at zero pressure the flat film's bending stiffness must be > 0 (nothing else resists)");
    }
  }
  if (m.induced) {
    const magnetics::InducedMagnetisation& f = m.induced->law;
    if (!(m.induced->volume_per_length >= 0.0) || !(f.axial_susceptibility >= 0.0) ||
        !(f.transverse_susceptibility >= 0.0) || !(f.saturation > 0.0) || !(f.reference_susceptibility > 0.0)) {
      throw InputError("rod: induced magnetisation needs volume, susceptibilities >= 0 and saturation > 0");
    }
  }
}

namespace {

/// The scratch of Newton's iterations, sized on first use: an iteration allocates nothing. States and field samples
/// change hands by swapping their storage.
struct NewtonScratch {
  System sys{0};
  System probe{0, false};  ///< the gradient at a step taken on the gradient's word (newton; rare)
  BlockFactor factor;
  VecX delta;      ///< the Newton step
  VecX z;          ///< a direction of negative curvature (damped steps only)
  RodState trial;  ///< a trial step, then the better of it and its rebuilt nodes
  std::vector<Vec3> rebuilt;  ///< the trial's nodes rebuilt along its frames
  RodState next;   ///< the Newton step's trial while one along z competes (rare)
  /// At the state being iterated, for its gradient and Hessian. The line search's trials do not keep theirs: one
  /// buffer per trial (the winner's then saves the next gradient ~100 samples) kept the buffers of a cold solve at
  /// 100 edges above what the allocator holds between solves, and the page faults cost more than the samples.
  FieldSamples current;

  void size(int edges) {
    if (sys.diag.size() != static_cast<std::size_t>(edges)) sys = System(edges);
  }
};

}  // namespace

struct RodWorkspace::Impl {
  int edges = -1;  ///< the Hessian below belongs to a rod of this many edges (−1: none yet)
  std::vector<Mat6> diag;
  std::vector<Mat6> sub;
  NewtonScratch scratch;  ///< kept between solves
};

RodWorkspace::RodWorkspace() : impl(std::make_unique<Impl>()) {}
RodWorkspace::~RodWorkspace() = default;
RodWorkspace::RodWorkspace(RodWorkspace&&) noexcept = default;
RodWorkspace& RodWorkspace::operator=(RodWorkspace&&) noexcept = default;
void RodWorkspace::forget_hessian() { impl->edges = -1; }

namespace {

/// Newton at a fixed load factor. Returns the cause of failure, empty on success. With a workspace, chord steps
/// reuse its Hessian until one fails to cut the gradient by a fifth (or to factor, to descend, or to pass the line
/// search); then it is recomputed. Built for baseline x86-64 and for x86-64-v3 (magvine/core/multiversion.hpp), with
/// the energy, the Hessian and the factorisation inlined into each copy.
MAGVINE_HOT_KERNEL std::string newton(const RodModel& m, const RodField& field, RodState& s, double load,
                                      const RodSolveOptions& o, RodSolveReport& report, int max_iterations,
                                      NewtonScratch& w, const Inertia* inertia = nullptr,
                                      RodWorkspace::Impl* ws = nullptr, const RodConstraints* constraints = nullptr) {
  bool fresh = ws == nullptr || ws->edges != m.edges || !o.reuse_hessian;
  bool last_was_chord = false;
  double previous_norm = std::numeric_limits<double>::infinity();
  const auto edges = static_cast<std::size_t>(m.edges);
  w.size(m.edges);
  w.current.reset(edges);
  System& sys = w.sys;
  BlockFactor& factor = w.factor;
  VecX& delta = w.delta;
  double mu_hint = 0.0;  // the Levenberg damping the last damped step needed
  // The least damping of the next step: raised after a step the line search rejected, relaxed tenfold per step
  // taken.
  double damping_floor = 0.0;
  const auto relax = [](double floor) { return floor > 1e-5 ? 0.1 * floor : 0.0; };
  for (int it = 0; it < max_iterations; ++it) {
    if (report.iterations >= o.max_iterations) {
      return "iteration budget of " + std::to_string(o.max_iterations) + " Newton iterations exhausted";
    }
    sys.gradient.setZero();
    const double energy = evaluate(m, field, s, load, &sys, inertia, constraints, &w.current);
    if (!std::isfinite(energy) || !sys.gradient.allFinite()) return "NaN in the energy or its gradient";
    report.gradient_norm = scaled_norm(m, sys.gradient);
    if (report.gradient_norm <= std::max(o.tolerance, noise_floor(m, s))) return {};
    if (last_was_chord && report.gradient_norm > 0.8 * previous_norm) fresh = true;
    previous_norm = report.gradient_norm;
    ++report.iterations;
    bool chord = !fresh;
    const auto refresh = [&] {
      analytic_hessian(m, field, s, load, sys, inertia, constraints, &w.current);
      ++report.hessians;
      chord = false;
      if (ws != nullptr) {
        ws->diag = sys.diag;
        ws->sub = sys.sub;
        ws->edges = m.edges;
      }
    };
    if (chord) {
      sys.diag = ws->diag;
      sys.sub = ws->sub;
    } else {
      refresh();
    }
    // Levenberg damping only when the Hessian is not positive definite (near a snap, or a field against the
    // magnetisation) or the step is not a descent direction; a chord Hessian that needs it is recomputed first.
    double mu = damping_floor;
    for (;;) {
      // delta = H⁻¹g first, negated below: −H⁻¹g is a descent direction when g·H⁻¹g > 0.
      if (factor.factor(sys, mu) && factor.solve(sys.gradient, delta) && sys.gradient.dot(delta) > 0.0) break;
      if (chord) {
        refresh();
        continue;
      }
      // Restart from a quarter of the damping the last damped step needed (not from 1e-9 every iteration: from
      // straight under the EPM that cost ~10 factorisations per iteration).
      mu = mu == 0.0 ? std::max(1e-9, 0.25 * mu_hint) : 4.0 * mu;
      if (mu > 1e8) return "no descent direction";
    }
    delta = -delta;
    mu_hint = mu > 0.0 ? mu : 0.25 * mu_hint;
    last_was_chord = chord;
    fresh = ws == nullptr || !o.reuse_hessian;
    // Converged when the undamped Newton step itself is below 1e-10 rad and 1e-10 L: the gradient can stall above
    // its tolerance from round-off alone (the strains of short edges carry ~1e-16·N relative error, times a stiff
    // EA), while the step the exact model asks for is already negligible.
    if (mu == 0.0 && !chord) {
      double turn = 0.0;
      double move = 0.0;
      for (Eigen::Index j = 0; j < m.edges; ++j) {
        move = std::max(move, delta.segment<3>(6 * j).norm());
        turn = std::max(turn, delta.segment<3>(6 * j + 3).norm());
      }
      if (turn < 1e-10 && move < 1e-10 * m.length) return {};
    }
    // Past a limit point the state sits near a saddle of the energy, where the gradient along the unstable mode is
    // tiny and damped Newton steps crawl. A few inverse iterations with the damped factor find the most negative
    // curvature direction; a trust-sized step along it (downhill) competes with the Newton step below.
    // The step along it is w.z times descent_sign.
    bool has_descent = false;
    double descent_sign = 1.0;
    if (mu > 0.0) {
      VecX& z = w.z;
      z = delta / delta.norm();
      for (int k = 0; k < 4 && factor.solve(z, z); ++k) z /= z.norm();
      if (z.allFinite() && quadratic_form(sys, z) < 0.0) {
        has_descent = true;
        descent_sign = sys.gradient.dot(z) > 0.0 ? -1.0 : 1.0;
      }
    }
    const double slope = sys.gradient.dot(delta);
    // A trust bound on the rotation increments: frames turn exactly but positions move linearly, so a long step
    // bends without the matching node motion and stretches the edges (the rebuilt trial below repairs most of it).
    // 0.5 rad: from the straight beam under 10 mT, 6 Newton iterations instead of 33 at 0.1 rad (bench_rod), the
    // same equilibria in every test and in `magvine validate` (angles equal to 1e-3), fewer iterations at snaps.
    double largest = 0.0;
    for (Eigen::Index j = 0; j < m.edges; ++j) largest = std::max(largest, delta.segment<3>(6 * j + 3).norm());
    double t = largest > kMaxTurn ? kMaxTurn / largest : 1.0;
    const double t0 = t;
    // Below ~1e-13 of the energy's size the energy cannot tell better from worse: take the (bounded) step.
    const bool resolvable = -slope > 1e-13 * (std::abs(energy) + 1e-300);
    // Positions move linearly but frames turn exactly, so a bending step also stretches the edges, which stalls a
    // slender (axially stiff) rod on tiny steps. Each trial is also offered with its nodes rebuilt along the new
    // frames at the strains the step predicts; the lower energy wins (test_rod's 12 large-deflection cases: 9–147
    // Newton iterations with it; 1092–7196 without, and one case failed). The winner is left in w.trial.
    const auto trial_at = [&](const VecX& step, double scale) {
      apply(s, step, scale, w.trial);
      const double e = evaluate(m, field, w.trial, load, nullptr, inertia, constraints, nullptr, &s);
      rebuild_positions(w.trial, s, step, scale, w.rebuilt);
      std::swap(w.trial.x, w.rebuilt);  // w.trial is now the rebuilt state (the same frames)
      const double e_rebuilt = evaluate(m, field, w.trial, load, nullptr, inertia, constraints, nullptr, &s);
      if (std::isfinite(e_rebuilt) && !(e_rebuilt >= e)) return e_rebuilt;
      std::swap(w.trial.x, w.rebuilt);
      return e;
    };
    double e_next = std::numeric_limits<double>::infinity();  // of the step taken: in w.trial, or w.next if kept
    bool in_next = false;
    for (;;) {
      const double e = trial_at(delta, t);
      if (std::isfinite(e) && (!resolvable || e <= energy + 1e-4 * t * slope)) {
        e_next = e;
        break;
      }
      t *= 0.5;
      if (t < 1e-10) break;
    }
    if (has_descent) {
      if (std::isfinite(e_next)) {  // keep the Newton step's trial while the descent's trials use w.trial
        std::swap(w.next, w.trial);
        in_next = true;
      }
      double turn = 0.0;
      for (Eigen::Index j = 0; j < m.edges; ++j) turn = std::max(turn, w.z.segment<3>(6 * j + 3).norm());
      for (double scale = turn > 0.0 ? kMaxTurn / turn : 0.0; scale > 1e-6 * kMaxTurn; scale *= 0.25) {
        const double e = trial_at(w.z, descent_sign * scale);
        if (std::isfinite(e) && e < std::min(e_next, energy)) {
          e_next = e;
          in_next = false;
          break;
        }
      }
    }
    // A step cut below a thousandth by the line search makes no progress: the energy's round-off (large cancelling
    // terms: a penalty contact's k·d², d a difference of positions whose last digits carry ~1e-18 m)
    // hides the decrease that the gradient still shows. Let the gradient decide as below.
    if (std::isfinite(e_next) && t < 1e-3 * t0 && !chord) e_next = std::numeric_limits<double>::infinity();
    if (!std::isfinite(e_next)) {
      if (chord) {  // the old Hessian misled the step: recompute it and try again
        fresh = true;
        last_was_chord = false;
        continue;
      }
      // At round-off the energy cannot resolve the last digits; accept a nearly converged state.
      if (report.gradient_norm <= 1e3 * o.tolerance) return {};
      // The Newton step's energy change can sink below the energy's round-off while the gradient is still large
      // in stiff directions (stretch, wall contacts: g·H⁻¹g ≪ the ~1e-16 relative error of an energy made of large
      // cancelling terms). Then the gradient, not the energy, decides: the (trust-bounded) step is taken if it
      // cuts the scaled gradient by a tenth.
      apply(s, delta, t0, w.trial);
      if (w.probe.gradient.size() != sys.gradient.size()) w.probe = System(m.edges, false);
      w.probe.gradient.setZero();
      const double e_probe = evaluate(m, field, w.trial, load, &w.probe, inertia, constraints, nullptr, &s);
      if (!std::isfinite(e_probe) || !(scaled_norm(m, w.probe.gradient) < 0.9 * report.gradient_norm)) {
        // The quadratic model misled the step (a contact met within its smooth zone, a field gradient's
        // negative stiffness): damp harder, towards a short step down the gradient scaled by the stiffness, which
        // the energy does resolve (Levenberg–Marquardt's rejected step).
        if (mu >= kMaxRetryDamping) return "line search failed";
        damping_floor = std::max(1e-4, 10.0 * mu);
        fresh = true;
        last_was_chord = false;
        continue;
      }
      std::swap(s, w.trial);
      w.current.reset(edges);
      damping_floor = relax(damping_floor);
      continue;
    }
    std::swap(s, in_next ? w.next : w.trial);
    w.current.reset(edges);
    damping_floor = relax(damping_floor);
  }
  return "Newton did not converge in " + std::to_string(max_iterations) + " iterations";
}

}  // namespace

RodModel rectangular_rod(double length, double width, double thickness, double shear_modulus, double density,
                         double remanence, const Vec3& direction, int edges, double stretch_shear_factor) {
  RodModel m;
  const double e = 3.0 * shear_modulus;
  const double area = width * thickness;
  m.length = length;
  m.edges = edges;
  m.bending_stiffness_2 = e * thickness * std::pow(width, 3) / 12.0;  // about d2: bending across the width
  m.bending_stiffness_3 = e * width * std::pow(thickness, 3) / 12.0;  // about d3: bending along d2 (thickness)
  // Saint-Venant torsion of a rectangle a ≥ b: J ≈ a b³ (1/3 − 0.21 (b/a)(1 − b⁴/(12 a⁴))).
  const double a = std::max(width, thickness);
  const double b = std::min(width, thickness);
  m.torsional_stiffness =
      shear_modulus * a * b * b * b * (1.0 / 3.0 - 0.21 * (b / a) * (1.0 - std::pow(b / a, 4) / 12.0));
  m.axial_stiffness = stretch_shear_factor * e * area;
  m.shear_stiffness = stretch_shear_factor * 5.0 / 6.0 * shear_modulus * area;  // Timoshenko factor of a rectangle
  m.mass_per_length = density * area;
  m.rotational_inertia_per_length = density * (width * std::pow(thickness, 3) + thickness * std::pow(width, 3)) / 24.0;
  if (remanence != 0.0)
    m.moment_per_length.assign(static_cast<std::size_t>(edges),
                               magnetics::hard_magnetic_moment<3>(Vec3(remanence * direction.normalized()), area));
  return m;
}

RodModel circular_rod(double length, double diameter, double shear_modulus, double density, int edges,
                      double stretch_shear_factor) {
  RodModel m;
  const double e = 3.0 * shear_modulus;
  const double area = 0.25 * kPi * diameter * diameter;
  const double second_moment = kPi * std::pow(diameter, 4) / 64.0;
  m.length = length;
  m.edges = edges;
  m.bending_stiffness_2 = e * second_moment;
  m.bending_stiffness_3 = e * second_moment;
  m.torsional_stiffness = shear_modulus * 2.0 * second_moment;
  m.axial_stiffness = stretch_shear_factor * e * area;
  m.shear_stiffness = stretch_shear_factor * 0.9 * shear_modulus * area;  // Timoshenko 6(1+ν)/(7+6ν), ν = ½
  m.mass_per_length = density * area;
  m.rotational_inertia_per_length = density * second_moment;
  return m;
}

RodModel circular_tube_rod(double length, double outer_diameter, double inner_diameter, double shear_modulus,
                           double density, int edges, double stretch_shear_factor) {
  RodModel m = circular_rod(length, outer_diameter, shear_modulus, density, edges, stretch_shear_factor);
  const double e = 3.0 * shear_modulus;
  const double area = 0.25 * kPi * (outer_diameter * outer_diameter - inner_diameter * inner_diameter);
  const double second_moment = kPi * (std::pow(outer_diameter, 4) - std::pow(inner_diameter, 4)) / 64.0;
  m.bending_stiffness_2 = e * second_moment;
  m.bending_stiffness_3 = e * second_moment;
  m.torsional_stiffness = shear_modulus * 2.0 * second_moment;
  m.axial_stiffness = stretch_shear_factor * e * area;
  m.shear_stiffness = stretch_shear_factor * 0.55 * shear_modulus * area;
  m.mass_per_length = density * area;
  m.rotational_inertia_per_length = density * second_moment;
  return m;
}

std::vector<double> joint_angles(const RodModel& model, const RodState& state) {
  std::vector<double> out;
  out.reserve(state.frames.size());
  for (std::size_t j = 0; j < state.frames.size(); ++j) {
    const Mat3 q = detail::joint_first_frame(model, state, static_cast<int>(j)).transpose() * state.frames[j];
    out.push_back(std::atan2(skew_axis(q).norm(), 0.5 * (q.trace() - 1.0)));
  }
  return out;
}

std::vector<double> joint_bending_moments(const RodModel& model, const RodState& state) {
  std::vector<double> out;
  for (int j = 0; j < model.edges; ++j) {
    const Mat3& ra = detail::joint_first_frame(model, state, j);
    const double ell = detail::joint_length(model, j);
    const Mat3 q = ra.transpose() * state.frames[static_cast<std::size_t>(j)];
    Vec3 stress;
    const Vec3 omega = joint_strain(q, ell);
    joint_energy(model, ell, omega - rest_strain(model, j), stress);
    // dW/dψ = dW/dκ · dκ/dψ with κ = 2 tan(ψ/2)/ℓ: the stress over ℓ times 1 + tan²(ψ/2).
    const double t = 0.5 * ell * omega.tail<2>().norm();
    out.push_back(stress.tail<2>().norm() / ell * (1.0 + t * t));
  }
  return out;
}

FlatteningLaw flattening_law(const FlatteningSection& section, double radius, double depth) {
  const double d = std::max(0.0, depth);
  if (section.cap) {
    const double k = 2.0 * kPi * section.pressure * radius;  // F = 2πPRδ
    return {0.5 * k * d * d, k * d, k};
  }
  const double c = section.pressure * section.length * std::sqrt(8.0 * radius);  // F = c√δ
  const double root = std::sqrt(d);
  return {2.0 / 3.0 * c * d * root, c * root, root > 0.0 ? 0.5 * c / root : std::numeric_limits<double>::infinity()};
}

std::vector<NodeWallForce> wall_barrier_forces(const RodState& state, const WallBarrier& wall) {
  std::vector<NodeWallForce> out(state.x.size());
  std::vector<Mat3> spread(state.x.size(), Mat3::Zero());
  const bool clear = detail::WallBarrierTerm::for_each_node(state, nullptr, wall, [&](const detail::NodeContact& n) {
    for (const anatomy::NearTriangle& t : n.near) {
      const double f = detail::barrier_force(wall, n.gap(t));
      const Vec3 normal = n.normal(t);
      out[n.node].force += f * normal;
      out[n.node].magnitude += f;
      spread[n.node] += f * normal * normal.transpose();
    }
    out[n.node].radius = n.radius;
  });
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (out[i].magnitude <= 0.0) continue;
    const Eigen::SelfAdjointEigenSolver<Mat3> eigen(spread[i]);
    out[i].axis = eigen.eigenvectors().col(2);
    if (out[i].axis.dot(out[i].force) < 0.0) out[i].axis = -out[i].axis;
  }
  if (!clear) {
    for (std::size_t i = 1; i < state.x.size() && i < wall.radius.size(); ++i) {
      std::array<anatomy::NearTriangle, 1> near{};
      if (wall.radius[i] > 0.0 && wall.world->triangles_within(state.x[i], rigid_radius(wall, i), near) > 0) {
        out[i].magnitude = std::numeric_limits<double>::infinity();
      }
    }
  }
  return out;
}

Vec3 clamp_force(const RodModel& model, const RodField& field, const RodState& state) {
  const TermContext c{model, field, state};
  const auto e = detail::StretchShear::edge(c, 0);
  Vec3 force = -(e.r * e.stress) / e.h;  // the first edge's pull on x_0 (dW/de = Rσ/h), reversed
  if (detail::Magnetic::active(c)) {
    // Half the first edge's magnetic force acts on x_0, which the clamp holds (magnetics::magnetic_wrench).
    const Vec3 hard = model.moment_per_length.empty() ? Vec3::Zero() : detail::Magnetic::hard_moment(c, 0);
    const magnetics::FieldSample f = field(detail::edge_midpoint(state, 0));
    double energy = 0.0;
    const Vec3 moment =
        detail::Magnetic::effective_moment(c, hard, detail::Magnetic::fill_volume(c, 0), state.frames[0], f, energy);
    force -= 0.5 * magnetics::magnetic_wrench(moment, f).force;
  }
  return force;
}

Vec3 body_load(const RodModel& model, const RodField& field, const RodState& state) {
  const TermContext c{model, field, state};
  Vec3 total = model.tip_force;
  for (std::size_t i = 1; i < state.x.size(); ++i) total += detail::lumped_mass(model, i) * model.gravity;
  if (!detail::Magnetic::active(c)) return total;
  for (int j = 0; j < model.edges; ++j) {
    const auto ju = static_cast<std::size_t>(j);
    const Vec3 hard = model.moment_per_length.empty() ? Vec3::Zero() : detail::Magnetic::hard_moment(c, ju);
    const magnetics::FieldSample f = field(detail::edge_midpoint(state, ju));
    double energy = 0.0;
    const Vec3 moment =
        detail::Magnetic::effective_moment(c, hard, detail::Magnetic::fill_volume(c, j), state.frames[ju], f, energy);
    total += magnetics::magnetic_wrench(moment, f).force;
  }
  return total;
}

Vec3 friction_slip(const NodeFriction& f, const Vec3& x) {
  const Vec3 d = x - f.reference;
  return d - f.normal.dot(d) * f.normal - f.free.dot(d) * f.free;
}

Vec3 friction_force(const NodeFriction& f, const Vec3& x) {
  const Vec3 u = friction_slip(f, x);
  return -f.coefficient * f.normal_force * detail::friction_law(u.norm(), f.slip).force_per * u;
}

double tip_contact_depth(const TipContact& contact, const Vec3& x) {
  return contact.depth + (x - contact.origin).dot(contact.axis);
}

Vec3 tip_contact_force(const TipContact& contact, const Vec3& x) {
  return -contact.law(tip_contact_depth(contact, x)).force * contact.axis;
}

RodState straight_rod(const RodModel& model) {
  RodState s;
  const Vec3 t = model.base_frame.col(0);
  const double h = uniform_edge_length(model);
  for (int i = 0; i < model.edges; ++i) s.x.push_back(model.base_position + i * h * t);
  // (N·h for a uniform rod, as before the tip edge had its own length: the same bits.)
  s.x.push_back(model.tip_edge_length > 0.0 ? Vec3(s.x.back() + model.tip_edge_length * t)
                                            : Vec3(model.base_position + model.edges * h * t));
  s.frames.assign(static_cast<std::size_t>(model.edges), model.base_frame);
  return s;
}

double rod_energy(const RodModel& model, const RodField& field, const RodState& state, double load,
                  const RodConstraints* constraints) {
  return evaluate(model, field, state, load, nullptr, nullptr, constraints);
}

VecX rod_gradient(const RodModel& model, const RodField& field, const RodState& state, double load,
                  const RodConstraints* constraints) {
  System sys(model.edges);
  evaluate(model, field, state, load, &sys, nullptr, constraints);
  return sys.gradient;
}

MatX rod_hessian(const RodModel& model, const RodField& field, const RodState& state, double load,
                 HessianMethod method, const RodConstraints* constraints) {
  System sys(model.edges);
  if (method == HessianMethod::analytic) {
    analytic_hessian(model, field, state, load, sys, nullptr, constraints);
  } else {
    finite_difference_hessian(model, field, state, load, sys, nullptr, constraints);
  }
  const auto n = static_cast<Eigen::Index>(model.edges);
  MatX out = MatX::Zero(6 * n, 6 * n);
  for (Eigen::Index j = 0; j < n; ++j) {
    out.block<6, 6>(6 * j, 6 * j) = sys.diag[static_cast<std::size_t>(j)];
    if (j == 0) continue;
    out.block<6, 6>(6 * j, 6 * (j - 1)) = sys.sub[static_cast<std::size_t>(j)];
    out.block<6, 6>(6 * (j - 1), 6 * j) = sys.sub[static_cast<std::size_t>(j)].transpose();
  }
  return out;
}

MatX rod_moment_sensitivity(const RodModel& model, const RodField& field, const RodState& state) {
  check_rod_model(model);
  MatX out = MatX::Zero(6 * model.edges, 3 * model.edges);
  const TermContext c{model, field, state};
  detail::Magnetic::add_moment_sensitivity(c, out);
  return out;
}

MatX rod_uniform_field_sensitivity(const RodModel& model, const RodState& state) {
  check_rod_model(model);
  if (model.induced) throw InputError("rod sensitivity: a uniform field's sensitivity needs hard moments only (no fill)");
  MatX out = MatX::Zero(6 * model.edges, 3);
  const RodField none;
  const TermContext c{model, none, state};
  detail::Magnetic::add_uniform_field_sensitivity(c, out);
  return out;
}

MatX rod_field_translation_sensitivity(const RodModel& model, const RodField& field, const RodState& state) {
  check_rod_model(model);
  MatX out = MatX::Zero(6 * model.edges, 3);
  const TermContext c{model, field, state};
  detail::Magnetic::add_field_translation_sensitivity(c, out);
  return out;
}

std::optional<MatX> rod_hessian_solve(const RodModel& model, const RodField& field, const RodState& state,
                                      const MatX& rhs, const RodConstraints* constraints) {
  check_rod_model(model);
  if (rhs.rows() != 6 * model.edges) throw InputError("rod sensitivity: the right-hand side has the wrong size");
  System sys(model.edges);
  analytic_hessian(model, field, state, 1.0, sys, nullptr, constraints);
  BlockFactor factor;
  if (!factor.factor(sys, 0.0)) return std::nullopt;
  MatX out(rhs.rows(), rhs.cols());
  VecX column;
  for (Eigen::Index c = 0; c < rhs.cols(); ++c) {
    if (!factor.solve(rhs.col(c), column)) return std::nullopt;
    out.col(c) = column;
  }
  return out;
}

VecX rod_position_covector(const std::vector<Vec3>& per_node) {
  const auto edges = static_cast<int>(per_node.size()) - 1;
  VecX out = VecX::Zero(6 * std::max(0, edges));
  for (int i = 1; i <= edges; ++i) out.segment<3>(6 * (i - 1)) = per_node[static_cast<std::size_t>(i)];
  return out;
}

RodMotion rod_at_rest(const RodModel& model) {
  RodMotion out;
  out.velocity.assign(static_cast<std::size_t>(model.edges) + 1, Vec3::Zero());
  out.angular_velocity.assign(static_cast<std::size_t>(model.edges), Vec3::Zero());
  return out;
}

RodSolveReport step_rod_dynamics(const RodModel& model, const RodField& field, RodState& state, RodMotion& motion,
                                 double dt, const RodSolveOptions& options) {
  check_rod_model(model);
  if (!(dt > 0.0) || !std::isfinite(dt)) throw InputError("rod dynamics: dt must be > 0");
  const auto n = static_cast<std::size_t>(model.edges);
  if (state.x.size() != n + 1 || motion.velocity.size() != n + 1 || motion.angular_velocity.size() != n) {
    throw InputError("rod dynamics: the state or motion does not match the model's edge count");
  }
  const double h = uniform_edge_length(model);  // (the dynamics keep every edge at h: no growing tip edge)
  Inertia inertia;
  inertia.dt = dt;
  inertia.rotational = model.rotational_inertia_per_length * h;
  inertia.x.resize(n + 1);
  inertia.mass.resize(n + 1);
  inertia.frames.resize(n);
  for (std::size_t i = 0; i <= n; ++i) {
    inertia.x[i] = state.x[i] + dt * motion.velocity[i];
    inertia.mass[i] = detail::lumped_mass(model, i);
  }
  for (std::size_t j = 0; j < n; ++j) {
    inertia.frames[j] = exp_rotation(dt * motion.angular_velocity[j]) * state.frames[j];
  }
  RodSolveReport report;
  RodState next = state;
  // Start from the prediction (nodes moved by v·dt, frames turned by w·dt): Newton then only corrects.
  for (std::size_t i = 1; i <= n; ++i) next.x[i] = inertia.x[i];
  next.frames = inertia.frames;
  NewtonScratch scratch;
  const std::string why = newton(model, field, next, 1.0, options, report, options.max_newton * 4, scratch, &inertia);
  if (!why.empty()) {
    report.failure = why;
    return report;
  }
  for (std::size_t i = 1; i <= n; ++i) motion.velocity[i] = (next.x[i] - state.x[i]) / dt;
  for (std::size_t j = 0; j < n; ++j) {
    const Eigen::AngleAxisd turn(next.frames[j] * state.frames[j].transpose());
    motion.angular_velocity[j] = turn.angle() / dt * turn.axis();
  }
  state = std::move(next);
  report.converged = true;
  report.load_steps = 1;
  return report;
}

RodDynamicsReport simulate_rod_dynamics(const RodModel& model, const RodField& field, RodState& state,
                                        RodMotion& motion, double duration, const RodDynamicsOptions& options,
                                        const std::function<void(double, const RodState&)>& observer) {
  RodDynamicsReport out;
  double dt = options.max_step;
  while (out.time < duration * (1.0 - 1e-12)) {
    dt = std::min({dt, options.max_step, duration - out.time});
    if (dt < options.min_step) {
      out.failure = "step fell below " + std::to_string(options.min_step) + " s at t = " + std::to_string(out.time) +
                    " s (stiff or diverging motion)";
      return out;
    }
    RodState whole = state;
    RodMotion whole_motion = motion;
    RodState half = state;
    RodMotion half_motion = motion;
    const RodSolveReport a = step_rod_dynamics(model, field, whole, whole_motion, dt);
    const bool ok = a.converged && step_rod_dynamics(model, field, half, half_motion, 0.5 * dt).converged &&
                    step_rod_dynamics(model, field, half, half_motion, 0.5 * dt).converged;
    double error = std::numeric_limits<double>::infinity();
    if (ok) {
      error = 0.0;
      for (std::size_t i = 0; i < state.x.size(); ++i) error = std::max(error, (whole.x[i] - half.x[i]).norm());
      error /= model.length;
    }
    if (!(error <= options.tolerance)) {
      ++out.rejected;
      dt *= ok ? std::max(0.2, 0.9 * std::sqrt(options.tolerance / error)) : 0.25;
      continue;
    }
    state = std::move(half);
    motion = std::move(half_motion);
    out.time += dt;
    ++out.steps;
    if (observer) observer(out.time, state);
    dt *= std::min(2.0, 0.9 * std::sqrt(options.tolerance / std::max(error, 1e-300)));
  }
  out.completed = true;
  return out;
}

RodSolveReport solve_rod_statics(const RodModel& model, const RodField& field, RodState& state,
                                 const RodSolveOptions& options, RodWorkspace* workspace,
                                 const RodConstraints* constraints) {
  RodWorkspace::Impl* ws = workspace != nullptr ? workspace->impl.get() : nullptr;
  check_rod_model(model);
  if (state.x.size() != static_cast<std::size_t>(model.edges) + 1 ||
      state.frames.size() != static_cast<std::size_t>(model.edges)) {
    throw InputError("rod: the state does not match the model's edge count");
  }
  NewtonScratch local;
  NewtonScratch& scratch = ws != nullptr ? ws->scratch : local;
  RodSolveReport report;
  // Warm start: the full load from the caller's state (the previous equilibrium of a simulation loop, or the
  // straight rod). Only when that fails does the ramp start over from the unloaded state.
  if (!options.ramp) {
    RodState trial = state;
    const std::string why =
        newton(model, field, trial, 1.0, options, report, options.max_snap_newton, scratch, nullptr, ws, constraints);
    if (!why.empty()) {
      report.failure = why;
      return report;
    }
    state = std::move(trial);
    report.load_steps = 1;
    report.converged = true;
    return report;
  }
  if (options.min_load_steps <= 1) {
    RodState trial = state;
    if (newton(model, field, trial, 1.0, options, report, options.max_newton, scratch, nullptr, ws, constraints)
            .empty()) {
      state = std::move(trial);
      report.load_steps = 1;
      report.converged = true;
      return report;
    }
  }
  double load = 0.0;
  double step = 1.0 / std::max(2, options.min_load_steps);
  const double min_step = 1.0 / options.max_load_steps;
  // The unloaded state first (it may not be at rest if the caller's state is not).
  if (std::string why =
          newton(model, field, state, 0.0, options, report, options.max_snap_newton, scratch, nullptr, ws, constraints);
      !why.empty()) {
    report.failure = "unloaded rod: " + why;
    return report;
  }
  while (load < 1.0) {
    const double next = std::min(1.0, load + step);
    RodState trial = state;
    std::string why =
        newton(model, field, trial, next, options, report, options.max_newton, scratch, nullptr, ws, constraints);
    if (!why.empty() && report.iterations >= options.max_iterations) {
      report.failure = "at load factor " + std::to_string(load) + ": " + why;
      return report;
    }
    if (!why.empty() && step <= options.snap_step) {
      // Past a limit point (a snap: the crease of a vine, the buckling of a rod) there is no equilibrium near the
      // last one, however small the load step; the energy still decreases along Newton's steps, so follow them to
      // the next stable branch.
      trial = state;
      why = newton(model, field, trial, next, options, report, options.max_snap_newton, scratch, nullptr, ws,
                   constraints);
      if (why.empty()) ++report.snaps;
    }
    if (why.empty()) {
      state = std::move(trial);
      load = next;
      ++report.load_steps;
      step = std::min(2.0 * step, 1.0 / options.min_load_steps);
      continue;
    }
    step *= 0.5;
    if (step < min_step) {
      report.failure = "load ramp exhausted at load factor " + std::to_string(load) + (why.empty() ? "" : ": " + why);
      return report;
    }
  }
  report.converged = true;
  return report;
}

}  // namespace magvine::robot
