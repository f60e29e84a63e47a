#pragma once
/// Total-Lagrangian MPM for stiff bodies that bend but do not flow (catheters, beams): the same particles, materials,
/// clamps and field as the updated-Lagrangian solver of mpm.hpp, but the grid is the body's reference configuration
/// (de Vaucorbeil, Nguyen & Hutchinson 2020, "A total-Lagrangian material point method for solid mechanics problems
/// involving large deformations", CMAME 360:112783).
///
/// The grid nodes carry positions x_i and velocities v_i that persist from step to step (MpmState::grid_x, grid_v);
/// the quadratic B-spline weights w_ip and their gradients ∇_X w_ip are taken once, at the particles' reference
/// positions X_p, and never change. Then
///   F_p = Σ_i x_i ∇_X w_ipᵀ,   x_p = Σ_i w_ip x_i,   f_i = −Σ_p V0 (P_el(F_p) + P_mag) ∇_X w_ip + Σ_p w_ip f_grad,p,
/// so every particle's F is the gradient of one displacement field and the body's rest is a stationary point of one
/// energy over the node positions, Σ_p V0 (ψ(F_p) + ψ_mag(F_p)) minus the work of gravity and the gradient force.
/// The updated-Lagrangian solver lets each particle carry its own F, updated from grid velocities on a grid rebuilt
/// every step: its particles hold more stress unknowns than its grid has equations, its rests form a continuum and
/// the loading path picks one (docs/mpm.md, "The implicit step"). Here the explicit step and the implicit step (and
/// any step size) settle to the same rest.
///
/// What it gives up: no material flow past the grid (a particle keeps its reference stencil, so a body that tears
/// or mixes needs the updated-Lagrangian solver), and no obstacles yet (a model with obstacles is refused; the domain
/// walls end a run whose particle leaves the domain, as in mpm.hpp).

#include <cstdint>
#include <memory>
#include <vector>

#include "magvine/mpm/mpm.hpp"

namespace magvine::mpm {

/// The reference grid: immutable after make_tl_grid.
template <int D>
struct TlGrid {
  static constexpr int kStencil = D == 2 ? 9 : 27;
  double cell = 0.0;                                 ///< δx [m]
  Eigen::Matrix<std::int64_t, D, 1> lo, n;           ///< the box of nodes (first index, counts per axis)
  std::vector<VecD<D>> rest;                         ///< X_i, each node's reference position [m]
  std::vector<double> mass;                          ///< lumped Σ_p w_ip m_p [kg; kg per metre in 2D]
  std::vector<int> clamp;                            ///< the clamp holding node i (index into model.clamps) or −1
  std::vector<std::uint32_t> node;                   ///< per particle, its kStencil nodes (p·kStencil + s)
  std::vector<double> weight;                        ///< w_ip, the same layout
  std::vector<VecD<D>> gradient;                     ///< ∇_X w_ip [1/m], the same layout
  std::vector<std::uint32_t> slab_start;             ///< particles by slab (4 cells along x): slab s's range in
  std::vector<std::uint32_t> slab_order;             ///< slab_order, which lists particle indices
  std::size_t particles = 0;
  std::uint64_t id = 0;  ///< unique per make_tl_grid call: a workspace's cached pattern belongs to one grid
};

/// Builds the reference grid from the particles' current positions (taken as the reference, undeformed) and sets the
/// state's node positions to the reference and node velocities from the particles' (mass-weighted). Throws
/// InputError for a model the total-Lagrangian step does not take (obstacles).
template <int D>
TlGrid<D> make_tl_grid(const MpmModel<D>& model, MpmState<D>& state);

/// What the steps keep between calls: a general field's node cache, and the implicit step's Hessian pattern and the
/// factor it reuses while that preconditions well. Opaque.
template <int D>
struct TlWorkspace {
  TlWorkspace();
  ~TlWorkspace();
  TlWorkspace(TlWorkspace&&) noexcept;
  TlWorkspace& operator=(TlWorkspace&&) noexcept;
  struct Impl;
  std::unique_ptr<Impl> impl;
};

/// One explicit (symplectic Euler) total-Lagrangian step of length dt [s]: node forces from the particles' stresses,
/// v_i ← (v_i + Δt (f_i/m_i + g)) / (1 + cΔt) (the damping of eq 3.17), the clamps' velocities, x_i ← x_i + Δt v_i,
/// then each particle's x, v and F from the nodes (C, the updated-Lagrangian step's affine field, is not used). Fails
/// on a non-finite, inverted or exploded particle, one that leaves the domain, or moves more than a cell in the step.
template <int D>
StepStatus tl_step(const MpmModel<D>& model, const TlGrid<D>& grid, const AppliedField& field, MpmState<D>& state,
                   TlWorkspace<D>& ws, double dt);

/// One implicit (backward Euler) total-Lagrangian step of length dt [s]: the free node velocities v minimise
///   E(v) = Σ_i m_i (½ (1 + cΔt) |v_i|² − v_i · v*_i) + Σ_p V0 [ψ(F̂_p) + ψ_mag(F̂_p)],  F̂_p = Σ_i (x_i + Δt v_i) ∇_X w_ipᵀ,
/// v*_i = v_i + Δt (f_grad,i / m_i + g) (Gast et al. 2015's optimisation form; the field is taken at the step's
/// start). Newton's method with a backtracking line search that keeps every F̂ uninverted; the Hessian's pattern is
/// fixed (the reference grid does not move), analysed once and factored (sparse LDLᵀ) when conjugate gradients
/// preconditioned by the last factor stop converging quickly; negative tangent eigenvalues are projected out where a
/// factor proves indefinite. When Newton fails the state is untouched.
template <int D>
StepStatus tl_implicit_step(const MpmModel<D>& model, const TlGrid<D>& grid, const AppliedField& field,
                            MpmState<D>& state, TlWorkspace<D>& ws, double dt, const ImplicitSettings& settings = {},
                            ImplicitStats* stats = nullptr);

/// A run's implicit steps with their length under ImplicitStepLength's control, in the total-Lagrangian frame when
/// given its reference grid (else the updated frame): `step` takes one step that stands, trying it again from the
/// state before it at half the length while it fails and halvings are left.
template <int D>
class ImplicitStepper {
 public:
  /// `grid` (borrowed; null: the updated frame) and the length the steps start from and grow back to [s].
  ImplicitStepper(const TlGrid<D>* grid, double base) : m_grid(grid), m_length(base) {}
  /// One step that stands, with `remaining` time left [s] under `field` (the state's time does not change between
  /// tries). Its status is the last try's: a failure means the halvings are spent (its cause says so), and the state
  /// holds that try, as the step functions leave it. `stats` (optional) gains every try's counts.
  StepStatus step(const MpmModel<D>& model, const AppliedField& field, MpmState<D>& state, MpmWorkspace<D>& ws,
                  TlWorkspace<D>& tl_ws, double remaining, const ImplicitSettings& settings,
                  ImplicitStats* stats = nullptr);
  /// Tries taken again so far.
  long retries() const { return m_length.retries(); }

 private:
  const TlGrid<D>* m_grid;
  ImplicitStepLength m_length;
  MpmState<D> m_saved;  ///< the state before the try (kept here so that its buffers are reused)
};

}  // namespace magvine::mpm
