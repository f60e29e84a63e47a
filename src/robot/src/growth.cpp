#include "magvine/robot/growth.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <optional>
#include <string>
#include <utility>

#include "magvine/anatomy/collision_world.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/text.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/magnetisation.hpp"

namespace magvine::robot {
namespace {

constexpr double kNone = std::numeric_limits<double>::quiet_NaN();
// A node that moved less than this (times R) since its contact radius was measured keeps it.
constexpr double kStill = 0.02;
// A squeezed node's contact radius is this fraction of the lumen width w (a little slack between the two walls, so
// the solver does not hold it at zero clearance from both); its physics (slot_area, flat_width) uses w itself. The
// radius is continuous in w: min(R, kSlack·w) reaches R at w = 2.22R, where slot_area and flat_width are already
// those of the round section.
constexpr double kSlack = 0.45;
// Moves toward the middle of its chords of the point where the growth test measures the lumen ahead of a new tip
// (Stepper::lumen_width): two leave a quarter of the offset in a round lumen.
constexpr int kRecentrings = 2;
// A step has not settled while a node's barrier radius, measured again where the solve moved it, shrinks by more
// than this fraction of R (Stepper::barrier_step).
constexpr double kRadiusChange = 0.01;
// Solves of a step's friction lag before its corrections are damped, and the change of the lagged forces (a
// fraction of their total) above which they are (Stepper::barrier_step).
constexpr int kUndampedSolves = 10;
constexpr double kCycleChange = 0.01;
// A step whose lag did not settle is taken again with its corrections halved whenever the change has not fallen below
// kStallRatio of its last low within kStallSolves solves (from kUndampedSolves on, down to kLeastDamping).
constexpr int kStallSolves = 4;
constexpr double kStallRatio = 0.7;
constexpr double kLeastDamping = 0.125;

bool has_reference(const Vec3& a) {
  return !std::isnan(a.x());
}

/// A tube of radius r squeezed into a slot of width g < 2r keeps its perimeter 2πr (a thin, inextensible film):
/// its section is a stadium of width g, two flat strips of width πr − πg/2 against the walls joined by half
/// circles, of area πrg − πg²/4. At g ≥ 2r, the round section.
double slot_area(double r, double g) {
  return g >= 2.0 * r ? kPi * r * r : kPi * r * g - 0.25 * kPi * g * g;
}
double flat_width(double r, double g) {
  return g >= 2.0 * r ? 0.0 : kPi * r - 0.5 * kPi * g;
}

/// The line load on each wall [N/m] of a catheter tube pinched into a gap g (CatheterTube: Roark's thin ring).
double ring_crush_load(const CatheterTube& c, double g) {
  const double t = 0.5 * (c.outer_diameter - c.inner_diameter);
  const double r = 0.25 * (c.outer_diameter + c.inner_diameter);
  return std::max(0.0, c.outer_diameter - g) * c.modulus * t * t * t / (12.0 * 0.149 * r * r * r);
}

/// The slower, surer solve after the step's own (growth_solver_options: Newton from the last equilibrium at the
/// full load) failed: the loads ramped up from that state, to the same tolerance.
RodSolveOptions ramped_solver(const RodSolveOptions& fast) {
  RodSolveOptions o;
  o.tolerance = fast.tolerance;
  o.max_iterations = 600;
  o.max_snap_newton = 300;
  o.reuse_hessian = fast.reuse_hessian;
  return o;
}

/// The body's radius as made: the catheter tube's or the pushed rod's when there is one, else the vine's. The edge
/// length and the contacts follow it.
double made_radius(const VineParameters& vine, const GrowthOptions& options) {
  if (options.catheter) return 0.5 * options.catheter->outer_diameter;
  if (options.rod) return options.rod->radius;
  return vine.radius;
}

/// The inserted distal length of a pushed rod (PushedRod), as `edges` edges: the body's uniform properties, and per
/// edge the magnetisation of the material there (edge midpoints mapped to the body's edges from its tip).
RodModel inserted_part(const RodModel& body, double length, int edges) {
  RodModel m = body;
  m.length = length;
  m.edges = edges;
  if (!body.moment_per_length.empty()) {
    const double h = length / edges;
    const double h_body = body.length / body.edges;
    m.moment_per_length.resize(static_cast<std::size_t>(edges));
    for (int j = 0; j < edges; ++j) {
      const double s = body.length - length + (j + 0.5) * h;  // material arc length from the rod's base
      const int k = std::clamp(static_cast<int>(std::floor(s / h_body)), 0, body.edges - 1);
      m.moment_per_length[static_cast<std::size_t>(j)] = body.moment_per_length[static_cast<std::size_t>(k)];
    }
  }
  return m;
}

/// The point at arc length s [m] along a body whose edges have the lengths `lengths` (nodes x); before the base, on
/// the line of `base_tangent` (material still in the introducer).
Vec3 point_at_arc(const RodState& body, const std::vector<double>& lengths, const Vec3& base_tangent, double s) {
  if (s <= 0.0) return body.x.front() + s * base_tangent;
  for (std::size_t j = 0; j < lengths.size(); ++j) {
    if (s <= lengths[j] || j + 1 == lengths.size()) {
      const double f = std::min(1.0, s / lengths[j]);
      return body.x[j] + f * (body.x[j + 1] - body.x[j]);
    }
    s -= lengths[j];
  }
  return body.x.back();
}

/// One call of grow_step or start_growth: the model, field, state and workspace it works on and the status it
/// fills, with the step's parts as methods.
struct Stepper {
  const GrowthModel& model;
  const RodField& field;
  GrowthState& state;
  GrowthWorkspace& ws;
  GrowthStatus& status;
  const TipContact* tip_contact = nullptr;  ///< the step's contact ahead of the tip (GrowthControl::tip_contact)

  const anatomy::CollisionWorld* world() const { return model.world; }
  double h() const { return model.edge_length; }
  double radius() const { return ws.radius; }
  double length() const { return ws.body.length; }

