#pragma once
/// The simulator's discretised magnetic rod (a Cosserat rod on a node chain), static equilibrium.
///
/// Nodes x_0..x_N (x_0 clamped) and one material frame R_j per edge j (x_j → x_{j+1}), columns (d1, d2, d3) =
/// (tangent, base normal, binormal) at rest. With h = L/N, the stored energy is
///   stretch and shear per edge:  ½ h vᵀ diag(EA, GA, GA) v,    v = R_jᵀ(x_{j+1} − x_j)/h − e1,
///   bending and twist per node:  ½ ℓ ωᵀ diag(GJ, EI_2, EI_3) ω,  ω = 2 vee(Q − Qᵀ)/((1 + tr Q) ℓ),  Q = R_{j−1}ᵀ R_j,
/// ℓ = h between edges and ℓ = h/2 between the clamp frame and the first edge (the clamp sits at x_0). ωℓ/2 is the
/// Gibbs vector tan(ψ/2)·axis of the joint rotation ψ: ω = ψ/ℓ to second order, and the energy grows without bound
/// as a joint folds back (ψ → π). A vine replaces the bending part (about d2, d3) by the inflated-beam law
/// (InflatedBending). The loads are potentials: a hard-magnetic edge of moment m_j = R_j m̂_j (m̂_j = M_j A h in the
/// body frame) has U = −m_j·B(midpoint), so its torque is m × B and its force Gᵀm (PHYSICS.md §2); a soft-magnetic
/// fill (InducedFill) has U = −V∫M·dB; gravity acts on lumped node masses; a tip force on x_N and a tip
/// moment on the last edge. Each term's energy, gradient and Hessian live together (src/robot/src/terms/); the body
/// frame is magnetics' convention (magnetisation.hpp: x = d1 along the body).
/// Equilibrium minimises the total potential energy.
///
/// Solver: Newton steps on the increments (δx_i, δφ_j) (frames updated by R ← exp([δφ]) R). The Hessian is block
/// tridiagonal in 6 × 6 blocks and factored in O(N); its second derivatives are analytic (the field's curvature
/// from forward differences of the field gradient, for non-uniform fields), checked in the tests against central
/// differences of the gradient (rod_hessian). Steps turn no frame by more than 0.5 rad, then Armijo backtracking on
/// the energy, each trial also offered with its nodes rebuilt along the new frames; the loads are ramped (full load
/// first, the step halved when Newton fails); NaN and an exhausted ramp stop with a named cause.

#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "magvine/core/eigen_types.hpp"
#include "magvine/magnetics/field_sample.hpp"
#include "magvine/magnetics/field_function.hpp"
#include "magvine/magnetics/magnetisation.hpp"

namespace magvine::anatomy {
class CollisionWorld;
class NearCache;
}

