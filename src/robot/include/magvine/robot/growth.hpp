#pragma once
/// An everting vine growing through anatomy (PHYSICS.md §3): quasi-static steps of the discretised vine of vine.hpp
/// against the airway wall of an anatomy::CollisionWorld (docs/growth-and-contact.md).
///
/// Model, state, step (STYLE.md): an immutable GrowthModel, a copyable GrowthState (a checkpoint is a copy), a
/// GrowthWorkspace, and grow_step(model, field, control, state, workspace, dt) returning a GrowthStatus with the
/// step's events; the pressure and the tether are the step's loads (GrowthControl). VineGrowth holds the four for one
/// run.
///
/// One minimisation per step. Each step solves the whole body's equilibrium (solve_rod_statics) with the wall as a
/// smooth barrier on the distance from each node's sphere to the wall triangles within d̂ of it (WallBarrier;
/// incremental potential contact, Li et al. 2020), lagged smoothed Coulomb friction per node (NodeFriction), and the
/// growth law as the tip edge's axial law (TipGrowth). The lagged normal forces and contact axes are iterated until
/// they stop changing (GrowthOptions::friction_tolerance); a step that does not converge is taken again as two
/// halves, down to dt/16, and one that still fails ends growth with a "solver" event. The line search never lets a
/// node cross the wall.
///
/// Eversion. New material appears at the tip: the tip edge lengthens by the growth law and splits into an edge of h
/// and the rest once it reaches 3h/2. Material already everted does not slide along the wall: its friction
/// reference is where it was laid down (static friction below the slip ε, Coulomb μλ beyond). The everting tip is
/// free along its tangent; sideways its friction's slip scale is its growth in the step.
///
/// Pushed mode (InsertionMode::kPushed): the same body inserted from the base, as a catheter: a prescribed
/// insertion at the growth law's speed (up to the tether), and every material point's friction reference where its
/// material was before the step's insertion, which gives kinetic friction μλ against the sliding.
/// GrowthOptions::catheter pushes a solid tube instead of the vine, GrowthOptions::rod a (magnetic) rod at its own
/// insertion speed.
///
/// Growth law (PHYSICS.md §3, Blumenschein et al. 2017's form; the constants are not published for these robots):
///   L̇ = K·max(0, P − Y),  Y = Y0 + c_L·L + c_θ·Σθ,
/// Σθ the total turning along the body (the sum of the joint angles). Growth stalls when Y ≥ P (an event naming the
/// three terms) and when an obstacle carries the growth force (P − Y)·πR² along the tip (a "blocked" event, once the
/// tip grows less than 1 % of its free growth in a step). The tether caps the length. Burst: a pressure whose hoop
/// stress exceeds the film's strength (vine.hpp, bursts) is an event and ends growth. Diametric extension: the
/// radius is R(1 + PR/(tE)) (vine.hpp, extended_radius), used for the contacts and the inflated-beam law.
///
/// Squeezing (thesis 4.7.2, 5.6.2): where the lumen across the body (its narrowest width w through a node, by ray
/// casts in the plane normal to the body, also R ahead and behind) is narrower than the diameter, the section
/// flattens at constant perimeter (a thin, inextensible film) into a stadium of width w: the node's contact radius
/// drops to 0.45·w (a little slack between the two walls), each wall carries the pressure on the flat strip,
/// P·(πR − πw/2) per unit length, and the tip in the narrowing is driven over the stadium's area
/// A = πRw − πw²/4 only: it advances while P·A/(πR²) > Y (else a "squeeze" event). The width ahead of the tip is
/// measured from the lumen's middle (lumen_width's re-centring).
///
/// Tissue forces per step (WallForces): per node the barrier's push and the friction, reversed, as vectors and
/// magnitudes (plus the flattened section's pressure, or a pinched catheter's ring force), and the global balance
/// of the converged body.

#include <array>
#include <functional>
#include <initializer_list>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "magvine/anatomy/collision_world.hpp"
#include "magvine/core/eigen_types.hpp"
#include "magvine/core/units.hpp"
#include "magvine/robot/rod.hpp"
#include "magvine/robot/vine.hpp"