  void add_event(GrowthEventKind kind, std::string detail) {
    status.events.push_back({state.time, ws.body.length, kind, std::move(detail)});
  }
  /// The body at `pressure`: the state's pressure and the workspace's rod model.
  void rebuild(double pressure) {
    state.pressure = pressure;
    growth_body(model, state, pressure, ws);
  }
  double magnetorheological_yield() const;
  int retract_to(double length);
  bool in_sight(const Vec3& a, const Vec3& b) const;
  double lumen_width(const Vec3& x, const Mat3& frame, Vec3* across = nullptr, int recentrings = 0) const;
  double node_radius(const Vec3& x, const Mat3& frame, const Vec3& seen_from, Vec3* across = nullptr,
                     int recentrings = 0) const;
  bool barrier_steps(double dt, double pressure, double cap, int depth = 0);
  bool barrier_step(double dt, double pressure, double cap, bool damp_stalls = false);
  bool lag_unsettled = false;  ///< the last barrier_step failed because its friction lag did not settle
  void start(double length, double pressure);
  void step(const GrowthControl& control, double dt);
};

double Stepper::magnetorheological_yield() const {
  if (!model.options.magnetorheology || !field) return 0.0;
  double integral = 0.0;  // ∫τ_y ds, the field at each edge's midpoint
  const std::vector<Vec3>& x = state.body.x;
  for (std::size_t j = 0; j + 1 < x.size(); ++j) {
    const Vec3 mid = 0.5 * (x[j] + x[j + 1]);
    const double field_h = field(mid).b.norm() / kMu0;  // H [A/m]
    integral += magnetics::magnetorheological_yield_stress(field_h, model.vine.volume_fraction) * h();
  }
  return 2.0 * integral / radius();
}

/// Inverts whole edges at the tip down to `length` (keeps one edge) and solves again; returns how many.
int Stepper::retract_to(double length) {
  int removed = 0;
  while (state.edges > 1 && (state.edges - 1) * h() >= length - 1e-12 * h()) {
    --state.edges;
    state.body.x.pop_back();
    state.body.frames.pop_back();
    ++removed;
  }
  if (removed == 0) return 0;
  state.tip_length = h();
  rebuild(state.pressure);  // (barrier_step sizes the per-node state to the shorter body)
  if (!barrier_step(0.0, state.pressure, 0.0)) {
    add_event(GrowthEventKind::kSolver, "after retracting: " + status.failure);
  }
  return removed;
}

/// Whether the segment from a to b crosses no wall: with a in the lumen, b is in it too and a body at a could reach
/// it (a short ray cast; CollisionWorld::contains casts parity rays across the whole mesh, 10–20 times the cost).
/// Unlike the parity test, a point in a neighbouring lumen behind tissue counts as out of sight.
bool Stepper::in_sight(const Vec3& a, const Vec3& b) const {
  return !world()->segment_crosses(a, b);
}

/// Narrowest width of the lumen across the body at x (4 lines through x in the plane ⟂ frame.col(0), ray casts up to
/// 2R each way) [m]. With `recentrings` > 0, where that would squeeze the body the lines are cast again from the mean
/// of the chords' midpoints, up to that many times, so that a point off a round lumen's axis does not read its short
/// chords as a gap.
double Stepper::lumen_width(const Vec3& x, const Mat3& frame, Vec3* across, int recentrings) const {
  const double reach = 2.0 * radius();
  Vec3 centre = x;
  double width = 0.0;
  Vec3 line = frame.col(1);
  for (int pass = 0;; ++pass) {
    width = 2.0 * reach;
    Vec3 middle = Vec3::Zero();  // the mean of the chords' midpoints
    for (int k = 0; k < 4; ++k) {
      const double a = 0.25 * kPi * k;
      const Vec3 u = std::cos(a) * frame.col(1) + std::sin(a) * frame.col(2);
      const auto plus = world()->ray_cast(centre, u, reach);
      const auto minus = world()->ray_cast(centre, -u, reach);
      const double d_plus = plus ? plus->distance : reach;
      const double d_minus = minus ? minus->distance : reach;
      if (d_plus + d_minus < width) line = u;
      width = std::min(width, d_plus + d_minus);
      middle += centre + 0.5 * (d_plus - d_minus) * u;
    }
    // A point off the lumen's axis has short chords across it (2√(ρ² − d²) at d off the axis of a round lumen of
    // radius ρ), which read as a gap that is not there. Where the width would squeeze the body, the point moves to
    // the mean of the chords' midpoints and the chords are cast again: in a round lumen each move halves the
    // offset (the midpoint of the chord along u is the axis point plus the offset's component along u, and four
    // directions 45° apart average uuᵀ to I/2); across a slot it changes no chord's length.
    if (pass == recentrings || kSlack * width >= radius()) break;
    middle *= 0.25;
    if ((middle - centre).norm() < 1e-3 * radius() || !in_sight(centre, middle)) break;
    centre = middle;
  }
  if (across != nullptr) *across = line;
  return width;
}

/// The body's contact radius at x: R, or half the lumen width at x or R ahead of or behind it when narrower.
/// `seen_from`: a point in the lumen (the node before, x itself when the caller knows x is in it); x out of its
/// sight is in the tissue. `across`, if given, receives the direction of the narrowest line (the pinch);
/// `recentrings` as lumen_width.
double Stepper::node_radius(const Vec3& x, const Mat3& frame, const Vec3& seen_from, Vec3* across,
                            int recentrings) const {
  if (world() == nullptr || model.options.rod) return radius();  // a solid rod does not flatten
  const Vec3 t = frame.col(0);
  Vec3 line = frame.col(1);
  double width = lumen_width(x, frame, &line, recentrings);
  // A centre pressed past the wall (a new tip placed into a carina's ridge before the solve pushes it out) sees the
  // tissue, not a gap: only the probes inside the lumen count then.
  const bool narrow = width < 4.0 * radius();
  const bool x_in = !narrow || in_sight(seen_from, x);
  if (!x_in) width = 4.0 * radius();
  if (narrow) {  // near a narrowing: the sphere's front and back too
    for (const double side : {1.0, -1.0}) {
      // Where the sphere's front is already past a wall (the tip against a carina's ridge), the rays would measure
      // the tissue between two branches, not a gap: the wall ahead is a contact, not a constriction.
      // Nor does a narrowing ahead that closes a radius further on (the notch of a carina's saddle, a blind end): a
      // slot squeezes a body that can go on into it.
      const Vec3 probe = x + side * radius() * t;
      if (!in_sight(x_in ? x : seen_from, probe) || (side > 0.0 && !in_sight(probe, probe + radius() * t))) continue;
      Vec3 u = line;
      const double w = lumen_width(probe, frame, &u, recentrings);
      if (w < width) line = u;
      width = std::min(width, w);
    }
  }
  if (across != nullptr) *across = line;
  return std::min(radius(), kSlack * width);
}

/// Steps of dt from the growth law's speed on (the step's preamble done), a failed one retried with its stalls
/// damped where its friction lag did not settle, then as two halves (down to dt/16); false when even those fail.
/// `cap`: how far the tether and the made length let it grow.
bool Stepper::barrier_steps(double dt, double pressure, double cap, int depth) {
  constexpr int kMaxHalvings = 4;
  const auto retried = [&] {
    ++status.retries;
    status.converged = true;
    status.failure.clear();
    return true;
  };
  if (barrier_step(dt, pressure, cap)) return true;
  if (lag_unsettled && barrier_step(dt, pressure, cap, true)) return retried();
  if (depth == kMaxHalvings || dt == 0.0) return false;
  const double before = length();
  if (!barrier_steps(0.5 * dt, pressure, cap, depth + 1)) return false;
  if (!barrier_steps(0.5 * dt, pressure, std::max(0.0, cap - (length() - before)), depth + 1)) return false;
  return retried();
}

bool Stepper::barrier_step(double dt, double pressure, double cap, bool damp_stalls) {
  lag_unsettled = false;
  const std::size_t nodes = state.body.x.size();
  const std::size_t tip = nodes - 1;
  const double area = kPi * radius() * radius();
  const bool pushed = model.options.mode == InsertionMode::kPushed;
  const Vec3 tangent = state.body.frames.back().col(0);
  // The growth load on the tip edge (TipGrowth): the growth law's incremental potential for a vine that everts, a
  // prescribed insertion (stiff, up to the tether) for a pushed body.
  TipGrowth growth;
  const double axial = ws.body.axial_stiffness / robot::edge_length(ws.body, ws.body.edges - 1);
  double squeeze = 1.0;
  double tip_room = radius();  // the tip's flattened contact radius in a narrowing ahead
  double push = 0.0;           // a pushed body's insertion in this step [m]
  // (At the tether, cap = 0, the tether takes the tip's pressure force: nothing pushes the body.)
  if (dt > 0.0 && cap > 0.0) {
    if (pushed || model.solid() || state.placing) {
      push = state.placing ? cap * std::min(1.0, dt) : std::min(status.speed * dt, cap);  // placing: dt 1, or halves
      growth = {axial * push, axial, push};
    } else if (model.options.law.extensibility > 0.0) {
      if (world() != nullptr) {
        // Squeezing: ahead of the tip the lumen's width (from its middle) leaves the flattened section's area only,
        // where the narrowing is one the tip can go on into (a carina's notch or a blind end closes a radius
        // further on: the tip meets it as a wall).
        const Vec3 ahead = state.body.x[tip] + radius() * tangent;
        if (in_sight(state.body.x[tip], ahead + radius() * tangent)) {
          tip_room = node_radius(ahead, state.body.frames.back(), ahead, nullptr, kRecentrings);
        }
        squeeze = slot_area(radius(), tip_room / kSlack) / area;
      }
      growth = {growth_force(pressure * squeeze, status.yield, radius()), area / (model.options.law.extensibility * dt),
                cap};
    }
  }
  // Contact radii (squeezed where the lumen is narrow), each at most what the node has room for at the start: a
  // configuration with a finite barrier energy.
  RodConstraints c;
  c.growth = growth;
  if (tip_contact != nullptr) c.tip_contact = *tip_contact;
  state.nodes.resize(nodes);
  // Node i's barrier radius for its contact radius r where it is now: the tip's at most its room ahead, and at
  // most its clearance (a finite barrier energy).
  // A vine's film flattens on the wall (WallBarrier::flattening): only its core needs the room.
  const bool film = model.options.flattening && !pushed && !model.solid() && !state.placing && pressure > 0.0;
  const double core = film ? kFilmCore : 1.0;
  const auto barrier_radius = [&](std::size_t i, double r) {
    if (i == tip) r = std::min(r, tip_room);  // the tip flattens into a slot
    std::array<anatomy::NearTriangle, 1> near{};
    if (world()->triangles_within(state.body.x[i], core * r, near) > 0) r = (near[0].distance - 0.1 * model.dhat) / core;
    return r > 0.1 * radius() ? r : 0.0;
  };
  // Whether node i has moved 2 % R from where its contact radius was measured.
  const auto moved = [&](std::size_t i) {
    return !((state.body.x[i] - state.nodes[i].radius_at).norm() <= kStill * radius());
  };
  const auto frame_of = [&](std::size_t i) -> const Mat3& { return state.body.frames[std::min(i, nodes - 2)]; };
  if (world() != nullptr) {
    WallBarrier wall{world(), std::vector<double>(nodes, 0.0), model.dhat, ws.stiffness, &ws.near, {}, kFilmCore,
                     &ws.sections};
    for (std::size_t i = 1; i < nodes; ++i) {
      GrowthNode& cache = state.nodes[i];
      if (moved(i)) {
        cache.radius_at = state.body.x[i];
        cache.radius = node_radius(state.body.x[i], frame_of(i), state.body.x[i - 1], &cache.across);
      }
      wall.radius[i] = barrier_radius(i, cache.radius);
    }
    if (film) {
      // Each side stands for an edge's length of body; the tip for its cap.
      wall.flattening.assign(nodes, FlatteningSection{pressure, h(), false});
      wall.flattening[tip].cap = true;
    }
    c.wall = std::move(wall);
  }
  // Friction references: where each everted node's material was laid down (kept across steps, moved to the
  // Coulomb limit after a slip), or where a pushed body's material was before this step's insertion.
  std::vector<Vec3>& reference = ws.reference;
  reference.resize(nodes);
  for (std::size_t i = 0; i < nodes; ++i) reference[i] = state.nodes[i].reference;
  if (pushed) {
    std::vector<double> lengths(static_cast<std::size_t>(ws.body.edges));
    for (int j = 0; j < ws.body.edges; ++j) lengths[static_cast<std::size_t>(j)] = robot::edge_length(ws.body, j);
    double s = 0.0;
    for (std::size_t i = 1; i < nodes; ++i) {
      s += lengths[i - 1];
      reference[i] = point_at_arc(state.body, lengths, model.base_frame.col(0), s - push);
    }
  }
  // The checkpoint a failed step returns to (the contact radii just measured stay measured).
  ws.checkpoint = state;
  const auto restore = [&] { state = ws.checkpoint; };
  // Two lagged contact channels per node, each with its own friction: the walls within d̂ of the sphere (force λ,
  // the principal direction of their normals), and a flattened section's strips (force s, across the pinch).
  std::vector<double>& lambda = ws.lambda;
  std::vector<double>& strip = ws.strip;
  std::vector<Vec3>& axis = ws.axis;
  lambda.resize(nodes);
  strip.resize(nodes);
  axis.resize(nodes);
  for (std::size_t i = 0; i < nodes; ++i) {
    lambda[i] = state.nodes[i].contact_force;
    strip[i] = state.nodes[i].strip_force;
    axis[i] = state.nodes[i].contact_axis;
  }
  // The last lagged values of λ and s fed to a solve, and what that solve returned (the secant relaxation below).
  std::vector<std::array<double, 4>>& last = ws.last;
  last.assign(nodes, {kNone, kNone, kNone, kNone});
  bool settled = false;
  // The everting tip. Along its tangent it advances by laying new material down (free). Sideways its material
  // slides on the wall, but while it grows the material under the contact already slides (it flows over the cap
  // at the growth's rate), so Coulomb friction resists a sideways slip u with μλ·f1(|u|/ε_tip), ε_tip the tip's
  // growth in the step (a spinning top's friction: nearly viscous for a slip much slower than the growth), ε
  // when it does not grow. Held by the wall, its material stays the same: the reference stays where it was held.
  if (!pushed && (!state.blocked || !has_reference(reference[tip]))) reference[tip] = state.body.x[tip];
  // The tip edge's growth in the current state: its extension past its made length, within the step's limit.
  const auto tip_grown = [&] {
    if (!(dt > 0.0 && growth.force > 0.0)) return 0.0;
    const Vec3 edge = state.body.x[tip] - state.body.x[tip - 1];
    const double extension = state.body.frames.back().col(0).dot(edge) - robot::edge_length(ws.body, ws.body.edges - 1);
    return std::clamp(extension, 0.0, std::max(0.0, growth.limit));
  };
  double tip_growth = state.blocked ? 0.0 : state.tip_grown;  // lagged, as λ
  const auto free_along = [&](std::size_t i, const Vec3& n) -> Vec3 {
    if (pushed || i != tip) return Vec3::Zero();
    const Vec3 f = tangent - tangent.dot(n) * n;
    return f.norm() > 1e-6 ? Vec3(f.normalized()) : Vec3::Zero();
  };
  double low = std::numeric_limits<double>::infinity();  // the lag's last low of its change, and its solve
  int low_at = 0;
  double stall_damping = 1.0;
  for (int k = 0; k < model.options.max_friction_iterations && !settled; ++k) {
    c.friction.clear();
    for (std::size_t i = 1; i < nodes && world() != nullptr; ++i) {
      if (!(lambda[i] > 0.0) && !(strip[i] > 0.0)) continue;
      if (!has_reference(reference[i])) reference[i] = state.body.x[i];
      const double slip = !pushed && i == tip ? std::max(model.slip, tip_growth) : model.slip;
      if (lambda[i] > 0.0) {
        c.friction.push_back({static_cast<int>(i), reference[i], axis[i], lambda[i], model.options.friction, slip,
                              free_along(i, axis[i])});
      }
      if (strip[i] > 0.0) {
        const Vec3& across = state.nodes[i].across;
        c.friction.push_back(
            {static_cast<int>(i), reference[i], across, strip[i], model.options.friction, slip, free_along(i, across)});
      }
    }
    ++status.solves;
    RodSolveReport r = solve_rod_statics(ws.body, field, state.body, model.options.solver, &ws.rod, &c);
    if (!r.converged && model.options.solver.ramp == false) {
      // Loads that changed too much for Newton from the last equilibrium (a magnet brought close, a deflation):
      // the same step with the loads ramped up from there.
      status.newton_iterations += r.iterations;
      r = solve_rod_statics(ws.body, field, state.body, ramped_solver(model.options.solver), &ws.rod, &c);
    }
    status.newton_iterations += r.iterations;
    if (!r.converged) {
      restore();
      status.converged = false;
      status.failure = r.failure;
      return false;
    }
    if (world() == nullptr) break;
    const double grown_now = pushed ? 0.0 : tip_grown();  // this solve's, for the tip friction's slip
    const std::vector<NodeWallForce> f = wall_barrier_forces(state.body, *c.wall);
    // The growth force of a vine is a load the wall carries when it blocks the tip; a pushed body's prescribed
    // insertion (a stiff spring to the push) is not, and would swamp the tolerance.
    const double tip_load = pushed || model.solid() || state.placing ? 0.0 : growth.force;
    double scale = tip_load;
    std::vector<double> next_strip(nodes, 0.0);
    for (std::size_t i = 1; i < nodes; ++i) {
      // A flattened section presses each of the two walls with P over its flat strip, 2·P·(πR − πg/2)·h; a
      // pinched catheter with its ring's line load, 2·q(g)·h.
      if (c.wall->radius[i] > 0.0 && state.nodes[i].radius < radius()) {
        const double g = state.nodes[i].radius / kSlack;
        next_strip[i] = 2.0 * h() *
                        (model.options.catheter ? ring_crush_load(*model.options.catheter, g)
                                                : state.pressure * flat_width(radius(), g));
      }
      scale = std::max({scale, f[i].magnitude, next_strip[i]});
    }
    // Settled when the lagged forces' total change is within friction_tolerance of the total contact force (plus
    // the growth force), and no node that carries a share of it turns its axis: light contacts that flicker on
    // and off a resting body change their few mN, not the friction the body carries.
    double change = 0.0;
    double total = tip_load;
    for (std::size_t i = 1; i < nodes; ++i) {
      change += std::abs(f[i].magnitude - lambda[i]) + std::abs(next_strip[i] - strip[i]);
      total += f[i].magnitude + next_strip[i];
    }
    // The tip's slip scale settles with the rest: within 10 % (or ε).
    settled = change <= model.options.friction_tolerance * total &&
              std::abs(grown_now - tip_growth) <= 0.1 * std::max(tip_growth, model.slip);
    // A pushed body's contact radii are lagged with the forces: every node slides by the step's insertion, and
    // one the solve moved has its radius measured again where it is now; the step has not settled while a radius
    // shrinks by more than kRadiusChange of R. Within a step a radius only shrinks (a node leaving a narrowing
    // takes its round section back at the next step's start), so the radii cannot alternate. (Measured only at the
    // step's start, a catheter pushed into the constriction's jaws met them with its round radius for one step:
    // 88.7 N on one node, 1.3 N the step after.) A vine's everted nodes do not slide, and its tip flattens to the
    // room ahead measured at the step's start (tip_room); lagged for vines too, the tip kept squeezing into the
    // closing end of a generation-4 branch within a step, and a trial of the generation-4 batch (seed 0) failed.
    for (std::size_t i = 1; i < nodes && pushed; ++i) {
      if (!moved(i)) continue;
      Vec3 across;
      const double measured = node_radius(state.body.x[i], frame_of(i), state.body.x[i - 1], &across);
      const double now = barrier_radius(i, measured);
      if (now < c.wall->radius[i] - kRadiusChange * radius()) {
        GrowthNode& node = state.nodes[i];
        node.radius_at = state.body.x[i];
        node.radius = measured;
        node.across = across;
        c.wall->radius[i] = now;
        settled = false;
      }
    }
    // (Halfway after the first solve: a tip between growing and held would otherwise alternate.)
    tip_growth += (grown_now - tip_growth) * (k > 0 ? 0.5 : 1.0);
    const double tolerance = model.options.friction_tolerance * scale;
    // A lag still changing by more than kCycleChange of the total contact force after kUndampedSolves solves is a
    // cycle among nodes (a contact lost and found again through a neighbour's friction), which the per-node secants
    // below do not see: every correction is then halved, and halved again after as many solves more. Closer to the
    // tolerance the corrections stay whole (damped there, the lag stalled at 1.5 tolerances after a deflation).
    const bool cycling = k >= kUndampedSolves && change > kCycleChange * total;
    // Below that, a cycle among a few light contacts can go on changing by a few tolerances: taken again
    // (damp_stalls), a change that stops falling is damped, stepwise. Not on the first try: measured on the
    // generation-4 batches, damping there let a lag settle that had not (h = 1 mm, 0-1-1-0-0 repeat 2) but kept
    // three others from settling that had (h = 1.5 mm, and breathing).
    if (change < kStallRatio * low) {
      low = change;
      low_at = k;
    } else if (damp_stalls && k >= kUndampedSolves && k - low_at >= kStallSolves) {
      stall_damping = std::max(kLeastDamping, 0.5 * stall_damping);
      low_at = k;
    }
    const double damping = std::min(stall_damping, !cycling ? 1.0 : (k < 2 * kUndampedSolves ? 0.5 : 0.25));
    for (std::size_t i = 1; i < nodes; ++i) {
      // From the kUndampedSolves-th solve on, a node's contact axis is held where it is (and its turning no longer
      // keeps the lag open): between two walls at a wide angle (a tip in the funnel of a lobar bifurcation) the
      // principal direction of their normals swings with their balance, by 0.3–0.8 rad from solve to solve, and
      // the axis has no fixed point to settle on; any plane between the walls is as good a lag. λ still settles.
      const bool held = k >= kUndampedSolves && !axis[i].isZero();
      if (!held && f[i].magnitude > 10.0 * tolerance && lambda[i] > 0.0 && axis[i].cross(f[i].axis).norm() > 1e-2) {
        settled = false;
      }
      // The lag is a fixed point λ = g(λ) per node. Where a node's friction moves it off the force it was lagged
      // at, g falls as λ rises (slope σ < 0) and plain iteration alternates, converging as |σ|^k or not at all;
      // the relaxation λ += (g − λ)/(1 − σ), σ the secant slope of the last two solves, takes the secant's root
      // (a tenth of the correction at least; where λ creeps one way, σ > 0, the whole correction).
      const auto relax = [](double in, double out, double in_before, double out_before) {
        if (std::isnan(in_before) || !(std::abs(in - in_before) > 1e-12 * (std::abs(in) + std::abs(out)))) return 1.0;
        const double slope = (out - out_before) / (in - in_before);
        return slope < 0.0 ? std::clamp(1.0 / (1.0 - slope), 0.1, 1.0) : 1.0;
      };
      const double dl = f[i].magnitude - lambda[i];
      const double ds = next_strip[i] - strip[i];
      const double w_lambda = std::min(damping, relax(lambda[i], f[i].magnitude, last[i][0], last[i][1]));
      const double w_strip = std::min(damping, relax(strip[i], next_strip[i], last[i][2], last[i][3]));
      last[i] = {lambda[i], f[i].magnitude, strip[i], next_strip[i]};
      lambda[i] += w_lambda * dl;
      strip[i] += w_strip * ds;
      const double w = std::min(w_lambda, w_strip);
      if (!held) {
        const Vec3 blended = axis[i].isZero() ? f[i].axis : Vec3(axis[i] + w * (f[i].axis - axis[i]));  // as its λ
        axis[i] = blended.norm() > 1e-9 ? Vec3(blended.normalized()) : f[i].axis;
      }
      state.nodes[i].wall_force = f[i].force;
    }
  }
  if (!settled && world() != nullptr) {
    restore();
    lag_unsettled = true;
    status.converged = false;
    status.failure =
        "the lagged friction did not settle in " + std::to_string(model.options.max_friction_iterations) + " solves";
    return false;
  }
  // Forces on the tissue (the converged solve's).
  for (std::size_t i = 0; i < nodes; ++i) {
    state.nodes[i].contact_force = lambda[i];
    state.nodes[i].strip_force = strip[i];
    state.nodes[i].contact_axis = axis[i];
  }
  state.forces = WallForces{};
  state.forces.normal.assign(nodes, 0.0);
  state.forces.shear.assign(nodes, 0.0);
  state.forces.normal_vector.assign(nodes, Vec3::Zero());
  state.forces.shear_vector.assign(nodes, Vec3::Zero());
  state.forces.pressure.assign(nodes, 0.0);
  for (const NodeFriction& f : c.friction) {
    const auto i = static_cast<std::size_t>(f.node);
    state.forces.shear_vector[i] -= friction_force(f, state.body.x[i]);
    // Static friction's reference follows a slip past ε (the node then sits at the Coulomb limit).
    const Vec3 u = friction_slip(f, state.body.x[i]);
    if (!pushed && u.norm() > model.slip) reference[i] += (1.0 - model.slip / u.norm()) * u;
  }
  for (std::size_t i = 1; i < nodes; ++i) {
    const double fn = lambda[i] + strip[i];
    state.forces.normal[i] = fn;
    state.forces.shear[i] = state.forces.shear_vector[i].norm();
    state.forces.normal_vector[i] = -state.nodes[i].wall_force;
    state.forces.max_normal = std::max(state.forces.max_normal, fn);
    state.forces.total_normal += fn;
    state.forces.max_shear = std::max(state.forces.max_shear, state.forces.shear[i]);
    state.forces.total_shear += state.forces.shear[i];
    if (fn > 0.0) ++state.forces.nodes_in_contact;
    // The contact pressure: a node stands for an edge's length of body, the tip for half its edge and its cap (a
    // hemisphere of radius R, whose film faces one way over πR·R).
    const double share = i == tip ? 0.5 * robot::edge_length(ws.body, ws.body.edges - 1) + radius() : h();
    // The walls within d̂ carry λ on one side; a flattened section's strips (or a pinched tube's ring) press two
    // opposite walls with s/2 each, the film there flat at its pressure.
    const double e = model.options.tissue_modulus;
    const double p_contact = model.solid() ? std::max(hertz_line_pressure(lambda[i] / share, radius(), e),
                                                      hertz_line_pressure(0.5 * strip[i] / share, radius(), e))
                                           : std::max(film_contact_pressure(lambda[i], pressure, radius(), share),
                                                      strip[i] > 0.0 ? pressure : 0.0);
    state.forces.pressure[i] = p_contact;
    state.forces.max_line_load = std::max(state.forces.max_line_load, fn / share);
    state.forces.max_pressure = std::max(state.forces.max_pressure, p_contact);
    if (!(fn > 0.0) || pushed) reference[i] = Vec3::Constant(kNone);  // off the wall: released
  }
  if (state.forces.nodes_in_contact > 0) {
    state.forces.mean_normal = state.forces.total_normal / state.forces.nodes_in_contact;
  }
  {
    // The global balance: every force on the body, each computed from its own law.
    Vec3 wall = Vec3::Zero();
    Vec3 friction = Vec3::Zero();
    for (std::size_t i = 1; i < nodes; ++i) {
      wall += state.nodes[i].wall_force;
      friction -= state.forces.shear_vector[i];
    }
    const Vec3 load = body_load(ws.body, field, state.body);
    state.forces.clamp = clamp_force(ws.body, field, state.body);
    const Vec3 contact = tip_contact != nullptr ? tip_contact_force(*tip_contact, state.body.tip()) : Vec3::Zero();
    state.forces.imbalance = wall + friction + load + state.forces.clamp + contact;
    state.forces.largest_load =
        std::max({wall.norm(), friction.norm(), load.norm(), state.forces.clamp.norm(), growth.force, contact.norm()});
  }
  for (std::size_t i = 0; i < nodes; ++i) state.nodes[i].reference = reference[i];
  // Growth: the tip edge's extension past its made length becomes made length; a tip edge of 3h/2 splits into an
  // edge of h and the rest.
  const double grown = tip_grown();
  state.tip_length += grown;
  state.tip_grown = grown;
  while (state.tip_length >= 1.5 * h()) {
    const Vec3 t = state.body.frames.back().col(0);
    const Vec3 at = state.body.x[state.body.x.size() - 2] + h() * t;
    const std::size_t n = state.body.x.size() - 1;  // the new node's index; the tip moves to n + 1
    state.body.x.insert(state.body.x.begin() + static_cast<std::ptrdiff_t>(n), at);
    state.body.frames.push_back(state.body.frames.back());
    state.nodes.insert(state.nodes.begin() + static_cast<std::ptrdiff_t>(n), GrowthNode{});
    for (auto* v : {&state.forces.normal, &state.forces.shear, &state.forces.pressure}) {
      v->insert(v->begin() + static_cast<std::ptrdiff_t>(n), 0.0);
    }
    for (auto* v : {&state.forces.normal_vector, &state.forces.shear_vector}) {
      v->insert(v->begin() + static_cast<std::ptrdiff_t>(n), Vec3::Zero());
    }
    ++state.edges;
    ++status.edges_added;
    state.tip_length -= h();
  }
  rebuild(pressure);
  // Events: the wall in front of the tip holding it (growth below 1 % of the free growth), or a narrowing.
  if (dt > 0.0 && !pushed && !model.solid() && !state.placing) {
    const double free = growth.stiffness > 0.0 ? growth.force / growth.stiffness : 0.0;
    const bool held = growth.force > 0.0 && grown < 0.01 * free;
    if (held && !state.blocked) {
      state.blocked = true;
      const double carried = -state.nodes[tip].wall_force.dot(tangent);
      add_event(GrowthEventKind::kBlocked,
                printf_string("the wall in front of the tip carries %.3f N of the growth force %.3f N", carried,
                              growth.force));
    } else if (growth.force == 0.0 && squeeze < 1.0 && pressure > status.yield && !state.blocked) {
      state.blocked = true;
      add_event(GrowthEventKind::kSqueeze,
                printf_string("the narrowing ahead leaves the tip %.0f %% of its section: %.2f kPa x %.2f is at or "
                              "below the yield %.2f kPa",
                              100.0 * squeeze, pressure / kKpaToPa, squeeze, status.yield / kKpaToPa));
    } else if (grown >= 0.01 * free && growth.force > 0.0) {
      state.blocked = false;
    }
  }
  return true;
}

void Stepper::start(double length, double pressure) {
  state = GrowthState{};
  ws.rod.forget_hessian();
  const int edges = std::max(1, static_cast<int>(std::lround(length / h())));
  state.edges = edges;
  state.tip_length = h();
  rebuild(pressure);  // validates the vine (VineParameterError)
  state.body = straight_rod(ws.body);
  // The body as made lies straight along the base's tangent. Where that would put a node's sphere into the
  // wall by more than d̂ (a base aimed at it), the body is cut before that node and everted from there to its
  // made length as a vine grows: the tip edge lengthened by at most h/2 a step, no time passing (a barrier
  // needs a start clear of the wall; shrinking such a node's contact radius would leave it in the tissue).
  const double made = ws.body.length;
  std::size_t fit = state.body.x.size();
  for (std::size_t i = 1; i < state.body.x.size() && world() != nullptr; ++i) {
    std::array<anatomy::NearTriangle, 1> near{};
    if (!world()->contains(state.body.x[i]) ||
        (world()->triangles_within(state.body.x[i], radius(), near) > 0 && near[0].distance < radius() - model.dhat)) {
      fit = i;
      break;
    }
  }
  if (fit < state.body.x.size()) {
    state.edges = std::max(1, static_cast<int>(fit) - 1);
    rebuild(pressure);
    state.body = straight_rod(ws.body);
  }
  state.nodes.assign(state.body.x.size(), GrowthNode{});  // no contact yet (barrier_step sizes the rest)
  if (!barrier_step(0.0, pressure, 0.0)) {
    add_event(GrowthEventKind::kSolver, "initial equilibrium: " + status.failure);
    return;
  }
  state.placing = true;
  // (Placed within 1e-6 h: the edges' lengths summed leave round-off of ~1e-9 h, which a push cannot close.)
  while (ws.body.length < made - 1e-6 * h()) {
    const double before = ws.body.length;
    const double step = std::min(0.5 * h(), made - ws.body.length);
    if (!barrier_steps(1.0, pressure, step) || ws.body.length < before + 0.01 * step) {
      add_event(GrowthEventKind::kSolver,
                printf_string("initial body: %.1f of its %.1f mm everted into the lumen (%s)", 1e3 * ws.body.length,
                              1e3 * made, status.failure.empty() ? "the wall holds the tip" : status.failure.c_str()));
      break;
    }
  }
  state.placing = false;
}

void Stepper::step(const GrowthControl& control, double dt) {
  if (!(dt > 0.0) || !std::isfinite(dt)) throw InputError("vine growth: dt must be > 0");
  if (!(control.pressure >= 0.0) || !std::isfinite(control.pressure)) {
    throw InputError("vine growth: pressure must be >= 0 and finite");
  }
  state.time += dt;  // a burst vine's time runs on (a moving airway carries it by the time)
  if (state.burst) {
    status.stalled = true;
    status.burst = true;
    return;
  }
  // The step depends on the state and its inputs only: the rod solver's Hessian kept from a step before (chord
  // steps) is dropped, and a step from a checkpoint repeats bit for bit in any workspace.
  ws.rod.forget_hessian();
  const double p = control.pressure;
  const VineParameters& vine = model.vine;
  if (!model.solid() && bursts(vine, p)) {
    const double hoop = hoop_stress(vine, p);
    state.burst = true;
    status.stalled = true;
    status.burst = true;
    add_event(GrowthEventKind::kBurst,
              printf_string("pressure %.1f kPa: hoop stress %.2f MPa above the film's strength %.2f MPa", p / kKpaToPa,
                            hoop / 1e6, vine.wall_strength / 1e6));
    return;
  }
  // The pressure is this step's load: the body at it.
  rebuild(p);
  if (model.options.rod) {
    status.speed = model.options.rod->insertion_speed;  // pushed up to the tether: no pressure, no growth law
  } else {
    const GrowthLaw& law = model.options.law;
    status.magnetorheological_yield = magnetorheological_yield();
    const GrowthRate rate =
        growth_rate(law, p, ws.body.length, growth_turning(ws, state), status.magnetorheological_yield);
    status.yield = rate.yield;
    status.speed = rate.speed;
    if (status.speed == 0.0 && !state.stalled) {
      state.stalled = true;
      std::string detail =
          printf_string("pressure %.2f kPa at or below the yield %.2f kPa (Y0 %.2f + length %.2f + turning %.2f kPa",
                        p / kKpaToPa, status.yield / kKpaToPa, law.yield_pressure / kKpaToPa,
                        rate.length_term / kKpaToPa, rate.turning_term / kKpaToPa);
      if (model.options.magnetorheology) {
        detail += printf_string(" + magnetorheological %.2f kPa", status.magnetorheological_yield / kKpaToPa);
      }
      add_event(GrowthEventKind::kStall, detail + ")");
    } else if (status.speed > 0.0 && state.stalled) {
      state.stalled = false;
      add_event(GrowthEventKind::kResume,
                printf_string("pressure %.2f kPa above the yield %.2f kPa", p / kKpaToPa, status.yield / kKpaToPa));
    }
  }
  // Retraction: a tether pulled back below the everted length inverts the tip of a deflated vine.
  const GrowthOptions& o = model.options;
  if (o.retraction_pressure >= 0.0 && control.tether_length < ws.body.length - 1e-9 * h()) {
    if (p <= o.retraction_pressure) {
      state.retract_refused = false;
      const int removed = retract_to(control.tether_length);
      status.edges_removed = removed;
      if (removed > 0 && !state.retracting) {
        state.retracting = true;
        add_event(GrowthEventKind::kRetract,
                  printf_string("the tether pulls the deflated vine (%.2f kPa) back from %.1f mm", p / kKpaToPa,
                                1e3 * (ws.body.length + removed * h())));
      }
    } else if (!state.retract_refused) {
      state.retract_refused = true;
      add_event(GrowthEventKind::kRetract,
                printf_string("the tether pulls back to %.1f mm but the vine is at %.2f kPa, above the "
                              "retraction pressure %.2f kPa: the length is held",
                              1e3 * control.tether_length, p / kKpaToPa, o.retraction_pressure / kKpaToPa));
    }
  }
  const double cap = std::max(0.0, std::min(control.tether_length, o.max_length) - ws.body.length);
  const double before = ws.body.length;
  if (!barrier_steps(dt, p, cap)) {
    status.converged = false;
    status.stalled = true;
    add_event(GrowthEventKind::kSolver, "step failed: " + status.failure);
    return;
  }
  status.stalled = ws.body.length <= before;
  if (status.edges_added > 0) state.retracting = false;
}

}  // namespace

GrowthRate growth_rate(const GrowthLaw& law, double pressure, double length, double turning, double extra_yield) {
  GrowthRate r;
  r.length_term = law.length_yield * length;
  r.turning_term = law.turning_yield * turning;
  r.extra_yield = extra_yield;
  r.yield = law.yield_pressure + r.length_term + r.turning_term + r.extra_yield;
  r.speed = law.extensibility * std::max(0.0, pressure - r.yield);
  return r;
}

double growth_force(double pressure, double yield, double radius) {
  return std::max(0.0, pressure - yield) * kPi * radius * radius;
}

double film_contact_pressure(double force, double pressure, double radius, double length) {
  if (!(force > 0.0)) return 0.0;
  return std::max(pressure, force / (kPi * radius * length));
}

namespace {
/// The contact modulus E* = E/(1 − ν²) of an elastic half-space against a rigid body (Johnson 1985, §4.2).
double contact_modulus(double modulus, double poisson) {
  return modulus / (1.0 - poisson * poisson);
}
}  // namespace

double hertz_line_pressure(double line_load, double radius, double modulus, double poisson) {
  if (!(line_load > 0.0)) return 0.0;
  return std::sqrt(line_load * contact_modulus(modulus, poisson) / (kPi * radius));
}

double hertz_half_width(double line_load, double radius, double modulus, double poisson) {
  if (!(line_load > 0.0)) return 0.0;
  return std::sqrt(4.0 * line_load * radius / (kPi * contact_modulus(modulus, poisson)));
}

std::string_view growth_event_name(GrowthEventKind kind) {
  switch (kind) {
    case GrowthEventKind::kStall:
      return "stall";
    case GrowthEventKind::kResume:
      return "resume";
    case GrowthEventKind::kBlocked:
      return "blocked";
    case GrowthEventKind::kSqueeze:
      return "squeeze";
    case GrowthEventKind::kBurst:
      return "burst";
    case GrowthEventKind::kRetract:
      return "retract";
    case GrowthEventKind::kSolver:
      return "solver";
  }
  return "unknown";
}

void check_growth(const VineParameters& vine, const GrowthOptions& options, const Mat3& base_frame) {
  const auto check = [](bool ok, const char* parameter, const std::string& what) {
    if (!ok) throw VineParameterError(parameter, "vine growth: " + what);
  };
  const auto finite_non_negative = [](double x) { return x >= 0.0 && std::isfinite(x); };
  const GrowthLaw& law = options.law;
  check(finite_non_negative(law.extensibility), "extensibility", "extensibility must be finite and >= 0");
  check(finite_non_negative(law.yield_pressure), "yield_pressure", "the yield must be finite and >= 0");
  check(finite_non_negative(law.length_yield), "length_yield", "the length yield must be finite and >= 0");
  check(finite_non_negative(law.turning_yield), "turning_yield", "the turning yield must be finite and >= 0");
  check(finite_non_negative(options.friction), "friction", "friction must be finite and >= 0");
  check(finite_non_negative(options.contact_stiffness), "contact_stiffness", "contact_stiffness must be >= 0");
  check(finite_non_negative(options.edge_length), "edge_length", "edge_length must be finite and >= 0");
  check(finite_non_negative(options.contact_distance), "contact_distance", "contact_distance must be finite and >= 0");
  check(finite_non_negative(options.friction_slip), "friction_slip", "friction_slip must be finite and >= 0");
  check(options.tissue_modulus > 0.0 && std::isfinite(options.tissue_modulus), "tissue_modulus",
        "tissue_modulus must be finite and > 0");
  check(options.max_friction_iterations >= 1, "max_friction_iterations", "max_friction_iterations must be >= 1");
  check(options.friction_tolerance > 0.0 && options.friction_tolerance < 1.0, "friction_tolerance",
        "friction_tolerance must be in (0, 1)");
  check(!options.magnetorheology || vine.fill == FillKind::kMagneticFluid, "magnetorheology",
        "magnetorheology needs a magnetic-fluid fill");
  check(std::isfinite(options.retraction_pressure), "retraction_pressure", "retraction_pressure must be finite");
  check(std::isfinite(options.max_length) || options.max_length == std::numeric_limits<double>::infinity(),
        "max_length", "the made length must not be NaN");
  check(options.gravity.allFinite(), "gravity", "gravity must be finite");
  check(base_frame.allFinite() && (base_frame.transpose() * base_frame).isApprox(Mat3::Identity(), 1e-9), "base",
        "base_frame must be orthonormal");
  check(vine.radius > 0.0 && std::isfinite(vine.radius), "diameter", "radius must be > 0");
  check(vine.length > 0.0 && std::isfinite(vine.length), "length", "the starting length must be > 0");
  if (options.catheter) {
    const CatheterTube& c = *options.catheter;
    check(options.mode == InsertionMode::kPushed, "mode", "a catheter tube is pushed: set mode to pushed");
    check(c.inner_diameter >= 0.0 && c.outer_diameter > c.inner_diameter && std::isfinite(c.outer_diameter), "catheter",
          "catheter: need 0 <= inner_diameter < outer_diameter");
    check(c.modulus > 0.0 && std::isfinite(c.modulus) && finite_non_negative(c.density), "catheter",
          "catheter: modulus must be > 0 and density >= 0");
  }
  if (options.rod) {
    const PushedRod& r = *options.rod;
    check(options.mode == InsertionMode::kPushed, "mode", "a rod is pushed: set mode to pushed");
    check(!options.catheter, "catheter", "push a rod or a catheter, not both");
    check(r.radius > 0.0 && std::isfinite(r.radius), "section", "rod: radius must be > 0");
    check(r.body.length > 0.0 && r.body.edges >= 1, "length", "rod: the body needs a length and edges");
    check(finite_non_negative(r.insertion_speed), "insertion_speed", "rod: insertion_speed must be >= 0");
    check(r.body.rest_strain.empty(), "kind", "rod: a pre-curved rod is not supported in anatomy");
    check(vine.length <= r.body.length * (1.0 + 1e-9), "inserted", "rod: the inserted length exceeds the rod's length");
  }
  // The edge length and the edges it makes of the starting length.
  const double h = options.edge_length > 0.0 ? options.edge_length : made_radius(vine, options);
  check(vine.length / h <= 1e6, "edge_length", "the edges would number more than a million");
}

GrowthModel make_growth_model(const VineParameters& vine, const GrowthOptions& options,
                              const anatomy::CollisionWorld* world, const Vec3& base_position, const Mat3& base_frame) {
  check_growth(vine, options, base_frame);
  GrowthModel m;
  m.vine = vine;
  m.vine.radius = made_radius(vine, options);  // the edge length and the contacts follow a tube's or rod's radius
  m.options = options;
  m.world = world;
  m.base_position = base_position;
  m.base_frame = base_frame;
  m.edge_length = options.edge_length > 0.0 ? options.edge_length : m.vine.radius;
  m.dhat = options.contact_distance > 0.0 ? options.contact_distance : 0.02 * m.vine.radius;
  m.slip = options.friction_slip > 0.0 ? options.friction_slip : 0.01 * m.vine.radius;
  return m;
}

double everted_length(const GrowthModel& model, const GrowthState& state) {
  return (state.edges - 1) * model.edge_length + state.tip_length;
}

void growth_body(const GrowthModel& model, const GrowthState& state, double pressure, GrowthWorkspace& workspace) {
  const GrowthOptions& o = model.options;
  const double h = model.edge_length;
  VineParameters v = model.vine;
  v.pressure = pressure;  // vine_rod extends the radius (diametric extension)
  v.edges = state.edges;
  v.length = state.edges * h;
  RodModel& m = workspace.body;
  if (o.catheter) {
    const CatheterTube& c = *o.catheter;
    m = circular_tube_rod(v.length, c.outer_diameter, c.inner_diameter, c.modulus / 3.0, c.density, v.edges);
  } else if (o.rod) {
    m = inserted_part(o.rod->body, v.length, v.edges);
  } else {
    m = vine_rod(v);
  }
  // The tip edge keeps its own made length.
  m.length = everted_length(model, state);
  m.tip_edge_length = state.edges > 1 ? state.tip_length : 0.0;
  m.base_position = model.base_position;
  m.base_frame = model.base_frame;
  m.gravity = o.gravity;
  const double r = model.solid() ? model.vine.radius : extended_radius(model.vine, pressure);  // a solid: no extension
  workspace.radius = r;
  const double ei = m.bending_stiffness_3;
  // A solid rod presses the wall with its section's stiffness over an edge, E·h (E from EI = Eπr⁴/4).
  const double solid = o.rod ? 4.0 * ei / (kPi * std::pow(r, 4)) * h : 0.0;
  workspace.stiffness =
      o.contact_stiffness > 0.0
          ? o.contact_stiffness
          : std::max({50.0 * kPi * (model.solid() ? 0.0 : pressure) * r, 10.0 * ei / (h * h * h), solid});
}

double growth_turning(const GrowthWorkspace& workspace, const GrowthState& state) {
  const std::vector<double> angles = joint_angles(workspace.body, state.body);
  return std::accumulate(angles.begin(), angles.end(), 0.0);
}

GrowthStatus start_growth(const GrowthModel& model, const RodField& field, double length, double pressure,
                          GrowthState& state, GrowthWorkspace& workspace) {
  GrowthStatus status;
  Stepper{model, field, state, workspace, status}.start(length, pressure);
  return status;
}

GrowthStatus grow_step(const GrowthModel& model, const RodField& field, const GrowthControl& control,
                       GrowthState& state, GrowthWorkspace& workspace, double dt) {
  GrowthStatus status;
  if (control.tip_contact &&
      (!control.tip_contact->law || !control.tip_contact->origin.allFinite() ||
       !std::isfinite(control.tip_contact->depth) || !(std::abs(control.tip_contact->axis.norm() - 1.0) < 1e-9))) {
    throw InputError("grow_step: a tip contact needs a law, a finite origin and depth and a unit axis");
  }
  Stepper{model, field, state, workspace, status, control.tip_contact ? &*control.tip_contact : nullptr}.step(control,
                                                                                                              dt);
  return status;
}

GrowthStatus grow_step_in_pieces(const GrowthModel& model, const RodField& field, const GrowthControl& control,
                                 GrowthState& state, GrowthWorkspace& workspace, double dt,
                                 std::initializer_list<int> splits, const std::function<void(int, int)>& load_to,
                                 const std::function<void(int, int)>& reached) {
  if (splits.size() == 0 || std::any_of(splits.begin(), splits.end(), [](int n) { return n < 1; })) {
    throw InputError("grow_step_in_pieces: the splits must be one or more piece counts, each at least 1");
  }
  const GrowthState start = state;
  GrowthStatus r;
  bool first = true;
  for (const int pieces : splits) {
    if (!first) state = start;
    first = false;
    std::vector<GrowthEvent> events;
    for (int j = 1; j <= pieces; ++j) {
      load_to(j, pieces);
      r = grow_step(model, field, control, state, workspace, dt / pieces);
      events.insert(events.end(), r.events.begin(), r.events.end());
      if (!r.converged) break;
      if (reached) reached(j, pieces);
    }
    r.events = std::move(events);
    if (r.converged) break;
  }
  return r;
}

VineGrowth::VineGrowth(const VineParameters& vine, const GrowthOptions& options, const anatomy::CollisionWorld* world,
                       RodField field, const Vec3& base_position, const Mat3& base_frame)
    : m_model(make_growth_model(vine, options, world, base_position, base_frame)), m_field(std::move(field)) {
  m_events = start_growth(m_model, m_field, vine.length, vine.pressure, m_state, m_workspace).events;
}

GrowthStatus VineGrowth::advance(double dt, const GrowthControl& control) {
  GrowthStatus status = grow_step(m_model, m_field, control, m_state, m_workspace, dt);
  m_events.insert(m_events.end(), status.events.begin(), status.events.end());
  return status;
}

}  // namespace magvine::robot