namespace magvine::robot {

/// Field and gradient at a world point [T, T/m] (magnetics::field_function makes one from magnets and their poses).
using RodField = magnetics::FieldFunction;

/// Bending of a pressurised thin-walled tube (PHYSICS.md §3, inflated_beam.hpp), per joint of bend angle ψ over ℓ
/// with curvature κ = |ω_bend| = 2 tan(ψ/2)/ℓ:
///   W = ℓ (M_c²/EI) Φ(κ EI/M_c) + ½ ℓ EI_flat κ²,   M_c = πR³P,
/// the first term the wrinkling law of eq 4.6/4.8 (linear to M_w = M_c/2, softening to the collapse M_c), the second
/// the collapsed (flat) film, which is all that is left at P = 0. The joint's moment is dW/dψ = M(κ)(1 + tan²(ψ/2)):
/// once the section has collapsed (M(κ) → M_c) this is the crease hinge of eq 4.13, M_c(1 + tan²(θ/2)), with no
/// further term; for a smooth bend ψ = κℓ → 0 under refinement and it is the continuum law.
struct InflatedBending {
  double radius = 0.0;                   ///< R [m]
  double pressure = 0.0;                 ///< P [Pa], ≥ 0
  double flat_bending_stiffness = 0.0;   ///< EI_flat of the collapsed film [N·m²] (> 0 when P = 0)
};

/// A soft-magnetic fill (magnetic fluid) that magnetises along the local field: its law (magnetics::
/// InducedMagnetisation, a co-energy density in the body frame) over the fill's cross-section; edge j stores
/// U = V e(R_jᵀB) with V = volume_per_length·h.
struct InducedFill {
  double volume_per_length = 0.0;        ///< fill cross-section [m²]
  magnetics::InducedMagnetisation law;   ///< susceptibilities (demagnetisation included) and saturation
};

/// Parameters of a rod, SI units, immutable.
struct RodModel {
  double length = 0.0;               ///< L [m]
  int edges = 0;                     ///< N ≥ 1
  double bending_stiffness_2 = 0.0;  ///< EI about d2 [N·m²]
  double bending_stiffness_3 = 0.0;  ///< EI about d3 [N·m²]
  double torsional_stiffness = 0.0;  ///< GJ [N·m²]
  double axial_stiffness = 0.0;      ///< EA [N]
  double shear_stiffness = 0.0;      ///< κGA [N]
  double mass_per_length = 0.0;      ///< ρA [kg/m]
  double rotational_inertia_per_length = 0.0;  ///< ρI about a transverse axis [kg·m] (dynamics only)
  /// Magnetic moment per unit length of each edge in its body frame [A·m] (= M·A); empty: not magnetic.
  std::vector<Vec3> moment_per_length;
  Vec3 base_position = Vec3::Zero();
  Mat3 base_frame = Mat3::Identity();  ///< columns: tangent, normal, binormal at the clamp
  Vec3 gravity = Vec3::Zero();         ///< [m/s²]
  Vec3 tip_force = Vec3::Zero();       ///< [N]
  /// [N·m], world frame, on the last edge: U = −M·φ, φ the last edge's rotation vector from the clamp, so valid while
  /// the tip turns less than half a turn (φ jumps at π).
  Vec3 tip_moment = Vec3::Zero();
  /// A vine: the inflated-beam law replaces the linear bending about d2 and d3 (EI_2 = EI_3 = the wall's EI).
  std::optional<InflatedBending> inflated;
  std::optional<InducedFill> induced;  ///< a soft-magnetic fill
  /// Rest strain of each joint (joint j between edge j − 1 and edge j, joint 0 at the clamp), the curvature–twist ω
  /// (= 2 tan(ψ/2)·axis/ℓ, body frame of the joint's first edge, ℓ = h/2 at the clamp, h elsewhere) at which it stores
  /// no energy: a pre-curved rod (a catheter with a shaped tip). The laws above act on ω − ω_rest. Empty: straight at rest; otherwise one entry per edge.
  std::vector<Vec3> rest_strain;
  /// The last edge's length [m] when it differs from the others (a growing tip edge, growth.hpp); 0: every edge
  /// has h = length/edges. Otherwise the first N − 1 edges have h = (length − tip_edge_length)/(N − 1), and the
  /// last edge's stretch, mass, magnetisation and joint follow its own length.
  double tip_edge_length = 0.0;
};

/// h of edges 0 … N − 2 (and of the last one unless RodModel::tip_edge_length says otherwise) [m].
inline double uniform_edge_length(const RodModel& m) {
  return m.tip_edge_length > 0.0 && m.edges > 1 ? (m.length - m.tip_edge_length) / (m.edges - 1)
                                                : m.length / m.edges;
}
/// The length of edge j [m].
inline double edge_length(const RodModel& m, int j) {
  return j == m.edges - 1 && m.tip_edge_length > 0.0 ? m.tip_edge_length : uniform_edge_length(m);
}

/// Stretch and shear stiffness of a rod relative to the physical EA and κGA: the rod is near-inextensible and
/// near-unshearable, as the elastica and the thesis's models assume. Measured on the 60 × 3 × 3 mm silicone beam
/// (test_rod): with the physical values (factor 1) its tip differs from the elastica by up to 1.7 % of L under the
/// thesis EPM at 150 mm; with 1000, by at most 0.4 %, the discretisation error.
inline constexpr double kNearInextensible = 1e3;

/// A rod of rectangular (width along d3 × thickness along d2) cross-section, E = 3G (incompressible), with one
/// magnetisation (remanence [T], direction in the body frame) along its whole length.
RodModel rectangular_rod(double length, double width, double thickness, double shear_modulus, double density,
                         double remanence, const Vec3& direction, int edges,
                         double stretch_shear_factor = kNearInextensible);

/// A solid rod of circular cross-section (diameter), E = 3G, not magnetic (set moment_per_length).
RodModel circular_rod(double length, double diameter, double shear_modulus, double density, int edges,
                      double stretch_shear_factor = kNearInextensible);

/// A hollow circular tube (a catheter: outer and inner diameter), E = 3G, not magnetic. Thin-walled tubes shear with
/// Timoshenko's factor 2(1+ν)/(4+3ν) = 0.55 at ν = ½.
RodModel circular_tube_rod(double length, double outer_diameter, double inner_diameter, double shear_modulus,
                           double density, int edges, double stretch_shear_factor = kNearInextensible);

/// The configuration: N + 1 node positions and N edge frames.
struct RodState {
  std::vector<Vec3> x;
  std::vector<Mat3> frames;

