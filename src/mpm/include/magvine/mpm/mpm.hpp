#pragma once
/// Magnetic MLS-MPM for hard-magnetic soft bodies (thesis chapter 3; PHYSICS.md §5), in 2D (plane strain or plane
/// stress, per metre of depth) and 3D.
///
/// One explicit step, after Hu et al. 2018 (MLS-MPM, quadratic B-splines, D⁻¹ = 4/δx²):
///  - P2G: per particle, P = P_el(F) + P_mag and the affine momentum  A = m C − Δt V0 D⁻¹ P Fᵀ  (eq 3.1–3.9);
///    node mass m_i = Σ w m_p, momentum Σ w (m v_p + A (x_i − x_p)), and, in a non-uniform field, the node moment
///    m_i = Σ w V0 F Br / μ0 (eq 3.15).
///  - Grid: v_i = p_i/m_i, + Δt (∇B_iᵀ m_i / m_i + g) (eq 3.16–3.19), damping v /= 1 + cΔt (the thesis's −c p,
///    taken implicitly so that it never overshoots), then the fixed nodes, the domain walls and the obstacles.
///  - G2P: v_p = Σ w v_i, C_p = D⁻¹ Σ w v_i (x_i − x_p)ᵀ, F ← (I + Δt C) F, x ← x + Δt v.
///
/// Stress: compressible Neo-Hookean with the isochoric split (eq 3.10),
///   P_el = G J^(−2/3) (F − (I1/3) F⁻ᵀ) + K J (J − 1) F⁻ᵀ,  K = 20 G by default;
/// in 2D the same law for the plane-strain F = diag(F2, 1) (I1 = tr F2ᵀF2 + 1, J = det F2), so that the rest state
/// is stress free (the public reference code applies the 3D formula to a 2×2 F, which leaves a stress G/3 at rest),
/// or for the plane-stress F = diag(F2, λ), λ such that τ33 = 0 (plane_stress_stretch).
/// Hard-magnetic stress (Zhao et al. 2019, eq 3.13): P_mag = −(1/μ0) B ⊗ B̃r, B̃r the referential remanence.
///
/// The grid is a dense box around the particles, rebuilt each step (never the whole domain), so memory follows the
/// body, not the domain. P2G, the grid update and G2P run in one OpenMP region over slabs four cells thick along the
/// longest axis: each thread owns a run of whole slabs (an equal share of the particles) for both transfers; P2G does
/// the even slabs, then the odd ones, so no two threads write one node and the sums do not depend on the thread count.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "magvine/core/eigen_types.hpp"
#include "magvine/magnetics/field_sample.hpp"

namespace magvine::mpm {

template <int D>
using VecD = Eigen::Matrix<double, D, 1>;
template <int D>
using MatD = Eigen::Matrix<double, D, D>;

/// An isotropic hyperelastic material.
struct Material {
  double shear_modulus = 0.0;  ///< G [Pa], > 0
  double bulk_modulus = 0.0;   ///< K [Pa], > 0 (the thesis uses 20 G)
  double density = 0.0;        ///< ρ [kg/m³], > 0
};

/// Longitudinal (P-wave) speed sqrt((K + 4G/3)/ρ) [m/s]: the fastest signal the explicit step must resolve.
double wave_speed(const Material& m);

/// What a 2D model is a slice of: a body long along z (plane strain, ε_zz = 0: the reference code's and the default) or
/// a thin sheet in the x–y plane (plane stress, σ_zz = 0). Per metre of depth either way.
enum class Plane { kStrain, kStress };

/// What happens at a wall or obstacle to grid velocity that points into it (eq 3.21 is `kSticky`).
enum class Boundary {
  kSticky,    ///< the whole velocity is zeroed
  kSlip,      ///< the normal part is removed, the tangential part kept
  kFriction,  ///< the normal part is removed and the tangential part reduced by μ |v_n| (Coulomb), to zero at most
};

/// A signed distance the solver does not compute itself (a mesh's: the scene layer builds it from a CollisionWorld)
/// [m], negative inside the solid, with the unit normal pointing out of the solid (into the free side). The solver
/// calls it once per grid node it needs and keeps the values (MpmWorkspace); calls may come from several threads at
/// once.
class SignedDistance {
 public:
  virtual ~SignedDistance() = default;
  virtual double at(const Vec3& x, Vec3* normal) const = 0;
};

/// A rigid, fixed obstacle given by a signed distance (negative inside) [m].
struct Obstacle {
  enum class Shape { kBox, kSphere, kHalfSpace, kCylinder, kSampled };
  Shape shape = Shape::kBox;
  Vec3 a = Vec3::Zero();  ///< box: min corner; sphere: centre; half-space: a point on the plane; cylinder: axis start
  Vec3 b = Vec3::Zero();  ///< box: max corner; half-space: outward normal (unit); cylinder: axis end
  double radius = 0.0;    ///< sphere and cylinder radius [m]
  Boundary boundary = Boundary::kSticky;
  double friction = 0.0;  ///< μ for kFriction
  std::string name;
  /// kSampled: the distance (3D only); the solver samples it at the grid nodes once and keeps the samples.
  std::shared_ptr<const SignedDistance> sampled;

