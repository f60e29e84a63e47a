#include "magvine/robot/needle.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "magvine/core/error.hpp"
#include "magvine/core/text.hpp"
#include "magvine/robot/vine.hpp"

namespace magvine::robot {

void check_needle(const NeedleTool& n) {
  const auto positive = [](double v) { return v > 0.0 && std::isfinite(v); };
  if (!positive(n.length)) throw InputError("needle: length must be > 0");
  if (!positive(n.diameter)) throw InputError("needle: diameter must be > 0");
  if (!(n.cutting_force >= 0.0 && std::isfinite(n.cutting_force))) throw InputError("needle: force must be >= 0");
  if (!(n.shaft_friction >= 0.0 && std::isfinite(n.shaft_friction))) {
    throw InputError("needle: friction must be >= 0");
  }
  if (!positive(n.max_slide)) throw InputError("needle: max_slide must be > 0");
  if (!positive(n.puncture_depth)) throw InputError("needle: puncture_depth must be > 0");
  if (!positive(n.speed)) throw InputError("needle: speed must be > 0");
  if (!positive(n.increment)) throw InputError("needle: increment must be > 0");
}

double needle_tissue_force(const NeedleTool& needle, double depth) {
  return needle_tissue_law(needle, depth).force;
}

ContactLaw needle_tissue_law(const NeedleTool& needle, double depth) {
  if (!(depth > 0.0)) return {};
  const double fc = needle.cutting_force;
  const double dp = needle.puncture_depth;
  if (depth < dp) return {0.5 * fc * depth * depth / dp, fc * depth / dp, fc / dp};
  const double past = depth - dp;
  return {0.5 * fc * dp + fc * past + 0.5 * needle.shaft_friction * past * past, fc + needle.shaft_friction * past,
          needle.shaft_friction};
}

namespace {

/// The walls' (normal and friction) force on the body [N]: the tissue forces of WallForces reversed.
Vec3 wall_on_body(const WallForces& f) {
  Vec3 total = Vec3::Zero();
  for (std::size_t i = 0; i < f.normal_vector.size(); ++i) total -= f.normal_vector[i] + f.shear_vector[i];
  return total;
}

/// From `tip` along `axis`, the distance to the wall [m] (infinity: none within `reach`).
double wall_ahead(const anatomy::CollisionWorld* world, const Vec3& tip, const Vec3& axis, double reach) {
  if (world == nullptr) return std::numeric_limits<double>::infinity();
  const std::optional<anatomy::RayHit> hit = world->ray_cast(tip, axis, reach);
  return hit ? hit->distance : std::numeric_limits<double>::infinity();
}

}  // namespace

PunctureReport push_needle(const GrowthModel& model, const RodField& field, const NeedleTool& needle,
                           const Vec3& nodule, double radius, double pressure, GrowthState& state,
                           GrowthWorkspace& workspace,
                           const std::function<void(const PunctureStep&, const GrowthState&)>& on_step) {
  check_needle(needle);
  if (!(radius > 0.0 && std::isfinite(radius))) throw InputError("needle: the nodule's radius must be > 0");
  if (!nodule.allFinite()) throw InputError("needle: the nodule's centre must be finite");
  PunctureReport out;
  const Vec3 tip0 = state.body.tip();
  const Vec3 t0 = state.body.frames.back().col(0);
  out.direction = t0;
  const double w0 = wall_ahead(model.world, tip0, t0, needle.length);
  out.wall_distance = std::isfinite(w0) ? w0 : -1.0;
  out.target_protrusion = std::min(needle.length, (nodule - tip0).dot(t0));
  out.needle_tip = tip0;
  const Vec3 wall0 = wall_on_body(state.forces);
  const Vec3 clamp0 = state.forces.clamp;
  GrowthControl control;
  control.pressure = pressure;
  control.tether_length = everted_length(model, state);  // held: the puncture grows nothing
  double p = 0.0;
  // The largest reaction a converged step held with the tip within max_slide, its protrusion, and the body's largest
  // moment over πR³P then (at the start: nothing held yet).
  double held = 0.0;
  double held_at = 0.0;
  double bent = vine_bend_state(workspace.body, state.body).largest_moment;
  const double dt = needle.increment / needle.speed;
  // The tissue ahead as the tip sees it where the step starts: the needle's tip `protrusion` past the vine's, the
  // wall along the tip's axis (a ray cast). Within the step the depth follows the tip (TipContact): a tip that backs
  // off presses less, as the tissue does (a dead load of the reaction at the start would not fall, and above what
  // the body's friction holds it had no equilibrium near: traced in a patient, Newton carried the tip 70-77 mm back).
  const auto tissue_at = [&](double protrusion) {
    TipContact c;
    c.origin = state.body.tip();
    c.axis = state.body.frames.back().col(0);
    const double ahead = wall_ahead(model.world, c.origin, c.axis, needle.length);
    c.depth = std::isfinite(ahead) ? protrusion - ahead : -needle.length;
    c.law = [&needle](double depth) { return needle_tissue_law(needle, depth); };
    return c;
  };
  // An equilibrium with the needle at `protrusion` (a whole increment's or one of its pieces'): the needle's depth
  // and the tissue's reaction there, the tip's slide back along the needle's first axis and the body's largest
  // moment; noted as held (within max_slide) and as punctured (past d_p).
  struct Equilibrium {
    double depth, force, slide, moment;
  };
  const auto reached = [&](double protrusion) {
    const double depth = tip_contact_depth(*control.tip_contact, state.body.tip());
    const Equilibrium e{depth, needle_tissue_force(needle, depth), (tip0 - state.body.tip()).dot(t0),
                        vine_bend_state(workspace.body, state.body).largest_moment};
    if (e.force > held && e.slide <= needle.max_slide) {
      held = e.force;
      held_at = protrusion;
      bent = e.moment;
    }
    out.punctured = out.punctured || depth >= needle.puncture_depth;
    return e;
  };
  while (p < out.target_protrusion) {
    const double from = p;
    p = std::min(p + needle.increment, out.target_protrusion);
    const GrowthState start = state;  // the last equilibrium (a failed grow_step leaves its time advanced)
    // An increment whose step fails (the growth step's own retries halve its time, not the needle's advance) is
    // taken again as 4, then 16 smaller advances from the last equilibrium: a quasi-static loading path.
    // Each converged piece (the whole increment's one included) is recorded once; the last is the increment's.
    const auto at = [&](int k, int pieces) { return pieces == 1 ? p : from + (p - from) * k / pieces; };
    Equilibrium e{};
    const GrowthStatus r = grow_step_in_pieces(
        model, field, control, state, workspace, dt, {1, 4, 16},
        [&](int k, int pieces) { control.tip_contact = tissue_at(at(k, pieces)); },
        [&](int k, int pieces) { e = reached(at(k, pieces)); });
    if (!r.converged) {
      state = start;
      out.held = false;
      out.why = printf_string(
          "the vine found no equilibrium with the needle at %.1f mm protrusion (it held %.2f N, its largest bending "
          "moment then %.2f of its collapse moment): %s",
          1e3 * p, held, bent, r.failure.c_str());
      break;
    }
    const double force = e.force;
    PunctureStep s;
    s.time = state.time;
    s.protrusion = p;
    s.depth = e.depth;
    s.force = force;
    s.reaction = -force * control.tip_contact->axis;  // tip_contact_force, its law evaluated once
    s.tip = state.body.tip();
    s.needle_tip = s.tip + p * state.body.frames.back().col(0);
    s.slide = e.slide;
    s.wall = wall_on_body(state.forces) - wall0;
    s.clamp = state.forces.clamp - clamp0;
    s.max_normal = state.forces.max_normal;
    s.total_normal = state.forces.total_normal;
    s.imbalance = force > 0.0 ? state.forces.imbalance.norm() / force : 0.0;
    s.unsupported = force > 0.0 ? (s.wall + s.clamp + s.reaction).norm() / force : 0.0;
    s.moment = e.moment;
    out.steps.push_back(s);
    if (on_step) on_step(s, state);
    out.needle_tip = s.needle_tip;
    out.slide = std::max(out.slide, s.slide);
    if (force > out.max_force) {
      out.max_force = force;
      out.wall_share = std::abs(s.wall.dot(s.reaction)) / (force * force);
    }
    out.max_unsupported = std::max(out.max_unsupported, s.unsupported);
    out.max_imbalance = std::max(out.max_imbalance, s.imbalance);
    out.max_normal = std::max(out.max_normal, s.max_normal);
    out.max_moment = std::max(out.max_moment, s.moment);
    if (s.slide > needle.max_slide) {
      out.held = false;
      out.why = printf_string(
          "the vine's tip slid back %.1f mm under the needle's %.2f N (limit %.1f mm; within it, it held at most "
          "%.2f N, at %.1f mm protrusion): its contacts do not hold the puncture",
          1e3 * s.slide, force, 1e3 * needle.max_slide, held, 1e3 * held_at);
      break;
    }
  }
  out.held_force = held;
  out.to_nodule = (out.needle_tip - nodule).norm();
  if (out.held && out.target_protrusion <= 0.0) {
    out.why = "the nodule lies behind the tip's direction: the needle cannot be aimed at it";
  } else if (out.held && out.to_nodule > radius) {
    out.why = printf_string("the needle's tip ends %.1f mm from the nodule's centre (radius %.1f mm)",
                            1e3 * out.to_nodule, 1e3 * radius);
  }
  out.success = out.held && out.target_protrusion > 0.0 && out.to_nodule <= radius;
  return out;
}

}  // namespace magvine::robot