  const Vec3& tip() const { return x.back(); }
  Vec3 tip_tangent() const { return frames.back().col(0); }
};

/// Checks a rod model (the solvers call it): stiffnesses, length and mass finite and positive, one magnetisation
/// and rest strain per edge, an orthonormal base frame, a vine's and a fill's laws well formed. InputError naming the
/// parameter otherwise.
void check_rod_model(const RodModel& model);

/// The straight, unloaded rod along the base tangent.
RodState straight_rod(const RodModel& model);

struct RodSolveOptions {
  /// On the gradient, relative to EI/L² (forces) and EI/L (torques); never below the round-off floor of the stiff
  /// stretch terms (~1e3 ε EA L²/EI, 1.1e-6 for the 60 × 3 × 3 mm beam), and a Newton step under 1e-10 (rad, L)
  /// also counts as converged.
  double tolerance = 1e-9;
  int max_newton = 15;        ///< per load step (then the load step halves: cheaper than damped crawling)
  int min_load_steps = 1;     ///< the ramp starts with steps of 1/min_load_steps (1: the full load at once)
  int max_load_steps = 1024;  ///< gives up when the ramp would need more
  /// A load step this small that still fails is taken as a limit point (a snap): Newton then runs up to
  /// max_snap_newton iterations at that load to reach the next stable branch.
  double snap_step = 1.0 / 64.0;
  int max_snap_newton = 1000;
  int max_iterations = 3000;  ///< Newton iterations over the whole ramp; then it stops with a cause
  /// false: no load ramp; Newton runs from the given state at the full load for up to max_snap_newton iterations
  /// (a simulation step whose last equilibrium is already close: ramping from the unloaded state would throw that
  /// away).
  bool ramp = true;
  /// Chord steps: with a RodWorkspace, Newton reuses its last Hessian while each step still cuts the gradient by a
  /// fifth. false: a new Hessian every iteration (the wall barrier's growth steps: chords there converged linearly,
  /// ~0.7 a step, and doubled the iterations; docs/benchmarks.md, vine growth).
  bool reuse_hessian = true;
};

struct RodSolveReport {
  bool converged = false;
  int iterations = 0;  ///< Newton iterations summed over the ramp
  int load_steps = 0;
  int snaps = 0;     ///< limit points passed (see RodSolveOptions::snap_step)
  int hessians = 0;  ///< Hessians computed (fewer than iterations with a RodWorkspace)
  double gradient_norm = 0.0;  ///< scaled, at the end
  std::string failure;         ///< empty when converged; otherwise the cause (NaN, no descent, ramp exhausted)
};

/// Scratch kept between solves of one rod (a simulation loop): Newton's buffers (a solve with a workspace allocates
/// nothing once they are sized; without one, each solve allocates them once) and the last Hessian, reused for chord
/// steps from a nearby state and recomputed whenever a chord step fails to cut the gradient by a fifth. One per
/// solver thread.
/// Since the Hessian became analytic it no longer pays (bench_rod, EPM moved 1 mm between solves: 0.46 vs 0.39 ms
/// with the dipole field, 0.92 vs 0.73 ms with the exact cylinder field); kept for fields far costlier than these.
class RodWorkspace {
 public:
  RodWorkspace();
  ~RodWorkspace();
  RodWorkspace(RodWorkspace&&) noexcept;
  RodWorkspace& operator=(RodWorkspace&&) noexcept;
  /// Drops the kept Hessian: the next solve starts from a fresh one, so that its result depends on its inputs only
  /// (a step from a checkpoint repeats bit for bit with any workspace).
  void forget_hessian();
  struct Impl;
  std::unique_ptr<Impl> impl;
};

/// A node held against sliding along a wall (static friction, the everted vine's no-shear condition): energy
/// ½ k dᵀ(I − nnᵀ)d, d = x − a its offset from the anchor a (terms/anchors.hpp: its gradient is the applied force
/// also for a normal shorter than 1). The shear force on the wall is k (I − nnᵀ)(x − a).
struct NodeAnchor {
  int node = 0;
  Vec3 anchor = Vec3::Zero();
  Vec3 normal = Vec3::UnitZ();  ///< the wall normal at the anchor
  double stiffness = 0.0;       ///< [N/m]
};

/// The fraction of a node's contact radius its film keeps rigid as it flattens on the wall (WallBarrier::core): at
/// a half, the nodes' spheres still cover the edges between them for h ≤ r_i (the default h = R), so no wall passes
/// between two nodes.
inline constexpr double kFilmCore = 0.5;

/// The film law of one node's section flattened on the wall by a depth δ (flattening_law) [J, N, N/m].
struct FlatteningLaw {
  double energy = 0.0;     ///< Ψ(δ)
  double force = 0.0;      ///< F = Ψ'(δ), the force the flattened patch carries
  double stiffness = 0.0;  ///< F'(δ); +∞ at δ = 0 for the cylinder
};

/// How a pressurised film's section gives way on the wall (WallBarrier::flattening). A thin film without bending
/// stiffness lying on a wall carries its inflation pressure P on the flat patch and nothing else, so a section
/// pressed into the wall by δ carries F = P × the patch's area. Away from the patch the section keeps its round
/// shape; to leading order in δ (the patch a chord of the round section at depth δ):
///   a side of the body (a cylinder of radius R over the length ℓ a node stands for): F = P ℓ √(8Rδ),
///     Ψ = (2/3) P ℓ √(8R) δ^{3/2};
///   the tip's cap (a hemisphere of radius R, head-on or obliquely): F = 2πPRδ (the patch a disc of radius
///     √(2Rδ)), Ψ = πPRδ².
/// Ψ is the pressure's work on the volume the flattening displaces (P·ΔV to leading order). The chord form lies
/// within 3 % of the membrane's exact section (a circular arc of the same perimeter) up to δ = 0.3R and 16 %
/// above it at δ = R.
struct FlatteningSection {
  double pressure = 0.0;  ///< P [Pa]
  double length = 0.0;    ///< ℓ [m]; ignored for the cap
  bool cap = false;       ///< the tip's hemisphere instead of a cylinder's side
  bool operator==(const FlatteningSection&) const = default;
};

/// Ψ, F and F' of `section` at radius R [m] flattened by δ ≥ 0 [m].
FlatteningLaw flattening_law(const FlatteningSection& section, double radius, double depth);

/// One node's last flattened sphere (WallBarrier::sections): what it was solved for, and the root. The solver asks
/// again at the same state (its gradient, then its Hessian; a line search's winner, then the next gradient), and
/// the root is a function of these and the triangles near the node. The same triangles may come back from the
/// NearCache in another order, so a recomputed root can differ from the kept one in its last digits (runs differ
/// at about 1e-11 with and without the memo); a run is still the same from one execution to the next.
struct SectionMemo {
  Vec3 x = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());  ///< the node [m] (NaN: none yet)
  std::uint64_t world = 0;  ///< the wall's geometry (CollisionWorld::geometry_id: a breathing airway's refits)
  double radius = 0.0;      ///< r_i [m]
  FlatteningSection section;
  double core = 0.0;
  double stiffness = 0.0;   ///< κ [N/m]
  double activation = 0.0;  ///< d̂ [m]
  double s = 0.0;           ///< the root [m]
  double energy = 0.0;      ///< Ψ(r_i − s) [J]
  double film_stiffness = 0.0;  ///< F'(r_i − s), or +∞ at the core [N/m]
};