  /// Signed distance [m] and outward normal at x (x in 3D; a 2D solver passes z = 0).
  double distance(const Vec3& x, Vec3* normal) const;
};

/// Immutable description of one MPM body set: particles' rest data, materials, grid, boundaries.
template <int D>
struct MpmModel {
  double cell = 0.0;                     ///< grid spacing δx [m]
  VecD<D> domain_min = VecD<D>::Zero();  ///< the domain's walls [m]
  VecD<D> domain_max = VecD<D>::Zero();
  Boundary walls = Boundary::kSticky;  ///< condition at the domain walls
  double wall_friction = 0.0;          ///< μ for kFriction walls
  VecD<D> gravity = VecD<D>::Zero();   ///< g [m/s²]
  double damping = 0.0;                ///< c [1/s] (eq 3.17)
  Plane plane = Plane::kStrain;        ///< 2D only
  std::vector<Material> materials;
  std::vector<Obstacle> obstacles;
  /// A clamp: the grid nodes inside the box [min, max] + velocity·t move at `velocity` (at rest: the body is fixed
  /// there; moving: its base is pushed or pulled, a catheter fed at a speed).
  struct Clamp {
    VecD<D> min;
    VecD<D> max;
    VecD<D> velocity;  ///< [m/s]
  };
  std::vector<Clamp> clamps;

  // Per particle (all the same length N).
  std::vector<double> volume;           ///< V0 [m³; m² per metre of depth in 2D]
  std::vector<double> mass;             ///< ρ V0 [kg]
  std::vector<VecD<D>> remanence;       ///< B̃r, referential [T]
  std::vector<std::uint16_t> material;  ///< index into materials
  std::vector<std::uint16_t> section;   ///< the section a particle was sampled in (for outputs)