namespace magvine::robot {

/// L̇ = K·max(0, P − Y0 − c_L·L − c_θ·Σθ). The constants are not published for these robots. Defaults, for the Ø8 mm
/// skin vine of thesis 4.6 at its 12 kPa: Y0 = 5 kPa is FITTED to the thesis's constriction thresholds (it passes
/// 3 mm, not 2 mm: the squeezed tip keeps 60 % and 43 % of its section, so 0.43·12 < Y < 0.60·12 kPa where the
/// constriction sits, 40–60 mm in); c_L and c_θ are chosen so that it still grows with two right-angle turns over
/// its whole 250 mm (Y = 5 + 3 + 3.1 kPa < 12 kPa); K gives ~15 mm/s when short.
struct GrowthLaw {
  double extensibility = 2e-6;  ///< K [m/(s·Pa)]
  double yield_pressure = 5e3;  ///< Y0 [Pa]
  double length_yield = 12e3;   ///< c_L [Pa/m]
  double turning_yield = 1e3;   ///< c_θ [Pa/rad]
};

enum class InsertionMode { kEversion, kPushed };

/// A solid-walled tube pushed as a catheter (InsertionMode::kPushed only), in place of the vine's body: the
/// comparison of thesis 5.6.2, a TPU tube of OD 4 mm and ID 3 mm. Squeezed into a gap g narrower than its outer
/// diameter D, its wall bends like a ring pinched across a diameter (Roark, thin ring under two opposite line
/// loads: δ = 0.149·q·r³/(E·t³/12) per unit length, r the wall's mean radius, t its thickness), so each wall
/// carries q = (D − g)·E·t³/(12·0.149·r³) per unit length; the hard limit is the tube pressed flat, g = 2t.
struct CatheterTube {
  double outer_diameter = 4e-3;  ///< [m]
  double inner_diameter = 3e-3;  ///< [m]
  /// Young's modulus [Pa]. TPU of Shore 85A–95A has E ≈ 20–50 MPa; 26 MPa is an assumption (the thesis gives no
  /// grade), not fitted.
  double modulus = 26e6;
  double density = 1200.0;  ///< [kg/m³] (TPU)
};

/// A solid rod or catheter, magnetic or not (the mechanics' rod kind: rod.hpp), pushed in place of the vine's body
/// (InsertionMode::kPushed only). `body` is the whole rod as built for free space (its length the full length; the
/// magnetisation per edge from the base, at body.edges); the inserted part is its distal end, so the tip carries the
/// rod's tip section whatever the insertion: edge j of the inserted length ℓ takes the magnetisation at material
/// arc length L − ℓ + (j + ½)h. A solid section does not flatten: no squeezing, and the contacts are spheres of
/// `radius` (the section's circumscribed radius: a square's corners do not enter the wall).
struct PushedRod {
  RodModel body;
  double radius = 0.0;            ///< contact radius [m]
  double insertion_speed = 0.01;  ///< [m/s]: the insertion follows the tether at this speed (no growth law)
};

/// The body's solver in a growth step: from the last equilibrium at full load, no ramp (RodSolveOptions::ramp), at
/// most 1000 Newton iterations (a step that needs more is solved again with its loads ramped, then taken again as
/// two halves). Newton's line search lowers the energy at every iteration, so a longer run from the last
/// equilibrium follows the quasi-static path; the ramp starts over from the unloaded body and may end on another
/// branch (with a budget of 200, the three steps of a breathing generation-4 batch that reached the ramp, all three
/// failed on its 600, needed 204-313 from the last equilibrium; the ramp, given 6000, needed 1600-2500 and 16-31
/// snaps).
inline RodSolveOptions growth_solver_options() {
  RodSolveOptions o;
  o.ramp = false;
  o.max_snap_newton = 1000;
  o.max_iterations = 1000;
  o.tolerance = 1e-7;
  o.reuse_hessian = false;
  return o;
}

struct GrowthOptions {
  GrowthLaw law;
  InsertionMode mode = InsertionMode::kEversion;
  /// Pushed mode only: push this tube instead of the (pressurised) vine body. The growth law still sets the
  /// insertion speed (control.pressure as a stand-in for the push); pressure, burst and diametric extension do not
  /// apply to it.
  std::optional<CatheterTube> catheter;
  /// Pushed mode only: push this rod instead (PushedRod; not with `catheter`).
  std::optional<PushedRod> rod;
  double edge_length = 0.0;  ///< h [m]; 0: the vine's radius
  double friction = 0.3;     ///< Coulomb μ between the body and the wall
  /// The barrier stiffness κ [N/m]; 0: automatic (the growth force at 2 % R depth).
  double contact_stiffness = 0.0;
  double max_length = std::numeric_limits<double>::infinity();  ///< the vine's made length [m]
  /// The barrier's activation distance d̂ [m]; 0: 2 % of the radius. The body rests within d̂ of the wall.
  double contact_distance = 0.0;
  /// The slip ε below which friction is static [m]; 0: 1 % of the radius.
  double friction_slip = 0.0;
  /// Solves per step while the lagged normal forces settle (each to the solver's tolerance); the step
  /// fails (and is retried in halves) when they have not settled by then.
  int max_friction_iterations = 40;
  /// The lagged normal forces have settled when their total change over the body is within this fraction
  /// of the total contact force (plus a vine's growth force), no node carrying more than 1 % of the largest force
  /// turns its contact axis by more than 0.01 rad, and the tip's growth (its friction's slip scale) is within 10 %.
  double friction_tolerance = 1e-3;
  /// Magnetorheological stiffening of a magnetic-fluid fill (thesis 5.6.4: near the EPM the fluid stiffened and
  /// growth stopped until the magnet was withdrawn). Growth feeds the tip with fluid flowing along the body; a
  /// Bingham fluid of yield stress τ_y flows through a tube of radius R only where the pressure gradient exceeds
  /// 2τ_y/R, so growing needs the extra pressure ΔP = (2/R)∫τ_y(|B(s)|/μ0) ds over the body (added to the yield Y).
  /// τ_y(H) is magnetics::magnetorheological_yield_stress (Ginder & Davis 1994). Off by default; only for a
  /// magnetic-fluid fill.
  bool magnetorheology = false;
  /// Retraction by deflating and pulling: at or below this pressure [Pa] a tether pulled back below the everted
  /// length inverts the tip (whole edges, as far as the tether has been pulled); above it the tether holds the
  /// length (a pressurised vine does not retract: the pull buckles it) and a "retract" event says so once.
  /// Negative: no retraction (the tether only caps growth).
  double retraction_pressure = -1.0;
  Vec3 gravity = Vec3(0.0, 0.0, -9.81);  ///< [m/s²] (bench phantoms: z up)
  /// Young's modulus of the airway wall [Pa], for the contact pressure under a solid body (hertz_line_pressure;
  /// the wall itself stays rigid in the solve). Human bronchial walls measure 0.17–1.65 MPa in compression, their
  /// mucosa 0.02–0.28 MPa (Wang et al. 2011, arXiv:1111.5645); 0.5 MPa is an assumption within the walls' range.
  double tissue_modulus = 0.5e6;
  /// A vine's film flattens on the wall (WallBarrier::flattening, flattening_law): a node's sphere gives way to
  /// half its radius under the pressure's work, so no node presses the wall with more than its flattened film
  /// carries until it is flattened to that core. Off: rigid spheres (as before 2026-12-06). Pushed and solid
  /// bodies are rigid either way.
  bool flattening = true;
  RodSolveOptions solver = growth_solver_options();
};

/// The growth law's terms at one step (growth_rate).
struct GrowthRate {
  double length_term = 0.0;   ///< c_L·L [Pa]
  double turning_term = 0.0;  ///< c_θ·Σθ [Pa]
  double extra_yield = 0.0;   ///< further yield, e.g. the magnetorheological ΔP [Pa]
  double yield = 0.0;         ///< Y = Y0 + c_L·L + c_θ·Σθ + extra [Pa]
  double speed = 0.0;         ///< L̇ = K·max(0, P − Y) [m/s]
};

/// The growth law (PHYSICS.md §3, Blumenschein et al. 2017's form): L̇ = K·max(0, P − Y), Y = Y0 + c_L·L + c_θ·Σθ
/// (+ `extra_yield`), at pressure P [Pa], everted length L [m] and total turning Σθ [rad].
GrowthRate growth_rate(const GrowthLaw& law, double pressure, double length, double turning, double extra_yield = 0.0);

/// The force a growing tip drives forward, (P − Y)·πR² [N] (0 at or below the yield): what an obstacle in front of a
/// stalled tip carries, and the work per length that the growth test weighs against the energy a new edge stores.
double growth_force(double pressure, double yield, double radius);

/// The pressure on a wall under a pressurised thin film that lies on it [Pa]: flat over its contact patch, the film
/// carries its inflation pressure P there (a membrane without bending stiffness has no other normal load), so a
/// node's force F spreads over F/P, up to the half of its film that can face one wall, πR·ℓ (ℓ the body length the
/// node stands for); a larger force is F/(πRℓ). 0 for F ≤ 0.
double film_contact_pressure(double force, double pressure, double radius, double length);

/// The poisson ratio of the airway wall in hertz_line_pressure: 0.45, nearly incompressible soft tissue (an
/// assumption; at 0.5 the peak pressure is 4 % higher).
constexpr double kTissuePoisson = 0.45;

/// The peak pressure under a cylinder of radius R much stiffer than the tissue, pressed into it with a line load q
/// [N/m] (Hertz line contact on an elastic half-space; Johnson, Contact Mechanics, 1985, §4.2, eq. 4.45):
///   p0 = √(q·E*/(πR)),  E* = E/(1 − ν²),  over the half width b = √(4qR/(πE*)) (hertz_half_width) [Pa].
double hertz_line_pressure(double line_load, double radius, double modulus, double poisson = kTissuePoisson);
/// The half width b of that contact [m].
double hertz_half_width(double line_load, double radius, double modulus, double poisson = kTissuePoisson);

/// What happened (GrowthEvent): the yield stalled growth, growth resumed, the wall blocked the tip, a narrowing
/// squeezed it out, the film burst, the tether retracted the tip (or was refused), the body's solve failed.
enum class GrowthEventKind { kStall, kResume, kBlocked, kSqueeze, kBurst, kRetract, kSolver };

/// "stall", "resume", "blocked", "squeeze", "burst", "retract", "solver": the only place this text is made.
std::string_view growth_event_name(GrowthEventKind kind);

/// Something that happened during growth.
struct GrowthEvent {
  double time = 0.0;    ///< [s]
  double length = 0.0;  ///< everted length then [m]
  GrowthEventKind kind = GrowthEventKind::kStall;
  std::string detail;  ///< human-readable cause with numbers (kPa, mm, N)
};

/// Forces on the tissue after a step [N], per node (0 for the clamp and nodes out of contact).
struct WallForces {
  std::vector<double> normal;
  std::vector<double> shear;
  /// The forces on the tissue as vectors [N] (normal: the barrier's push reversed; shear: the friction's).
  std::vector<Vec3> normal_vector;
  std::vector<Vec3> shear_vector;
  /// The contact pressure on the tissue [Pa] (0 off the wall): a vine's film presses with its pressure
  /// (film_contact_pressure, the node's force over its patch), a solid body with the Hertz peak of its line load
  /// (hertz_line_pressure, GrowthOptions::tissue_modulus).
  std::vector<double> pressure;
  double max_pressure = 0.0;  ///< [Pa]
  /// The global balance of the converged body, Σ(wall normal + friction + magnetic + gravity + clamp + tip
  /// contact) on the body [N] (zero at equilibrium), and the largest of those loads' magnitudes [N], its scale.
  Vec3 imbalance = Vec3::Zero();
  double largest_load = 0.0;
  Vec3 clamp = Vec3::Zero();  ///< the clamp's force on the body [N]
  double max_normal = 0.0;
  /// The largest normal force per length of body over the nodes [N/m]: a node's normal force over the length it
  /// stands for (an edge; the tip half its edge and its cap), the line load. A distributed contact splits the same
  /// load over more nodes on a finer mesh, so a node's force falls with h; its line load is what converges.
  double max_line_load = 0.0;
  double mean_normal = 0.0;  ///< over the nodes in contact
  double total_normal = 0.0;
  double max_shear = 0.0;
  double total_shear = 0.0;
  int nodes_in_contact = 0;
};

/// What one step did (grow_step), with the events it raised.
struct GrowthStatus {
  int edges_added = 0;
  bool stalled = false;  ///< no growth this step (yield, blocked, tether, length or burst)
  bool burst = false;
  bool converged = true;  ///< the body reached equilibrium (else the cause is in failure and a kSolver event)
  int solves = 0;         ///< body solves in the step (the friction lag's iterations)
  int retries = 0;        ///< steps that failed and were taken again (a damped lag, or as two halves)
  int newton_iterations = 0;
  double yield = 0.0;                     ///< Y [Pa] (with the magnetorheological term)
  double magnetorheological_yield = 0.0;  ///< its magnetorheological part ΔP [Pa]
  int edges_removed = 0;                  ///< retraction
  double speed = 0.0;                     ///< the growth law's L̇ before tether and blocking [m/s]
  std::string failure;
  std::vector<GrowthEvent> events;  ///< what happened in this step, in order
};

/// The control inputs of one step: the loads of the step, not parts of the model.
struct GrowthControl {
  double pressure = 0.0;                                           ///< P [Pa]
  double tether_length = std::numeric_limits<double>::infinity();  ///< the length the tether has released [m]
  /// A contact ahead of the tip whose reaction depends on where the tip is (TipContact, rod.hpp: a needle's
  /// tissue). It enters the equilibrium and the global balance (WallForces::imbalance) like every other load.
  std::optional<TipContact> tip_contact = std::nullopt;
};

/// Checks what a growth model needs of its vine, options and base frame (make_growth_model calls it; scene loaders
/// call it first, so that a bad value is an input error before any run): VineParameterError naming the option
/// (friction, edge_length, catheter, rod, base, …) otherwise. The vine's own parameters are vine_rod's to check.
void check_growth(const VineParameters& vine, const GrowthOptions& options, const Mat3& base_frame);

/// What a growing body is made of and where it grows (STYLE.md, Model): the vine as made (or the pushed catheter or
/// rod), the options, the anatomy and the clamp. Immutable after make_growth_model; shared by trials and threads.
/// The world is borrowed (it must outlive the model); null is free space.
struct GrowthModel {
  VineParameters vine;  ///< as made: radius the body's made radius (the tube's or rod's when pushed); the
                        ///< pressure, length and edges are not read (the state's)
  GrowthOptions options;
  const anatomy::CollisionWorld* world = nullptr;
  Vec3 base_position = Vec3::Zero();   ///< the clamp [m]
  Mat3 base_frame = Mat3::Identity();  ///< the clamp's frame (tangent = first column)
  double edge_length = 0.0;            ///< h [m]
  double dhat = 0.0;                   ///< the barrier's activation distance d̂ [m]
  double slip = 0.0;                   ///< the static friction's slip ε [m]
  /// A pushed catheter tube or rod rather than the vine's film: no pressure in its wall, no burst, no squeeze.
  bool solid() const { return options.catheter.has_value() || options.rod.has_value(); }
};

/// Builds and checks a growth model (check_growth; InputError, VineParameterError for the vine's own parameters).
/// `vine.length` and `vine.pressure` are the start's (start_growth), not the model's.
GrowthModel make_growth_model(const VineParameters& vine, const GrowthOptions& options,
                              const anatomy::CollisionWorld* world, const Vec3& base_position, const Mat3& base_frame);

/// One node's contact history (GrowthState::nodes; node 0 is the clamp and carries none).
struct GrowthNode {
  /// Its friction reference: where its material was laid down or last held (NaN: none) [m].
  Vec3 reference = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
  Vec3 contact_axis = Vec3::Zero();  ///< the lagged contact axis (unit; zero: none)
  double contact_force = 0.0;        ///< the lagged wall force λ [N]
  double strip_force = 0.0;          ///< the lagged force of a flattened section's strips [N]
  Vec3 wall_force = Vec3::Zero();    ///< the wall's net force on the body at the last solve [N]
  /// Where its contact radius was last measured (reused while the node moves less than 2 % R) [m].
  Vec3 radius_at = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
  double radius = 0.0;          ///< its (squeezed) contact radius there [m]
  Vec3 across = Vec3::UnitY();  ///< the pinch direction there
};

/// Everything of a growing body that changes in time (STYLE.md, State): plain and copyable, no pointers; a
/// checkpoint is a copy, and grow_step from a copy repeats the same step bit for bit.
struct GrowthState {
  double time = 0.0;              ///< [s]
  double pressure = 0.0;          ///< the pressure the body is at (the last step's) [Pa]
  int edges = 0;                  ///< N
  double tip_length = 0.0;        ///< the tip edge's made length [m] (between h/2 and 3h/2)
  double tip_grown = 0.0;         ///< the tip's growth in the last step [m] (its friction's slip scale)
  RodState body;                  ///< nodes and frames
  std::vector<GrowthNode> nodes;  ///< per node, its contact history (as many as body.x)
  WallForces forces;              ///< the forces on the tissue after the last step
  bool burst = false;
  bool stalled = false;          ///< by the yield (a "stall" event was given)
  bool blocked = false;          ///< by the wall or a narrowing (a "blocked" or "squeeze" event was given)
  bool retract_refused = false;  ///< a "retract" event said the vine must be deflated
  bool retracting = false;       ///< a "retract" event announced this retraction
  bool placing = false;          ///< start_growth is everting the initial body: prescribed growth, no events
};

/// The everted length of a state [m]: (N − 1)·h plus the tip edge's made length.
double everted_length(const GrowthModel& model, const GrowthState& state);

/// Scratch of grow_step (STYLE.md, Workspace), reused between steps: the rod model of the body at the step's
/// pressure, the rod solver's workspace, the checkpoint a failed step returns to.
struct GrowthWorkspace {
  RodModel body;           ///< the state's body as a rod at the step's pressure (derived: growth_body)
  double radius = 0.0;     ///< the body's (extended) radius at that pressure [m]
  double stiffness = 0.0;  ///< the barrier stiffness κ at that pressure [N/m]
  RodWorkspace rod;
  GrowthState checkpoint;  ///< the state before the step being tried
  /// The friction lag's scratch, per node: the references, the lagged λ, strip forces and axes, and the last two
  /// solves' inputs and outputs (the secant relaxation).
  std::vector<Vec3> reference;
  std::vector<double> lambda;
  std::vector<double> strip;
  std::vector<Vec3> axis;
  std::vector<std::array<double, 4>> last;
  /// Per node, its neighbourhood of the wall (the barrier's NearCache: spares BVH walks, changes no result).
  std::vector<anatomy::NearCache> near;
  /// Per node, its last flattened sphere (the barrier's SectionMemo: spares root solves, changes results only at
  /// round-off).
  std::vector<SectionMemo> sections;
};

/// The state's body as a rod (vine_rod of the vine with its N edges and tip edge, at `pressure`; the tube or the
/// inserted part of the rod when pushed), into workspace.body, with the radius and barrier stiffness at that
/// pressure.
void growth_body(const GrowthModel& model, const GrowthState& state, double pressure, GrowthWorkspace& workspace);

/// The first state: a body of `length` [m] (≥ one edge; rounded to whole edges) along the clamp's tangent at
/// `pressure` [Pa], in equilibrium with the field and the wall; where the straight body would enter the wall it is
/// cut and everted from there to its length (a "solver" event says how far it got if it cannot).
GrowthStatus start_growth(const GrowthModel& model, const RodField& field, double length, double pressure,
                          GrowthState& state, GrowthWorkspace& workspace);

/// Advances `state` by dt [s] under `control` (the pressure and tether are this step's loads): one step of the
/// growth law and the body's equilibrium with the wall together, a step that does not converge taken again as two
/// halves (down to dt/16). Returns what happened; on failure (converged false, a kSolver event) the state is the
/// last converged one with the time advanced. Throws InputError for dt ≤ 0 or a negative or non-finite pressure.
GrowthStatus grow_step(const GrowthModel& model, const RodField& field, const GrowthControl& control,
                       GrowthState& state, GrowthWorkspace& workspace, double dt);

/// A step whose load moves within it (the airway's breathing, a needle's advance), which grow_step's own retries
/// (halves of the growth) do not cut: taken in `splits[0]` pieces of dt/pieces each (1: the whole step), and while
/// that fails again from `state` as it was, in `splits[1]`, then `splits[2]`, … pieces: a loading path (e.g.
/// {1, 2, 4}). Before piece j of n (1-based) `load_to(j, n)` sets the load there: `control` is read afresh for every
/// piece, so load_to may change the caller's object it refers to (and the world). After each converged piece
/// `reached(j, n)` is called (may be empty). Returns the last attempt's status with the events of all its pieces;
/// on failure `state` is the last converged piece's, as grow_step leaves it. Throws InputError for no splits or a
/// piece count below 1.
GrowthStatus grow_step_in_pieces(const GrowthModel& model, const RodField& field, const GrowthControl& control,
                                 GrowthState& state, GrowthWorkspace& workspace, double dt,
                                 std::initializer_list<int> splits, const std::function<void(int, int)>& load_to,
                                 const std::function<void(int, int)>& reached = {});

/// Σθ over the joints of the state's body [rad] (workspace.body must be the state's: growth_body).
double growth_turning(const GrowthWorkspace& workspace, const GrowthState& state);

/// A convenience over the step function for one run: a model, a state, a workspace, the field and the events so
/// far. The world and the field are borrowed as in GrowthModel.
class VineGrowth {
 public:
  /// `vine`: the body (vine.length the initial everted length, ≥ one edge; vine.edges ignored; for a pushed rod or
  /// catheter only its length, the inserted length, is read), at vine.pressure; base pose of the clamp (tangent =
  /// first column of base_frame). `world` may be null (free space). Throws InputError for bad
  /// parameters (VineParameterError for the vine's own).
  VineGrowth(const VineParameters& vine, const GrowthOptions& options, const anatomy::CollisionWorld* world,
             RodField field, const Vec3& base_position, const Mat3& base_frame);

  /// grow_step by dt [s] under `control`; its events join events().
  GrowthStatus advance(double dt, const GrowthControl& control);

  /// Replaces the magnetic field (a moved EPM).
  void set_field(RodField field) { m_field = std::move(field); }

  const RodState& state() const { return m_state.body; }
  const GrowthState& growth_state() const { return m_state; }
  const GrowthModel& growth_model() const { return m_model; }
  const RodModel& model() const { return m_workspace.body; }
  double time() const { return m_state.time; }
  double length() const { return m_workspace.body.length; }  ///< everted length [m]
  double edge_length() const { return m_model.edge_length; }
  double radius() const { return m_workspace.radius; }                     ///< current (extended) radius [m]
  double turning() const { return growth_turning(m_workspace, m_state); }  ///< Σθ over the joints [rad]
  bool burst() const { return m_state.burst; }
  const std::vector<GrowthEvent>& events() const { return m_events; }
  const WallForces& wall_forces() const { return m_state.forces; }

 private:
  GrowthModel m_model;
  RodField m_field;
  GrowthState m_state;
  GrowthWorkspace m_workspace;
  std::vector<GrowthEvent> m_events;
};

}  // namespace magvine::robot