/// The wall as a smooth barrier on the unsigned distance between each node's sphere and the wall's triangles
/// (incremental potential contact, Li et al. 2020, eq. 6; terms/wall_barrier.hpp): for every triangle t within
/// r_i + d̂ of node i, the gap g = |x_i − q_t| − r_i (q_t the closest point on t) stores
///   κ b(g),  b(g) = −(g − d̂)² ln(g/d̂) for 0 < g < d̂, 0 beyond,
/// infinite at g ≤ 0, so no configuration with a finite energy overlaps the wall. The wall's force on the node is
/// −κ b'(g) along (x − q)/|x − q|. A line-search trial whose node centre moves by r_i or more from the iterate is
/// also refused when the straight path crosses a triangle (a shorter move stays inside the wall-free ball of the
/// feasible iterate). The nodes' spheres cover the edges between them while r_i > h/2.
///
/// With `flattening` (a pressurised film, FlatteningSection) the sphere's radius gives way: node i's radius is
/// s ∈ [c·r_i, r_i] (c = `core`), the film storing the pressure's work Ψ(r_i − s) as it flattens
/// (flattening_law), and s is the one that minimises κ Σ_t b(|x_i − q_t| − s) + Ψ(r_i − s) for the node at x_i
/// (condensed out: the barrier's force on the node is then the film's, F = Ψ'). Below c·r_i the section is rigid.
struct WallBarrier {
  const anatomy::CollisionWorld* world = nullptr;
  std::vector<double> radius;  ///< per node [m] (index = node); ≤ 0: the node does not touch the wall
  double activation = 0.0;     ///< d̂ [m]
  double stiffness = 0.0;      ///< κ [N/m]
  /// Optional, per node: each node's neighbourhood of the wall kept across the solve's queries (NearCache; exact,
  /// so the solve is the same with or without it). Sized by the barrier to the nodes it queries.
  std::vector<anatomy::NearCache>* near = nullptr;
  /// Per node (index = node), or empty: every node's sphere is rigid.
  std::vector<FlatteningSection> flattening;
  /// The fraction of r_i a flattening section keeps rigid (kFilmCore).
  double core = kFilmCore;
  /// Optional, per node: the last flattened sphere each node solved (SectionMemo; the same solve with or without
  /// it, to round-off).
  std::vector<SectionMemo>* sections = nullptr;
};