  std::size_t size() const { return volume.size(); }
  /// The largest stable step for this model: courant · δx / max wave speed [s].
  double stable_step(double courant) const;
};

/// Everything that changes in time.
template <int D>
struct MpmState {
  double time = 0.0;       ///< [s]
  std::vector<VecD<D>> x;  ///< positions [m]
  std::vector<VecD<D>> v;  ///< velocities [m/s]
  std::vector<MatD<D>> c;  ///< affine velocity field C (APIC/MLS) [1/s]
  std::vector<MatD<D>> f;  ///< deformation gradient F
  /// Total-Lagrangian steps only (total_lagrangian.hpp): the reference grid's node positions [m] and velocities [m/s];
  /// empty for the updated-Lagrangian steps of this file.
  std::vector<VecD<D>> grid_x, grid_v;
};

/// A rest state: particles at `positions`, at rest, undeformed.
template <int D>
MpmState<D> rest_state(const std::vector<VecD<D>>& positions);

/// The applied field for one step. A 2D solver uses the x–y parts of B and G at z = 0.
struct AppliedField {
  enum class Kind { kNone, kUniform, kGeneral };
  Kind kind = Kind::kNone;
  Vec3 uniform = Vec3::Zero();  ///< B [T] for kUniform
  /// kGeneral: B and ∇B at a world point. Called only for grid nodes, and again only after `version` changes.
  std::function<magnetics::FieldSample(const Vec3&)> sample;
  std::uint64_t version = 0;  ///< change it whenever the general field changes (moving magnets)
};

/// A grid node's record: momentum (then velocity) in the first D entries, mass in entry D (a 2D record leaves the
/// last entry unused). 32-byte aligned: the particle kernels move it as one 4-double SIMD value.
struct alignas(32) NodeRecord {
  double value[4];
};

/// Preallocated scratch (grid box, node field cache, slab buckets). Reused across steps; grows, never shrinks.
template <int D>
struct MpmWorkspace {
  Eigen::Matrix<std::int64_t, D, 1> lo, n;  // the grid box: first node index and node counts per axis
  std::vector<NodeRecord> node;
  std::vector<VecD<D>> node_moment;  // magnetic moment [A·m²] (non-uniform fields only)
  // Field at the nodes of a box that only grows, evaluated once per field version.
  Eigen::Matrix<std::int64_t, D, 1> field_lo, field_n;
  std::vector<VecD<D>> field_b;
  std::vector<MatD<D>> field_g;
  std::uint64_t field_version = ~std::uint64_t{0};
  bool field_valid = false;
  std::vector<std::uint32_t> slab_start, slab_order, slab_count, slab_key;
  /// A sampled obstacle's distance and normal at the nodes of a box that only grows (one per obstacle; unused for the
  /// analytic shapes).
  struct ObstacleSamples {
    Eigen::Matrix<std::int64_t, D, 1> lo, n;
    std::vector<double> distance;
    std::vector<VecD<D>> normal;
    bool valid = false;
    const SignedDistance* source = nullptr;  ///< what was sampled, at which spacing: another model starts afresh
    double cell = 0.0;
  };
  std::vector<ObstacleSamples> obstacle_samples;
  /// The model's clamps moved to the current step's time (a moving clamp's box), set once per step.
  std::vector<typename MpmModel<D>::Clamp> clamps;
  /// The implicit step's vectors: per grid node (Newton's target and iterate, gradient, direction, CG's vectors, the
  /// preconditioner, which nodes are unknowns) and per particle (the trial F, a stress-like matrix per pass).
  struct ImplicitScratch {
    std::vector<VecD<D>> target, v, trial, grad, dir, res, pre, conj, hconj, diag;
    std::vector<unsigned char> unknown;
    std::vector<MatD<D>> f_trial, stress, magnetic;
    std::vector<VecD<D>> field;                                // B at each particle [T]
    std::vector<Eigen::Matrix<double, D * D, D * D>> tangent;  // ∂P/∂F at F̂, per particle
  } implicit;
};

/// What a step found. `ok` is false when the state must not be used (the cause says why).
struct StepStatus {
  bool ok = true;
  std::string cause;  ///< e.g. "particle 12 left the domain", "NaN velocity", "J = -0.2 (inverted element)"
};

/// Gives the calling thread's MPM steps a 1/ways share of the OpenMP threads (the cores this process may use, or
/// OMP_NUM_THREADS), at least one. For callers that run several bodies at once on their own threads: otherwise every
/// body's team wants every core, and the teams spin against each other.
void share_step_threads(int ways);

/// One explicit MLS-MPM step of length dt [s]. On failure the state holds the failed step and status names the cause
/// (non-finite values, an inverted or exploded element, a particle leaving the domain, or moving more than a cell).
template <int D>
StepStatus step(const MpmModel<D>& model, const AppliedField& field, MpmState<D>& state, MpmWorkspace<D>& ws,
                double dt);

/// How hard the implicit step works.
struct ImplicitSettings {
  double tolerance = 1e-6;  ///< Newton stops when its last correction moves every node by less than this [cells]
  int max_newton = 40;      ///< Newton iterations before the step fails
  int max_cg = 2000;        ///< conjugate-gradient iterations per Newton iteration (the inexact solve ends there)
};

/// What an implicit step did.
struct ImplicitStats {
  int newton = 0;          ///< Newton iterations
  long cg = 0;             ///< conjugate-gradient iterations over all of them (each one Hessian product)
  int factorizations = 0;  ///< Newton iterations solved by the sparse LDLᵀ (the others by CG)
  double correction = 0;   ///< the last Newton correction's largest node displacement [cells]
};

/// One implicit (backward Euler) MLS-MPM step of length dt [s], stable at any dt for the elastic stress (thesis 3.8:
/// "replace the semi-implicit Euler method with a fully implicit solver"; Gast et al. 2015's optimisation form):
/// the grid velocities v minimise the incremental potential
///   E(v) = Σ_i m_i (½ (1 + cΔt) |v_i|² − v_i · v*_i) + Σ_p V0_p ψ(F̂_p(v)),  F̂_p = (I + Δt Σ_i v_i ∇w_ipᵀ) F_p,
/// whose stationarity is m_i ((1 + cΔt) v_i − v*_i) = −Δt Σ_p V0 P(F̂_p) F_pᵀ ∇w_ip: the explicit step's momentum
/// balance with the stress at the end of the step. ψ holds the elastic and the hard-magnetic energy (linear in F, so
/// its stress is the explicit step's); v*_i what does not depend on v: the transferred momentum, the gradient force and
/// gravity. ∇w_ip = w_ip D⁻¹ (x_i − x_p) is MLS-MPM's gradient, so F̂ is what G2P will form. Newton's method: the first
/// iteration assembles the Hessian (per-particle tangents from elastic_stress_differential) and solves with its sparse
/// LDLᵀ; the later ones run conjugate gradients preconditioned by that factor (Jacobi where there is none: too many
/// unknowns, or an indefinite Hessian); a backtracking line search on E keeps every F̂ uninverted. Clamped nodes are
/// held; the walls and obstacles act on the solved velocities, as in the explicit step. The particles must still move
/// less than a cell per step. On a particle check's failure the state holds the failed step, as `step`; when Newton
/// fails the state is untouched.
template <int D>
StepStatus implicit_step(const MpmModel<D>& model, const AppliedField& field, MpmState<D>& state, MpmWorkspace<D>& ws,
                         double dt, const ImplicitSettings& settings = {}, ImplicitStats* stats = nullptr);

/// The length of a run of implicit steps (ImplicitStepper: scenes, settle): a step that fails (Newton unconverged, a
/// particle over a cell) is taken again from the state before it at half the length tried, down to base/2^kMaxHalvings;
/// after kRegrowAfter good steps in a row the length doubles back towards base.
class ImplicitStepLength {
 public:
  static constexpr int kMaxHalvings = 8;
  static constexpr int kRegrowAfter = 8;
  explicit ImplicitStepLength(double base) : m_base(base), m_tried(base) {}
  /// The length to try next with `remaining` time left [s].
  double next(double remaining) const {
    return std::min({m_base / std::ldexp(1.0, m_halvings), m_tried, remaining});
  }
  /// Records a try of length dt that succeeded (`ok`) or failed. Returns whether it is to be taken again (failed, with
  /// halvings left; the caller restores the state first); otherwise it stands (a failure then ends the run).
  bool record(bool ok, double dt) {
    if (!ok && m_halvings < kMaxHalvings) {
      ++m_halvings;
      ++m_retries;
      m_good = 0;
      m_tried = 0.5 * dt;
      return true;
    }
    m_tried = m_base;
    if (ok && m_halvings > 0 && ++m_good >= kRegrowAfter) {
      --m_halvings;
      m_good = 0;
    }
    return false;
  }
  /// Tries taken again so far.
  long retries() const { return m_retries; }