/// Smoothed Coulomb friction of one node against the wall, lagged (Li et al. 2020, §5): with the normal force λ and
/// the normal n held from the previous solve, u = (I − nnᵀ)(x − x_ref) the tangential slip from the reference,
///   D = μ λ f0(|u|),  f0(y) = y for y ≥ ε,  f0(y) = −y³/(3ε²) + y²/ε + ε/3 below,
/// whose force −μλ f1(|u|) û saturates at the Coulomb limit μλ past the slip ε and is a stiff spring 2μλ/ε below it
/// (static friction). With a `free` direction f (unit, ⟂ n) the slip along f is free too: u = (I − nnᵀ − ffᵀ)(x −
/// x_ref) (an everting tip advances along its tangent by laying new material down; sideways its material would
/// slide). terms/friction.hpp.
struct NodeFriction {
  int node = 0;
  Vec3 reference = Vec3::Zero();  ///< x_ref [m]
  Vec3 normal = Vec3::UnitZ();    ///< n, unit
  double normal_force = 0.0;      ///< λ [N]
  double coefficient = 0.0;       ///< μ
  double slip = 0.0;              ///< ε [m], > 0
  Vec3 free = Vec3::Zero();       ///< f: unit and ⟂ n, or zero (none)
};

/// The slip u = (I − nnᵀ − ffᵀ)(x − x_ref) of a node at x (NodeFriction) [m].
Vec3 friction_slip(const NodeFriction& friction, const Vec3& x);