 private:
  double m_base;
  double m_tried;
  int m_halvings = 0;
  int m_good = 0;
  long m_retries = 0;
};

/// Kinetic energy Σ ½ m v² [J; J per metre of depth in 2D].
template <int D>
double kinetic_energy(const MpmModel<D>& model, const MpmState<D>& state);

/// Plane stress: the out-of-plane stretch λ of F = diag(F2, λ) at which the Neo-Hookean's τ33 vanishes (a thin sheet in
/// the x–y plane, free on its faces), by Newton from J = 1 to round-off. NaN when det F2 ≤ 0.
double plane_stress_stretch(const Material& m, const MatD<2>& f2);

/// First Piola–Kirchhoff stress of the elastic part (exposed for tests) [Pa]. `plane` says what a 2D F means (3D
/// ignores it): F = diag(F2, 1) (plane strain) or diag(F2, λ) with λ = plane_stress_stretch (plane stress).
template <int D>
MatD<D> elastic_stress(const Material& m, const MatD<D>& f, Plane plane = Plane::kStrain);

/// The differential dP = (∂P/∂F) : dF of elastic_stress at F [Pa] (the implicit step's Hessian): closed form in 3D and
/// plane strain, a central difference of elastic_stress in plane stress (whose λ depends on F).
template <int D>
MatD<D> elastic_stress_differential(const Material& m, const MatD<D>& f, const MatD<D>& df,
                                    Plane plane = Plane::kStrain);

/// Kirchhoff stress τ = P Fᵀ of the elastic part, formed without inverting F (what P2G uses) [Pa].
template <int D>
MatD<D> kirchhoff_stress(const Material& m, const MatD<D>& f, Plane plane = Plane::kStrain);

/// Strain energy density of the elastic part [J/m³ of the reference] (its derivative is elastic_stress: in plane
/// stress ∂ψ/∂λ = τ33/λ = 0, so λ's dependence on F2 adds nothing).
template <int D>
double strain_energy_density(const Material& m, const MatD<D>& f, Plane plane = Plane::kStrain);

extern template struct MpmModel<2>;
extern template struct MpmModel<3>;

}  // namespace magvine::mpm