/// The growth law on the tip edge (growth.hpp): the last edge's axial stretch law is replaced by the incremental
/// potential of L̇ = K·(P − Y − F_obstacle/(πR²)) over one step dt: for an extension e of the tip edge past its
/// made length, W(e) = −F e + ½ k e² (e ≥ 0, F = πR²(P − Y) the growth force, k = πR²/(K dt)), so that in free space
/// e = F/k = K(P − Y)dt and against an obstacle growth stops where the obstacle carries F. The tether takes what would
/// grow it past `limit` (F is capped at k·limit, and 100k holds the limit against other pulls); compression (e < 0)
/// meets the edge's own axial stiffness EA/ℓ. With F ≤ 0 the edge does not grow.
struct TipGrowth {
  double force = 0.0;      ///< F [N]
  double stiffness = 0.0;  ///< k [N/m], > 0
  double limit = std::numeric_limits<double>::infinity();  ///< the most the tip edge may grow in this step [m]
};

/// A contact law along one axis: the potential Ψ(d) [J] of a depth d [m], its force F = Ψ'(d) [N] and stiffness
/// F'(d) [N/m] (TipContact).
struct ContactLaw {
  double potential = 0.0;
  double force = 0.0;
  double stiffness = 0.0;
};

/// Something ahead of the tip that resists it by how deep the tip has pushed into it (a needle's tissue: the
/// needle's tip rides at a fixed protrusion ahead of the rod's, needle.hpp): the depth d(x_N) = depth + (x_N −
/// origin)·axis, the potential Ψ(d) and the force −F(d)·axis on x_N (terms/tip_contact.hpp). As the tip backs off,
/// the reaction falls with it; a dead load of F(depth) would not, and above what the body can hold it has no
/// equilibrium near (the body runs). The law is the caller's (convex: F' ≥ 0).
struct TipContact {
  Vec3 origin = Vec3::Zero();  ///< where the tip was when `depth` was measured [m]
  Vec3 axis = Vec3::UnitX();   ///< unit: the direction the tip pushes into it
  double depth = 0.0;          ///< d at origin [m] (≤ 0: not touching yet)
  std::function<ContactLaw(double)> law;
};

/// The depth of a tip at x in a TipContact [m].
double tip_contact_depth(const TipContact& contact, const Vec3& x);

/// The TipContact's force on a tip at x, −F(d(x))·axis [N].
Vec3 tip_contact_force(const TipContact& contact, const Vec3& x);

/// Terms a simulation adds to the rod's energy for one solve; not scaled by the load ramp. Node 0 (the clamp)
/// takes none.
struct RodConstraints {
  std::vector<NodeAnchor> anchors;
  std::optional<WallBarrier> wall;
  std::vector<NodeFriction> friction;
  std::optional<TipGrowth> growth;
  std::optional<TipContact> tip_contact;
};

/// The wall's push on one node (wall_barrier_forces).
struct NodeWallForce {
  Vec3 force = Vec3::Zero();  ///< Σ_t −κ b'(g_t) n_t, the net force on the node [N]
  double magnitude = 0.0;     ///< Σ_t |f_t|: what the walls carry together (two jaws of a slot add up) [N]
  Vec3 axis = Vec3::Zero();   ///< the principal direction of Σ_t |f_t| n_t n_tᵀ (unit; zero without contact)
  double radius = 0.0;        ///< the sphere's radius s: r_i, or less where a film flattened [m]
};

/// The sphere of node i that no finite barrier energy lets the wall into [m]: a film's core c·r_i where the node's
/// section flattens (WallBarrier::flattening with a pressure above 0), else its whole radius r_i.
inline double rigid_radius(const WallBarrier& wall, std::size_t i) {
  const bool film = i < wall.flattening.size() && wall.flattening[i].pressure > 0.0;
  return film ? wall.core * wall.radius[i] : wall.radius[i];
}

/// The wall's push on each node of `state` under `wall` (WallBarrier). A node that overlaps the wall gets an
/// infinite magnitude.
std::vector<NodeWallForce> wall_barrier_forces(const RodState& state, const WallBarrier& wall);

/// The force the clamp exerts on the rod at equilibrium [N]: what holds x_0, the first edge's internal force and
/// the half of its magnetic force that acts on x_0 (without constraints on x_0), from the stretch law and the field
/// alone, so that Σ (wall + magnetic + gravity + clamp) = 0 is a check of the solve, not an identity.
Vec3 clamp_force(const RodModel& model, const RodField& field, const RodState& state);

/// The model's own loads on the whole body [N]: the magnetic force on every edge, the weight of the lumped masses
/// and the tip force.
Vec3 body_load(const RodModel& model, const RodField& field, const RodState& state);

/// The friction force on the node at x (NodeFriction: −μλ f1(|u|) û) [N].
Vec3 friction_force(const NodeFriction& friction, const Vec3& x);

/// Moves `state` to static equilibrium under the model's loads and `field` (empty: none), starting from `state`
/// (the full load first; the ramp from the unloaded state when that fails). With a workspace, Newton reuses the
/// previous Hessian while it keeps reducing the gradient. Throws InputError for an invalid model.
RodSolveReport solve_rod_statics(const RodModel& model, const RodField& field, RodState& state,
                                 const RodSolveOptions& options = {}, RodWorkspace* workspace = nullptr,
                                 const RodConstraints* constraints = nullptr);

/// Bending moment |M| = dW/dψ at each joint [N·m]: joint 0 between the clamp and edge 0 (at x_0), joint j between
/// edges j − 1 and j (at x_j), from the stored energy's derivative (the inflated-beam law for a vine).
std::vector<double> joint_bending_moments(const RodModel& model, const RodState& state);

/// Rotation angle ψ ∈ [0, π] of each joint (bend and twist together) [rad], joints numbered as above.
std::vector<double> joint_angles(const RodModel& model, const RodState& state);

/// Node velocities and edge angular velocities (world frame) for the dynamics.
struct RodMotion {
  std::vector<Vec3> velocity;          ///< N + 1 [m/s] (node 0: clamped, zero)
  std::vector<Vec3> angular_velocity;  ///< N [rad/s]
};

/// At rest.
RodMotion rod_at_rest(const RodModel& model);

/// One backward-Euler step of length dt [s] (implicit, unconditionally stable; it damps modes with ω·dt ≳ 1), solved
/// as the minimisation of the incremental potential (lumped node masses ρA·h, rotational inertia ρI·h per edge) by
/// the same Newton solver as the statics. Updates state and motion; on failure both are left unchanged and the
/// report names the cause.
RodSolveReport step_rod_dynamics(const RodModel& model, const RodField& field, RodState& state, RodMotion& motion,
                                 double dt, const RodSolveOptions& options = {});

struct RodDynamicsOptions {
  double max_step = 1e-3;    ///< [s]
  double min_step = 1e-9;    ///< below this the run stops with a cause
  double tolerance = 1e-4;   ///< local error of a step (node positions, step doubling) in units of L
};

struct RodDynamicsReport {
  bool completed = false;
  int steps = 0;        ///< accepted steps
  int rejected = 0;     ///< steps halved for accuracy or failed Newton
  double time = 0.0;    ///< reached [s]
  std::string failure;  ///< empty when completed
};

/// Advances by `duration` with steps chosen for accuracy: each step of dt is compared with two of dt/2, accepted
/// (the two halves kept) when the largest node difference is below tolerance·L, and the next dt scaled from the
/// error (backward Euler's local error is O(dt²)). Calls `observer(time, state)` after every accepted step when given.
RodDynamicsReport simulate_rod_dynamics(const RodModel& model, const RodField& field, RodState& state,
                                        RodMotion& motion, double duration, const RodDynamicsOptions& options = {},
                                        const std::function<void(double, const RodState&)>& observer = {});

/// Total potential energy [J] and its gradient with respect to (δx_1, δφ_0, δx_2, δφ_1, …) (6 per edge, node j+1's
/// position then edge j's rotation increment, world frame) at load factor `load` — exposed for the derivative
/// tests.
double rod_energy(const RodModel& model, const RodField& field, const RodState& state, double load = 1.0,
                  const RodConstraints* constraints = nullptr);
VecX rod_gradient(const RodModel& model, const RodField& field, const RodState& state, double load = 1.0,
                  const RodConstraints* constraints = nullptr);

/// How the Newton Hessian is formed: `analytic` (what the solver uses) or `finite_differences` (central differences
/// of the analytic gradient, 36 gradient evaluations for any N; the reference the tests check `analytic` against).
enum class HessianMethod { analytic, finite_differences };
/// The Hessian of rod_energy in the unknowns of rod_gradient, symmetric, dense (6N × 6N; for tests and tools).
MatX rod_hessian(const RodModel& model, const RodField& field, const RodState& state, double load = 1.0,
                 HessianMethod method = HessianMethod::analytic, const RodConstraints* constraints = nullptr);

/// Design sensitivities (implicit differentiation of an equilibrium, issue 29). At an equilibrium x*(p) of parameters
/// p, g(x*(p), p) = 0, so H dx*/dp = −∂g/∂p (H = rod_hessian) and an objective J(x*) has dJ/dp = −λᵀ ∂g/∂p with the
/// adjoint H λ = ∂J/∂x: one solve with the equilibrium's Hessian per objective, whatever the number of parameters.
///
/// ∂g/∂m̂: the derivative of rod_gradient with respect to every edge's moment per length (RodModel::
/// moment_per_length, body frame), 6N × 3N (columns 3j..3j+2 for edge j), at load 1. Exact: the magnetic wrench is
/// linear in the moment.
MatX rod_moment_sensitivity(const RodModel& model, const RodField& field, const RodState& state);

/// ∂g/∂B: the derivative of rod_gradient with respect to a uniform field added to `field`, 6N × 3, for a rod with hard
/// moments (InputError for an induced fill, whose moment depends on B). Exact: −m × B is linear in B.
MatX rod_uniform_field_sensitivity(const RodModel& model, const RodState& state);

/// ∂g/∂p: the derivative of rod_gradient with respect to a translation p of every source of `field` (the field becomes
/// B(x − p): a magnet moved by p), 6N × 3, from the magnetic term's own Hessian blocks (exact where the field's
/// curvature is closed-form, as for dipoles; from differences of its gradient otherwise, as the Newton Hessian).
MatX rod_field_translation_sensitivity(const RodModel& model, const RodField& field, const RodState& state);

/// H⁻¹ rhs for the analytic Hessian at `state` (rod_hessian), by the solver's block LDLᵀ in O(N) per column (one
/// factorisation for all of rhs's columns: the adjoint of one objective, or the forward sensitivities dx*/dp =
/// −H⁻¹ ∂g/∂p of every parameter); empty when H is not positive definite there (not a stable equilibrium).
std::optional<MatX> rod_hessian_solve(const RodModel& model, const RodField& field, const RodState& state,
                                      const MatX& rhs, const RodConstraints* constraints = nullptr);

/// A covector on the node positions (∂J/∂x_i for i = 1..N; entry 0, the clamped node, is ignored) as a vector in the
/// unknowns of rod_gradient (zero on the rotations).
VecX rod_position_covector(const std::vector<Vec3>& per_node);

}  // namespace magvine::robot
