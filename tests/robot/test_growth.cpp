// Vine growth through anatomy (robot/growth.hpp): eversion without shear in a tube, the growth law's stall against
// its closed form, burst, a tip blocked by a wall, the pushed catheter's friction against the vine's, and the step
// function's state: a checkpoint is a copy, and one model serves trials in threads.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <algorithm>
#include <cstdio>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "magvine/anatomy/collision_world.hpp"
#include "magvine/anatomy/phantom.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/cylinder.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/magnetics/field_sample.hpp"
#include "magvine/robot/elastica.hpp"
#include "magvine/robot/growth.hpp"
#include "magvine/robot/inflated_beam.hpp"

namespace magvine::robot {
namespace {

/// The thesis vines (robot::thesis_skin_mvr, thesis_fluid_vine): the Ø8 mm skin MVR at 12 kPa, the Ø5 mm fluid vine
/// at 35 kPa.
VineParameters skin_mvr(double length = 8e-3) { return thesis_skin_mvr(length); }

/// A closed box [min, max] (12 triangles, outward normals): flat walls, so a body lying on its floor has one contact
/// normal (a polygonal tube's floor is a shallow V whose facets push it sideways).
anatomy::TriangleMesh box_mesh(const Vec3& lo, const Vec3& hi) {
  anatomy::TriangleMesh m;
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 2; ++i) m.vertices.emplace_back(i ? hi.x() : lo.x(), j ? hi.y() : lo.y(), k ? hi.z() : lo.z());
  const auto v = [](int i, int j, int k) { return static_cast<std::uint32_t>(i + 2 * j + 4 * k); };
  const Vec3 centre = 0.5 * (lo + hi);
  const auto quad = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t d) {
    for (anatomy::Triangle t : {anatomy::Triangle{a, b, c}, anatomy::Triangle{a, c, d}}) {
      const Vec3 n = (m.vertices[t[1]] - m.vertices[t[0]]).cross(m.vertices[t[2]] - m.vertices[t[0]]);
      if (n.dot(m.vertices[t[0]] - centre) < 0.0) std::swap(t[1], t[2]);
      m.triangles.push_back(t);
    }
  };
  for (int s = 0; s < 2; ++s) {
    quad(v(s, 0, 0), v(s, 1, 0), v(s, 1, 1), v(s, 0, 1));
    quad(v(0, s, 0), v(1, s, 0), v(1, s, 1), v(0, s, 1));
    quad(v(0, 0, s), v(1, 0, s), v(1, 1, s), v(0, 1, s));
  }
  return m;
}

VineParameters fluid_vine() { return thesis_fluid_vine(5e-3); }

/// The field of the thesis's EPM (Ø101.6 × 101.6 mm N52, J = 1.48 T, exact cylinder) centred at `centre`, its
/// magnetisation along `axis`.
RodField thesis_epm(const Vec3& centre, const Vec3& axis) {
  magnetics::FieldModel epm;
  epm.add(magnetics::CylinderMagnet(50.8e-3, 101.6e-3, Vec3(0.0, 0.0, 1.48)), magnetics::Pose::from_axis(centre, axis),
          "EPM");
  return field_function(epm, epm.rest_poses);
}

struct Tube {
  anatomy::Phantom phantom;
  anatomy::CollisionWorld world;
  explicit Tube(const anatomy::TubeParams& p) : phantom(anatomy::make_tube_phantom(p)), world(phantom.mesh) {}
};

TEST(GrowthLaw, SpeedYieldAndForceByHand) {
  // L̇ = K·max(0, P − Y), Y = Y0 + c_L·L + c_θ·Σθ (+ extra); the tip's force (P − Y)·πR² (growth.hpp).
  const GrowthLaw law{.extensibility = 2e-6, .yield_pressure = 5e3, .length_yield = 12e3, .turning_yield = 1e3};
  const GrowthRate r = growth_rate(law, 12e3, 0.1, 1.5, 0.25e3);
  EXPECT_NEAR(r.length_term, 1.2e3, 1e-9);
  EXPECT_NEAR(r.turning_term, 1.5e3, 1e-9);
  EXPECT_NEAR(r.yield, 5e3 + 1.2e3 + 1.5e3 + 0.25e3, 1e-9);
  EXPECT_NEAR(r.speed, 2e-6 * (12e3 - 7.95e3), 1e-15);  // 8.1 mm/s
  EXPECT_EQ(growth_rate(law, 7e3, 0.1, 1.5).speed, 0.0);  // at or below the yield: stalled, never negative
  EXPECT_NEAR(growth_force(35e3, 20e3, 2.5e-3), 15e3 * kPi * 2.5e-3 * 2.5e-3, 1e-12);  // 0.295 N
  EXPECT_EQ(growth_force(10e3, 20e3, 2.5e-3), 0.0);
}

TEST(ContactPressure, HertzLineContactAgreesWithItsOwnDistributionAndCurvature) {
  // Johnson (1985) §4.2: under a cylinder pressed into a half-space with line load q the pressure is elliptical,
  // p(x) = p0·√(1 − x²/b²), so it must integrate to q over [−b, b]; and the surfaces' curvature matching gives
  // p0 = b·E*/(2R) (eq. 4.45), a second route to p0 from b. q = 50 N/m, R = 2 mm, E = 0.5 MPa, ν = 0.45.
  const double q = 50.0;
  const double r = 2e-3;
  const double e = 0.5e6;
  const double p0 = hertz_line_pressure(q, r, e);
  const double b = hertz_half_width(q, r, e);
  const int n = 20000;  // midpoint rule: the √ end singularity leaves ~n^-1.5 relative error
  double integral = 0.0;
  for (int k = 0; k < n; ++k) {
    const double x = -b + (k + 0.5) * 2.0 * b / n;
    integral += p0 * std::sqrt(1.0 - x * x / (b * b)) * 2.0 * b / n;
  }
  EXPECT_NEAR(integral, q, 1e-5 * q);
  const double e_star = e / (1.0 - kTissuePoisson * kTissuePoisson);
  EXPECT_NEAR(p0, b * e_star / (2.0 * r), 1e-12 * p0);
  std::printf("  p0 %.1f kPa over 2b = %.3f mm\n", p0 / 1e3, 2e3 * b);
  EXPECT_EQ(hertz_line_pressure(0.0, r, e), 0.0);
}

TEST(ContactPressure, AFilmPressesWithItsPressureUntilItsPatchIsFull) {
  // A thin film flat on a wall carries its inflation pressure P there: a force F spreads over F/P, up to πR·ℓ.
  const double p = 35e3;
  const double r = 2.5e-3;
  const double l = 2.5e-3;
  EXPECT_EQ(film_contact_pressure(0.01, p, r, l), p);                 // a lying body's few mN: P
  EXPECT_NEAR(film_contact_pressure(2.0, p, r, l), 2.0 / (kPi * r * l), 1e-9);  // 102 kPa: the patch is full
  EXPECT_EQ(film_contact_pressure(0.0, p, r, l), 0.0);
}

TEST(Growth, FollowsTheGrowthLawToWhereTheYieldReachesThePressureAndStallsBelowIt) {
  // Free space, no gravity, straight: Y = Y0 + c_L L, so dL/dt = K (P − Y0 − c_L L) and
  // L(t) = L* − (L* − L0) e^(−K c_L t), L* = (P − Y0)/c_L = 125 mm, time constant 1/(K c_L) = 50 s. Whole edges
  // only: the length lags the closed form by less than one edge (h = 4 mm); forward Euler in time (K c_L dt =
  // 0.005) runs ahead of it by at most (K c_L dt/2)(L* − L0) max(τe^−τ) = 0.11 mm. After 8 time constants the vine sits within one edge of L*; a
  // pressure below the yield then stalls it with an event naming the yield's terms.
  GrowthOptions o;
  o.gravity = Vec3::Zero();
  o.law = {.extensibility = 1.25e-6, .yield_pressure = 4e3, .length_yield = 16e3, .turning_yield = 1e3};
  VineGrowth g(skin_mvr(), o, nullptr, {}, Vec3::Zero(), Mat3::Identity());
  const double p = 6e3;
  const double l_star = (p - 4e3) / 16e3;
  const double l0 = g.length();
  const double h = g.edge_length();
  const double rate = o.law.extensibility * o.law.length_yield;
  double worst_lag = 0.0;
  double worst_lead = 0.0;
  while (g.time() < 8.0 / rate) {
    const GrowthStatus r = g.advance(0.25, {.pressure = p});
    ASSERT_TRUE(r.converged) << r.failure;
    const double lag = l_star - (l_star - l0) * std::exp(-rate * g.time()) - g.length();
    worst_lag = std::max(worst_lag, lag);
    worst_lead = std::max(worst_lead, -lag);
  }
  std::printf("  length vs the closed form: lags by up to %.2f mm, leads by up to %.3f mm\n", 1e3 * worst_lag,
              1e3 * worst_lead);
  EXPECT_LT(worst_lag, h);
  EXPECT_LT(worst_lead, 0.15e-3);
  EXPECT_LE(g.length(), l_star + 1e-9);
  EXPECT_GT(g.length(), l_star - h);
  // The yield at this length is Y0 + c_L L (+ 0 turning): just below it nothing grows.
  const double yield = 4e3 + 16e3 * g.length();
  const double before = g.length();
  for (int i = 0; i < 40; ++i) EXPECT_TRUE(g.advance(0.25, {.pressure = yield - 10.0}).stalled);
  EXPECT_EQ(g.length(), before);
  ASSERT_FALSE(g.events().empty());
  EXPECT_EQ(g.events().back().kind, GrowthEventKind::kStall);
  std::printf("  %s\n", g.events().back().detail.c_str());
}

TEST(Growth, TetherReleaseCapsTheLength) {
  // The tether pays out at 5 mm/s, slower than the growth law would grow (~13 mm/s at 12 kPa): the length follows the
  // tether (whole edges: at most one edge behind it, never ahead), and a stopped tether stops the growth.
  GrowthOptions o;
  o.gravity = Vec3::Zero();
  VineGrowth g(skin_mvr(), o, nullptr, {}, Vec3::Zero(), Mat3::Identity());
  const double l0 = g.length();
  double worst_lag = 0.0;
  while (g.time() < 8.0) {
    const double tether = l0 + 5e-3 * (g.time() + 0.05);
    const GrowthStatus r = g.advance(0.05, {.pressure = 12e3, .tether_length = tether});
    ASSERT_TRUE(r.converged) << r.failure;
    EXPECT_GT(r.speed, 10e-3);  // the law alone would outrun the tether
    EXPECT_LE(g.length(), tether + 1e-12);
    worst_lag = std::max(worst_lag, tether - g.length());
  }
  EXPECT_LT(worst_lag, g.edge_length() + 1e-12);
  const double held = g.length();
  for (int i = 0; i < 20; ++i) g.advance(0.05, {.pressure = 12e3, .tether_length = held});
  EXPECT_EQ(g.length(), held);
}

TEST(Growth, AFieldSwitchedOnMidGrowthBendsTheBodyBeforeItGrowsOn) {
  // Free space, no gravity: the skin vine (magnetised along its body y, ⟂ to its axis) grows straight along x; a
  // uniform 20 mT field along x, switched on with set_field, exerts the distributed torque q = |m'||B| (m' the moment
  // per length), so the clamped body bends in the x–y plane by the Euler–Bernoulli y(L) = −qL³/(3EI) (its base
  // moment qL stays below the wrinkling moment, so the inflated beam is linear; 2 % for the small rotation of m and
  // the discretisation). The next step first finds that equilibrium (the loads changed), then the vine grows on.
  GrowthOptions o;
  o.gravity = Vec3::Zero();
  VineGrowth g(skin_mvr(40e-3), o, nullptr, {}, Vec3::Zero(), Mat3::Identity());
  g.set_field([](const Vec3&) {
    magnetics::FieldSample f;
    f.b = Vec3(20e-3, 0.0, 0.0);
    return f;
  });
  ASSERT_TRUE(g.advance(1e-3, {.pressure = 12e3}).converged);  // 0.013 mm of growth (the tip edge lengthens)
  const double l = g.length();
  ASSERT_NEAR(l, 40e-3 + 1e-3 * growth_rate(o.law, 12e3, 40e-3, 0.0).speed, 1e-9);
  const double q = g.model().moment_per_length[0].norm() * 20e-3;
  const double ei = g.model().bending_stiffness_3;
  const double expected = -q * l * l * l / (3.0 * ei);
  std::printf("  tip y %.4f mm, Euler-Bernoulli %.4f mm\n", 1e3 * g.state().tip().y(), 1e3 * expected);
  EXPECT_NEAR(g.state().tip().y(), expected, 0.02 * std::abs(expected));
  EXPECT_NEAR(g.state().tip().z(), 0.0, 1e-9);
  while (g.length() < l + 10e-3) ASSERT_TRUE(g.advance(0.05, {.pressure = 12e3}).converged);
  EXPECT_LT(g.state().tip().y(), 1.5 * expected);  // grown on along the bent tip and bent further
}

TEST(Growth, ABodyWithoutEquilibriumStoresNoGrowthForLater) {
  // While new loads have no equilibrium (here a field that reads NaN), the body keeps its last one and the tip does
  // not grow; the growth law's speed over that time must not be stored and paid out as several edges at once when
  // the loads are fine again (a 12 mm jump in one step did that at a generation-3 junction). Afterwards one step
  // of dt grows at most speed·dt plus the one edge that may have been due before.
  GrowthOptions o;
  o.gravity = Vec3::Zero();
  VineGrowth g(skin_mvr(40e-3), o, nullptr, {}, Vec3::Zero(), Mat3::Identity());
  const GrowthControl inflated{.pressure = 12e3};
  for (int i = 0; i < 10; ++i) ASSERT_TRUE(g.advance(0.02, inflated).converged);
  g.set_field([](const Vec3&) {
    magnetics::FieldSample f;
    f.b = Vec3::Constant(std::nan(""));
    return f;
  });
  const double held = g.length();
  GrowthStatus r;
  for (int i = 0; i < 50; ++i) r = g.advance(0.02, inflated);  // 1 s without equilibrium
  EXPECT_FALSE(r.converged);
  EXPECT_EQ(g.length(), held);
  g.set_field({});
  r = g.advance(0.02, inflated);
  ASSERT_TRUE(r.converged) << r.failure;
  const double grown = g.length() - held;
  std::printf("  without equilibrium for 1 s, then %.1f mm in one 0.02 s step (speed %.1f mm/s, edge %.1f mm)\n",
              1e3 * grown, 1e3 * r.speed, 1e3 * g.edge_length());
  EXPECT_LE(grown, r.speed * 0.02 + g.edge_length() + 1e-12);
}

TEST(Growth, BurstsWhenTheHoopStressPassesTheFilmStrength) {
  // Hoop stress P R(1 + ε) / t: the 20 µm film at 10 MPa bursts above 47.7 kPa (46.2 kPa without the extension).
  GrowthOptions o;
  VineGrowth g(skin_mvr(), o, nullptr, {}, Vec3::Zero(), Mat3::Identity());
  EXPECT_FALSE(g.advance(0.1, {.pressure = 47e3}).burst);
  const double before = g.length();
  const GrowthStatus r = g.advance(0.1, {.pressure = 48.5e3});
  EXPECT_TRUE(r.burst);
  EXPECT_TRUE(g.burst());
  EXPECT_EQ(g.events().back().kind, GrowthEventKind::kBurst);
  EXPECT_TRUE(g.advance(1.0, {.pressure = 12e3}).stalled);  // a burst vine grows no more
  EXPECT_EQ(g.length(), before);
  // burst_pressure (what a scene's boost_pressure is checked against) is the same threshold: the hoop stress with
  // the extension equals the strength there to round-off, and the growth bursts just above it, not just below.
  const double p = burst_pressure(skin_mvr());
  std::printf("  burst pressure %.2f kPa\n", p / 1e3);
  EXPECT_NEAR(p * extended_radius(skin_mvr(), p) / skin_mvr().wall.thickness, skin_mvr().wall_strength,
              1e-12 * skin_mvr().wall_strength);
  EXPECT_GT(p, 47e3);
  EXPECT_LT(p, 48.5e3);
  // The one criterion (vine.hpp): bursts ⟺ P > burst_pressure, and hoop_stress includes the extension.
  EXPECT_FALSE(bursts(skin_mvr(), 0.999 * p));
  EXPECT_TRUE(bursts(skin_mvr(), 1.001 * p));
  EXPECT_NEAR(hoop_stress(skin_mvr(), p), skin_mvr().wall_strength, 1e-12 * skin_mvr().wall_strength);
  VineGrowth below(skin_mvr(), o, nullptr, {}, Vec3::Zero(), Mat3::Identity());
  EXPECT_FALSE(below.advance(0.1, {.pressure = 0.999 * p}).burst);
  VineGrowth above(skin_mvr(), o, nullptr, {}, Vec3::Zero(), Mat3::Identity());
  EXPECT_TRUE(above.advance(0.1, {.pressure = 1.001 * p}).burst);
}

/// Grows the Ø8 mm vine (or pushes it, `mode`) to 100 mm along the floor of a square channel, gravity pulling it
/// down; returns the largest drift of a node after it first touched the wall and the summed wall forces.
struct FloorRun {
  double drift = 0.0;
  double normal = 0.0;
  double shear = 0.0;
  int contacts = 0;
};
FloorRun grow_along_floor(InsertionMode mode) {
  // A 12 mm square channel, floor at z = −5 mm.
  const anatomy::CollisionWorld channel(box_mesh(Vec3(0.0, -6e-3, -5e-3), Vec3(0.12, 6e-3, 7e-3)));
  GrowthOptions o;
  o.mode = mode;
  const VineParameters v = skin_mvr();
  // The base rests on the floor: centre R(1 + ε) above it (ε the hoop strain at 12 kPa), plus the barrier's
  // activation distance d̂ = 2 % R (closer, the barrier would fight the clamp).
  const double radius = v.radius * (1.0 + v.pressure * v.radius / (v.wall.thickness * v.wall.modulus));
  VineGrowth g(v, o, &channel, {}, Vec3(2e-3, 0.0, radius + 0.02 * v.radius - 5e-3), Mat3::Identity());
  FloorRun out;
  std::vector<Vec3> first_touch;
  while (g.length() < 100e-3) {
    const GrowthStatus r = g.advance(0.05, {.pressure = 12e3});
    EXPECT_TRUE(r.converged) << r.failure;
    if (!r.converged || g.time() > 100.0) break;
    const WallForces& f = g.wall_forces();
    first_touch.resize(g.state().x.size(), Vec3::Constant(std::nan("")));
    // Everted material: every node but the tip (which advances, and leaves a new node behind it as it goes).
    for (std::size_t i = 1; i + 1 < g.state().x.size(); ++i) {
      if (f.normal[i] <= 0.0) continue;
      if (std::isnan(first_touch[i].x())) first_touch[i] = g.state().x[i];
      out.drift = std::max(out.drift, (g.state().x[i] - first_touch[i]).norm());
    }
    out.normal += f.total_normal;
    out.shear += f.total_shear;
    for (const Vec3& x : g.state().x) EXPECT_TRUE(channel.contains(x)) << "a node left the lumen";
  }
  out.contacts = g.wall_forces().nodes_in_contact;
  EXPECT_NEAR(g.length(), 100e-3, g.edge_length());
  return out;
}

TEST(Growth, EvertedNodesStayPutOnATubeFloorWhileTheTipAdvancesAndTheCatheterSlides) {
  // Eversion: every node, once it touches the wall, stays where it touched (no sliding: PHYSICS.md §3; static
  // friction holds it within the slip ε = 1 % R; asserted: within 1 % of ε) and the wall shear vanishes against
  // the normal force (the floor is flat: nothing loads the friction but the creep below ε). Pushed: the same body
  // slides, so every node in contact carries kinetic friction μ·F_n (μ = 0.3), to the lag's tolerance (the
  // friction is computed from the normal force of the solve before the last, which the last moved by at most
  // friction_tolerance of the total).
  // Re-measured with the barrier model (issue 28): the planes model's anchors gave a drift below 1e-6 mm and
  // μ exactly; the barrier gives 6e-5 mm and 0.3000002.
  const FloorRun vine = grow_along_floor(InsertionMode::kEversion);
  const FloorRun pushed = grow_along_floor(InsertionMode::kPushed);
  std::printf("  vine: %d nodes on the floor, largest drift after touching %.3g mm, shear/normal %.3g\n",
              vine.contacts, 1e3 * vine.drift, vine.shear / vine.normal);
  std::printf("  pushed: %d nodes on the floor, shear/normal %.9f\n", pushed.contacts, pushed.shear / pushed.normal);
  EXPECT_GT(vine.contacts, 20);
  EXPECT_LT(vine.drift, 1e-2 * 0.01 * skin_mvr().radius);
  EXPECT_LT(vine.shear, 1e-3 * vine.normal);
  EXPECT_NEAR(pushed.shear / pushed.normal, 0.3, 0.3 * GrowthOptions{}.friction_tolerance);
}

TEST(Growth, TipGrowingIntoTheEndWallIsBlockedAndNeverTunnels) {
  // The tube's capped far end stops the tip head-on: growth must stall with a "blocked" event, the body stay inside
  // the lumen, and the Newton iterations stay bounded.
  anatomy::TubeParams tp;
  tp.diameter = 10e-3;
  tp.length = 60e-3;
  const Tube tube(tp);
  GrowthOptions o;
  VineGrowth g(skin_mvr(), o, &tube.world, {}, Vec3(2e-3, 0.0, 0.0), Mat3::Identity());
  int most_iterations = 0;
  for (int step = 0; step < 200; ++step) {
    const GrowthStatus r = g.advance(0.05, {.pressure = 12e3});
    ASSERT_TRUE(r.converged) << r.failure;
    most_iterations = std::max(most_iterations, r.newton_iterations);
    for (const Vec3& x : g.state().x) {
      ASSERT_TRUE(tube.world.contains(x)) << "a node left the lumen at " << 1e3 * x.transpose() << " mm, step " << step
                                          << ", length " << 1e3 * g.length();
    }
  }
  bool blocked = false;
  for (const GrowthEvent& e : g.events()) {
    std::printf("  event at %.1f mm: %s: %s\n", 1e3 * e.length, std::string(growth_event_name(e.kind)).c_str(), e.detail.c_str());
    blocked = blocked || e.kind == GrowthEventKind::kBlocked;
  }
  std::printf("  stopped at %.1f mm, tip x %.1f mm (end wall at 60 mm); most Newton iterations in a step %d\n",
              1e3 * g.length(), 1e3 * g.state().tip().x(), most_iterations);
  EXPECT_TRUE(blocked);
  EXPECT_LT(g.state().tip().x(), tp.length);
  EXPECT_GT(g.state().tip().x(), tp.length - g.radius() - g.edge_length());
  EXPECT_LT(most_iterations, 500);
}

/// Grows the fluid vine (Ø5 mm, 35 kPa, Y0 = 20 kPa, no gravity) at `heading` to the x axis towards the side wall
/// y = 15 mm of a 30 mm wide channel with edges of `edge`; returns how far [m] the tip got along x past where it
/// first touched that wall, and whether growth was blocked.
std::pair<double, bool> slide_along_side_wall(double heading, double edge) {
  const anatomy::CollisionWorld channel(box_mesh(Vec3(0.0, -15e-3, -8e-3), Vec3(0.14, 15e-3, 8e-3)));
  GrowthOptions o;
  o.gravity = Vec3::Zero();
  o.law.yield_pressure = 20e3;
  o.edge_length = edge;
  VineGrowth g(fluid_vine(), o, &channel, {}, Vec3(2e-3, -12e-3, 0.0),
               Eigen::AngleAxisd(heading, Vec3::UnitZ()).toRotationMatrix());
  double touched = -1.0;
  while (g.time() < 10.0 && g.state().tip().x() < 0.12) {
    const GrowthStatus r = g.advance(0.02, {.pressure = 35e3});
    EXPECT_TRUE(r.converged) << r.failure;
    if (!r.converged) break;
    if (touched < 0.0 && g.state().tip().y() > 15e-3 - g.radius() - 0.2e-3) touched = g.state().tip().x();
  }
  bool blocked = false;
  for (const GrowthEvent& e : g.events()) {
    std::printf("    %.1f mm: %s: %s\n", 1e3 * e.length, std::string(growth_event_name(e.kind)).c_str(), e.detail.c_str());
    blocked = blocked || e.kind == GrowthEventKind::kBlocked;
  }
  for (const Vec3& x : g.state().x) EXPECT_TRUE(channel.contains(x)) << "a node left the channel";
  return {touched < 0.0 ? 0.0 : g.state().tip().x() - touched, blocked};
}

TEST(Growth, WhetherATipTurnsAlongAWallDoesNotDependOnTheEdgeLength) {
  // A tip meeting a flat wall below the friction limit (73°) turns along it: the body, free to swing, bends over
  // its length (the crease, if any, forms where the wall's push has the lever arm for it, M_c·tan α/F behind the
  // tip) and the growth force pays for that turn over the growth it takes. At 30° and 60° the tip must slide on to
  // the channel's end, and how far it gets must not depend on the edge length (R and R/2) beyond one long edge.
  for (const double degrees : {30.0, 60.0}) {
    double first = 0.0;
    for (const double edge : {2.5e-3, 1.25e-3}) {
      std::printf("  h = %.2f mm, heading %.0f deg:\n", 1e3 * edge, degrees);
      const auto [slid, blocked] = slide_along_side_wall(degrees * kDegToRad, edge);
      std::printf("  slid %.1f mm along the wall, %s\n", 1e3 * slid, blocked ? "blocked" : "not blocked");
      EXPECT_FALSE(blocked) << "h " << edge << ", " << degrees << " deg";
      EXPECT_GT(slid, 40e-3) << "h " << edge << ", " << degrees << " deg";
      if (first == 0.0) first = slid;
      EXPECT_NEAR(slid, first, 2.5e-3) << "h " << edge << ", " << degrees << " deg";
    }
  }
}

TEST(Growth, ATipMeetingACarinaHeadOnRollsOffIntoADaughterButAFlatWallHoldsIt) {
  // The Y bifurcation (parent Ø12 mm, daughters Ø9.5 mm at ±35°, rounded carina), the fluid vine grown along the
  // parent's axis with no load across it, 0.2 mm to one side: it meets the carina's crest at ~80°, steeper than the
  // friction limit (73°). A flat wall met that steeply holds the tip (friction), but on a convex crest the pushed,
  // rounded tip is unstable and rolls off: it must grow into a daughter, every node in the lumen. (The head-on end
  // wall of TipGrowingIntoTheEndWallIsBlockedAndNeverTunnels, flat, and a blind end, concave, still block.)
  const anatomy::Phantom y = anatomy::make_y_bifurcation({});
  const anatomy::CollisionWorld world(y.mesh);
  for (const double side : {1.0, -1.0}) {
    GrowthOptions o;
    o.gravity = Vec3::Zero();
    o.law.yield_pressure = 20e3;
    VineGrowth g(fluid_vine(), o, &world, {}, Vec3(2e-3, 0.2e-3 * side, 0.0), Mat3::Identity());
    while (g.length() < 100e-3 && g.time() < 20.0) {
      const GrowthStatus r = g.advance(0.02, {.pressure = 35e3});
      ASSERT_TRUE(r.converged) << r.failure;
    }
    const Vec3 tip = g.state().tip();
    std::printf("  side %+.0f: %.1f mm grown in %.2f s, tip (%.1f, %.1f, %.1f) mm\n", side, 1e3 * g.length(), g.time(),
                1e3 * tip.x(), 1e3 * tip.y(), 1e3 * tip.z());
    for (const GrowthEvent& e : g.events()) {
      std::printf("    %.2f s %s: %s\n", e.time, std::string(growth_event_name(e.kind)).c_str(), e.detail.c_str());
    }
    for (const Vec3& x : g.state().x) EXPECT_TRUE(world.contains(x)) << "a node left the lumen";
    EXPECT_NEAR(g.length(), 100e-3, g.edge_length());
    EXPECT_GT(std::abs(tip.y()), 10e-3);  // in a daughter (their axes: y = ±(x − 66 mm)·tan 35°)
  }
}

TEST(Growth, VineConformsIntoTheDaughterItLeansTowards) {
  // The Y bifurcation (parent Ø12 mm, daughters Ø9.5 mm at ±35°): a fluid vine started against one side wall, its
  // weight pulling it that way (gravity across the parent), slides along the wall into that side's daughter; mirrored,
  // into the other. Every node stays in the lumen; the Newton work stays bounded.
  const anatomy::Phantom y = anatomy::make_y_bifurcation({});
  const anatomy::CollisionWorld world(y.mesh);
  for (const double side : {1.0, -1.0}) {
    GrowthOptions o;
    o.gravity = Vec3(0.0, 9.81 * side, 0.0);
    o.law.yield_pressure = 20e3;
    VineGrowth g(fluid_vine(), o, &world, {}, Vec3(2e-3, 3e-3 * side, 0.0), Mat3::Identity());
    int newton = 0;
    while (g.length() < 100e-3 && g.time() < 20.0) {
      const GrowthStatus r = g.advance(0.02, {.pressure = 35e3});
      ASSERT_TRUE(r.converged) << r.failure;
      newton += r.newton_iterations;
    }
    for (const Vec3& x : g.state().x) EXPECT_TRUE(world.contains(x)) << "a node left the lumen";
    const Vec3 tip = g.state().tip();
    std::printf("  side %+.0f: %.1f mm grown in %.2f s, tip (%.1f, %.1f, %.1f) mm, %d Newton iterations, %d nodes on "
                "the wall\n",
                side, 1e3 * g.length(), g.time(), 1e3 * tip.x(), 1e3 * tip.y(), 1e3 * tip.z(), newton,
                g.wall_forces().nodes_in_contact);
    for (const GrowthEvent& e : g.events()) std::printf("    %.2f s %s: %s\n", e.time, std::string(growth_event_name(e.kind)).c_str(), e.detail.c_str());
    EXPECT_NEAR(g.length(), 100e-3, g.edge_length());
    EXPECT_GT(side * tip.y(), 10e-3);  // well inside the daughter (its axis: y = (x − 66 mm)·tan 35°)
    EXPECT_LT(newton, 5000);
  }
}

TEST(Growth, BodyStartedDeepInTheWallIsPushedBackAndGrowsOn) {
  // Deep penetration: the initial 20 mm body points 10° down into the floor of the square channel, its tip 3.5 mm
  // into it. The first equilibrium must push it back into the lumen, and growth then goes on along the floor.
  // (Barrier model, issue 28: the body as made is cut where it enters the wall and everted from there.)
  const anatomy::CollisionWorld channel(box_mesh(Vec3(0.0, -6e-3, -5e-3), Vec3(0.12, 6e-3, 7e-3)));
  VineParameters v = skin_mvr(20e-3);
  const double radius = v.radius * (1.0 + v.pressure * v.radius / (v.wall.thickness * v.wall.modulus));
  const double tilt = 10.0 * kDegToRad;
  const Mat3 frame = Eigen::AngleAxisd(tilt, Vec3::UnitY()).toRotationMatrix();  // tangent (cos, 0, −sin)
  GrowthOptions o;
  VineGrowth g(v, o, &channel, {}, Vec3(2e-3, 0.0, radius - 5e-3), frame);
  for (const Vec3& x : g.state().x) EXPECT_TRUE(channel.contains(x)) << "not pushed back";
  double deepest = 0.0;
  for (const Vec3& x : g.state().x) deepest = std::max(deepest, -5e-3 - (x.z() - radius));
  std::printf("  after the first equilibrium the deepest node is %.3f mm into the floor (was 3.5 mm)\n",
              1e3 * deepest);
  EXPECT_LT(deepest, 0.05 * radius);
  while (g.length() < 60e-3 && g.time() < 20.0) ASSERT_TRUE(g.advance(0.05, {.pressure = 12e3}).converged);
  for (const Vec3& x : g.state().x) EXPECT_TRUE(channel.contains(x));
  EXPECT_NEAR(g.length(), 60e-3, g.edge_length());
}

TEST(Growth, GrazingASideWallIntoACornerSlidesThenBlocksWithoutTunnelling) {
  // Sharp edges: the vine heads 20° off the channel's axis, meets the side wall at a shallow angle (it must slide
  // along it), and ends in the corner between that wall and the channel's end (two walls at 90°, a sharp edge).
  // The fluid vine (soft enough for the wall to turn it with less than its growth force).
  // Re-measured with the barrier model (issue 28): the tip slides along the side wall to the end wall (y = 2.86 mm
  // from x = 10 to 57 mm), and there the growth force, 0.40 N, now pressing the end wall, compresses the 55 mm
  // body beyond its Euler load (~0.1 N); it buckles, and its tip, whose friction on the end wall starts with the
  // step after it first touches (lagged), crosses to the other corner, where the wall holds it. The planes model
  // stopped the tip by its incidence rule before the body carried the growth force.
  const anatomy::CollisionWorld channel(box_mesh(Vec3(0.0, -6e-3, -5e-3), Vec3(0.06, 6e-3, 7e-3)));
  VineParameters v = fluid_vine();
  const double radius = v.radius * (1.0 + v.pressure * v.radius / (v.wall.thickness * v.wall.modulus));
  const Mat3 frame = Eigen::AngleAxisd(20.0 * kDegToRad, Vec3::UnitZ()).toRotationMatrix();
  GrowthOptions o;
  o.law.yield_pressure = 20e3;
  VineGrowth g(v, o, &channel, {}, Vec3(2e-3, 0.0, radius - 5e-3), frame);
  int most = 0;
  for (int step = 0; step < 200; ++step) {
    const GrowthStatus r = g.advance(0.02, {.pressure = 35e3});
    ASSERT_TRUE(r.converged) << r.failure;
    most = std::max(most, r.newton_iterations);
    for (const Vec3& x : g.state().x) ASSERT_TRUE(channel.contains(x)) << "a node left the channel, step " << step;
  }
  bool blocked = false;
  for (const GrowthEvent& e : g.events()) {
    std::printf("  event at %.1f mm: %s: %s\n", 1e3 * e.length, std::string(growth_event_name(e.kind)).c_str(), e.detail.c_str());
    blocked = blocked || e.kind == GrowthEventKind::kBlocked;
  }
  const Vec3 tip = g.state().tip();
  std::printf("  tip (%.1f, %.1f) mm after %.1f mm, most Newton iterations in a step %d\n", 1e3 * tip.x(),
              1e3 * tip.y(), 1e3 * g.length(), most);
  EXPECT_TRUE(blocked);
  EXPECT_GT(std::abs(tip.y()), 6e-3 - radius - 0.5e-3);  // in a corner
  EXPECT_GT(tip.x(), 0.06 - radius - g.edge_length());  // at the end wall
  EXPECT_LE(most, 2000);
}

/// Grows `v` at `pressure` through the constriction phantom (Ø12 mm tube, jaws 25 mm long at x = 50 mm) with a
/// slot of `gap`; returns whether the tip got past the jaws (x > 75 mm), and prints the events.
/// Grows (or pushes) a body from a clamp at base_x along the axis of the thesis's constriction (growth.hpp:
/// a Ø12 mm tube squeezed to a slot `gap` wide over 25 mm, x = 37.5–62.5 mm) until its tip is 80 mm in or 15 s
/// have passed, and records the largest sums of the normal and shear forces on the nodes in the slot.
struct SlotRun {
  bool passed = false;
  double normal = 0.0;  ///< largest sum over the slot's nodes [N] (both jaws)
  double shear = 0.0;   ///< [N] (both jaws)
  double node = 0.0;    ///< the largest force on one node over the run [N]
};
SlotRun grow_through_slot(const VineParameters& v, double pressure, double gap, const GrowthOptions& o,
                          double base_x = 2e-3) {
  anatomy::ConstrictionParams cp;
  cp.gap = gap;
  const anatomy::Phantom ph = anatomy::make_constriction(cp);
  const anatomy::CollisionWorld world(ph.mesh);
  VineGrowth g(v, o, &world, {}, Vec3(base_x, 0.0, 0.0), Mat3::Identity());
  SlotRun out;
  while (g.state().tip().x() < 80e-3 && g.time() < 15.0) {
    const GrowthStatus r = g.advance(0.02, {.pressure = pressure});
    EXPECT_TRUE(r.converged) << r.failure;
    double normal = 0.0;
    double shear = 0.0;
    for (std::size_t i = 0; i < g.state().x.size(); ++i) {
      if (std::abs(g.state().x[i].x() - cp.constriction_x) < 0.5 * cp.constriction_length) {
        normal += g.wall_forces().normal[i];
        shear += g.wall_forces().shear[i];
      }
    }
    out.normal = std::max(out.normal, normal);
    out.shear = std::max(out.shear, shear);
    out.node = std::max(out.node, g.wall_forces().max_normal);
    for (const Vec3& x : g.state().x) EXPECT_TRUE(world.contains(x)) << "a node left the lumen";
  }
  out.passed = g.state().tip().x() > cp.constriction_x + 0.5 * cp.constriction_length;
  std::printf("  %s Ø%.0f mm at %.0f kPa, %.1f mm gap: %s (tip x %.1f mm); in the slot at most %.3g N normal, "
              "%.3g N shear (both jaws)\n",
              o.catheter ? "pushed tube" : (o.mode == InsertionMode::kPushed ? "pushed vine" : "vine"),
              o.catheter ? 1e3 * o.catheter->outer_diameter : 2e3 * v.radius, pressure / 1e3, 1e3 * gap,
              out.passed ? "passes" : "stopped", 1e3 * g.state().tip().x(), out.normal, out.shear);
  for (const GrowthEvent& e : g.events()) std::printf("    %s: %s\n", std::string(growth_event_name(e.kind)).c_str(), e.detail.c_str());
  return out;
}

bool passes_constriction(const VineParameters& v, double pressure, double gap, const GrowthOptions& o) {
  return grow_through_slot(v, pressure, gap, o).passed;
}

TEST(Growth, SqueezesThroughTheThesisConstrictionsAndStopsWhereItDid) {
  // Thesis 4.7.2: the Ø8 mm skin MVR at 12 kPa passes 5 mm and 3 mm gaps but not 2 mm; thesis 5.6.2: the Ø5 mm
  // fluid vine passes 2.5 mm. The model: the section flattens at constant perimeter and the tip is driven over
  // the flattened area only (growth.hpp). Fitted: the skin vine's yield Y0 = 5 kPa (the default), the one
  // constant that sets its threshold; the fluid vine's Y0 = 15 kPa is an assumption (thesis: it grows at 35 kPa).
  const GrowthOptions skin;
  EXPECT_TRUE(passes_constriction(skin_mvr(), 12e3, 5e-3, skin));
  EXPECT_TRUE(passes_constriction(skin_mvr(), 12e3, 3e-3, skin));
  EXPECT_FALSE(passes_constriction(skin_mvr(), 12e3, 2e-3, skin));
  GrowthOptions fluid;
  fluid.law.yield_pressure = 15e3;
  EXPECT_TRUE(passes_constriction(fluid_vine(), 35e3, 2.5e-3, fluid));
  EXPECT_TRUE(passes_constriction(fluid_vine(), 35e3, 3e-3, fluid));  // once stuck: Newton stalled at round-off
}

TEST(Growth, ThroughAThreeMillimetreGapTheVineShearsTheJawsFarLessThanAPushedTube) {
  // Thesis 5.6.2: a Ø4 mm fluid vine grown at 35 kPa through a 3 mm × 25 mm gap vs a TPU tube (OD 4, ID 3 mm)
  // pushed through it: peak shear 10.3 mN vs 1.04 N, peak normal 2.87 N vs 7.88 N (on the load-cell jaw). Both
  // start from a clamp 7.5 mm before the jaws (a rig's guide: from farther back the vine's sagging span enters
  // the gap bent, and the jaws' friction carries its moment; the tube buckles in the Ø12 mm lumen). The vine's
  // normal force is its pressure on the flattened strips; the tube's, its ring's crushing (CatheterTube, E 26 MPa
  // assumed); its shear μ·F_n with μ = 0.3 (assumed; the thesis's 1.04/7.88 implies 0.13). Measured 2026-12-02:
  // per jaw the vine 2.48 N normal and 30 mN shear, the tube 8.83 N and 2.65 N, a shear ratio of 88. (Before the
  // contact radii were lagged within the step, the tube entered the jaws with its round radius for one step and
  // read 45.3 N per jaw.)
  VineParameters vine = fluid_vine();
  vine.radius = 2e-3;
  GrowthOptions o;
  o.law.yield_pressure = 15e3;
  const SlotRun grown = grow_through_slot(vine, 35e3, 3e-3, o, 30e-3);
  o.mode = InsertionMode::kPushed;
  o.catheter = CatheterTube{};
  const SlotRun pushed = grow_through_slot(vine, 35e3, 3e-3, o, 30e-3);
  std::printf("  per jaw, simulated vs thesis: vine normal %.2f vs 2.87 N, shear %.1f vs 10.3 mN; tube normal %.2f vs "
              "7.88 N, shear %.2f vs 1.04 N; shear ratio %.0f (thesis 101)\n",
              0.5 * grown.normal, 0.5e3 * grown.shear, 0.5 * pushed.normal, 0.5 * pushed.shear,
              pushed.shear / grown.shear);
  EXPECT_TRUE(grown.passed);
  EXPECT_TRUE(pushed.passed);
  EXPECT_GE(pushed.shear, 10.0 * grown.shear);  // the acceptance: a ratio of at least 10
  EXPECT_LT(grown.normal, pushed.normal);
  // In the slot a node of the tube carries its ring's crushing on the two jaws and nothing more: Roark's thin ring
  // pinched across a diameter, δ = 0.149·q·r³/(E·t³/12) per unit length, with δ = D − g, over the node's edge h
  // on each jaw. Bound 10 %: the jaws' entry corners add a few per cent as the tube slides in (1.7 % measured);
  // the round radius of a step's start, kept while the tube slid into the jaws, gave 65 times the ring's load.
  const CatheterTube tube;
  const double t = 0.5 * (tube.outer_diameter - tube.inner_diameter);
  const double r_mean = 0.25 * (tube.outer_diameter + tube.inner_diameter);
  const double q = (tube.outer_diameter - 3e-3) * tube.modulus * t * t * t / (12.0 * 0.149 * std::pow(r_mean, 3));
  const double ring = 2.0 * q * 0.5 * tube.outer_diameter;  // h = the tube's radius (the default edge length)
  std::printf("  the tube's largest node force %.3f N, its ring's load on a node %.3f N\n", pushed.node, ring);
  EXPECT_LE(pushed.node, 1.1 * ring);
}

TEST(Growth, ADeflatedVineLyingInTheSBendBendsTowardsAMagnetBroughtClose) {
  // The skin vine grown 68 mm along the S-bend phantom's floor (past the first obstacle's end), then deflated to
  // 1 kPa as the thesis's EPM (Ø101.6 mm N52) is brought beside the channel, its axis vertical so its field at the
  // body lies along the skin's magnetisation (gradient mode, thesis 4.7.3): the full load at once does not converge
  // from the inflated equilibrium, so the step ramps it up from there. The body wrinkles to its collapse and its
  // free part swings towards the magnet and over the obstacle; no node leaves the lumen. (Re-measured with the
  // barrier model, issue 28: its largest joint moment is 0.99 of the collapse moment πR³P, on the wrinkled
  // plateau just short of the crease; the planes model's anchors held the body so that one joint passed it.)
  const anatomy::Phantom ph = anatomy::make_s_bend({});
  const anatomy::CollisionWorld world(ph.mesh);
  Mat3 frame;  // tangent +x, the skin's magnetisation (body y) vertical
  frame.col(0) = Vec3::UnitX();
  frame.col(1) = Vec3::UnitZ();
  frame.col(2) = -Vec3::UnitY();
  const VineParameters v = skin_mvr();
  const double radius = v.radius * (1.0 + v.pressure * v.radius / (v.wall.thickness * v.wall.modulus));
  VineGrowth g(v, {}, &world, {}, Vec3(2e-3, 14e-3, -10e-3 + radius), frame);
  while (g.time() < 8.0) ASSERT_TRUE(g.advance(0.1, {.pressure = 12e3, .tether_length = 70e-3}).converged);
  const Vec3 before = g.state().tip();
  g.set_field(thesis_epm(Vec3(85e-3, -85e-3, 0.0), -Vec3::UnitZ()));
  const GrowthStatus r = g.advance(0.1, {.pressure = 1e3, .tether_length = 70e-3});
  ASSERT_TRUE(r.converged) << r.failure;
  const Vec3 after = g.state().tip();
  double largest = 0.0;
  for (const double m : joint_bending_moments(g.model(), g.state())) largest = std::max(largest, std::abs(m));
  const double collapse = collapse_moment(g.model().inflated->radius, g.model().inflated->pressure);
  std::printf("  tip (%.1f, %.1f) mm -> (%.1f, %.1f) mm, %d Newton iterations, largest joint moment %.3f of the "
              "collapse moment\n", 1e3 * before.x(), 1e3 * before.y(), 1e3 * after.x(), 1e3 * after.y(),
              r.newton_iterations, largest / collapse);
  EXPECT_NEAR(before.y(), 14e-3, 0.5e-3);
  EXPECT_LT(after.y(), before.y() - 5e-3);  // towards the magnet (−y)
  EXPECT_GT(largest, 0.95 * collapse);  // wrinkled to (nearly) all of its section: the hinge it swings about
  for (const Vec3& x : g.state().x) EXPECT_TRUE(world.contains(x)) << "a node left the lumen";
}

TEST(Growth, MagnetorheologicalStiffeningStallsTheFluidVineAtTheBinghamLength) {
  // GrowthOptions::magnetorheology: a uniform 20 mT field along the fluid vine (free space, no gravity: the fill's
  // induced moment lies along the body, so nothing bends) adds ΔP = 2τ_y·L/R to the yield, so growth stalls where
  // P = Y0 + (c_L + 2τ_y/R)·L: L* = (P − Y0)/(c_L + 2τ_y/R), 16 mm here instead of 1.7 m without it. Tolerance one
  // edge (growth is by whole edges).
  GrowthOptions o;
  o.gravity = Vec3::Zero();
  o.law.yield_pressure = 15e3;
  o.magnetorheology = true;
  const double b = 20e-3;
  VineGrowth g(fluid_vine(), o, nullptr, [b](const Vec3&) {
    magnetics::FieldSample f;
    f.b = Vec3(b, 0.0, 0.0);
    return f;
  }, Vec3::Zero(), Mat3::Identity());
  for (int i = 0; i < 400; ++i) ASSERT_TRUE(g.advance(0.05, {.pressure = 35e3}).converged);
  const double tau = magnetics::magnetorheological_yield_stress(b / kMu0, fluid_vine().volume_fraction);
  const double expected = (35e3 - 15e3) / (o.law.length_yield + 2.0 * tau / g.radius());
  std::printf("  tau_y %.0f Pa at %.0f mT; stalled at %.2f mm, Bingham length %.2f mm\n", tau, 1e3 * b,
              1e3 * g.length(), 1e3 * expected);
  EXPECT_NEAR(g.length(), expected, g.edge_length());
  ASSERT_FALSE(g.events().empty());
  EXPECT_EQ(g.events().back().kind, GrowthEventKind::kStall);
  EXPECT_NE(g.events().back().detail.find("magnetorheological"), std::string::npos);
}

TEST(Growth, TheStiffenedFluidResumesGrowingWhenTheMagnetIsWithdrawn) {
  // Thesis 5.6.4: near the EPM the magnetorheological fluid stiffened and growth stopped; withdrawing the magnet let
  // it grow. The fluid vine grows along x in free space towards the thesis's EPM on its axis, the magnet's face
  // 29 mm beyond the tip (its field along the body: the fill's induced moment too, so the body stays straight,
  // pulled along its axis). (Re-measured with the barrier model, issue 28: the magnet used to sit 80 mm to the
  // side, where the body has no equilibrium in free space; the planes model kept the straight body and reported
  // the failed solve as an event, the barrier model ends the run.)
  GrowthOptions o;
  o.gravity = Vec3::Zero();
  o.law.yield_pressure = 15e3;
  o.magnetorheology = true;
  VineGrowth g(thesis_fluid_vine(40e-3), o, nullptr, thesis_epm(Vec3(120e-3, 0.0, 0.0), Vec3::UnitX()),
               Vec3::Zero(), Mat3::Identity());
  ASSERT_TRUE(g.events().empty()) << g.events().front().detail;
  for (int i = 0; i < 40; ++i) {
    const GrowthStatus r = g.advance(0.05, {.pressure = 35e3});
    ASSERT_TRUE(r.converged) << "step " << i << ": " << r.failure;
  }
  const double near = g.length();
  const double extra = g.advance(0.05, {.pressure = 35e3}).magnetorheological_yield;
  g.set_field(thesis_epm(Vec3(400e-3, 0.0, 0.0), Vec3::UnitX()));
  for (int i = 0; i < 40; ++i) ASSERT_TRUE(g.advance(0.05, {.pressure = 35e3}).converged);
  std::printf("  magnet 29 mm beyond the tip: stalled at %.1f mm (magnetorheological yield %.1f kPa); withdrawn to 400 mm: %.1f "
              "mm\n",
              1e3 * near, extra / 1e3, 1e3 * g.length());
  EXPECT_NEAR(near, 40e-3, g.edge_length());  // no growth near the magnet
  EXPECT_GT(extra, 20e3);                       // the fluid's yield alone exceeds P − Y0
  EXPECT_GT(g.length(), near + 10e-3);          // grows once it is withdrawn
}

TEST(Growth, RetractsByDeflatingAndPullingTheTether) {
  // GrowthOptions::retraction_pressure: pulled back at 12 kPa the vine holds its length (an event says so);
  // deflated to 0.5 kPa it inverts from the tip down to the tether, by whole edges.
  GrowthOptions o;
  o.gravity = Vec3::Zero();
  o.retraction_pressure = 1e3;
  VineGrowth g(skin_mvr(60e-3), o, nullptr, {}, Vec3::Zero(), Mat3::Identity());
  const double made = g.length();
  ASSERT_TRUE(g.advance(0.1, {.pressure = 12e3, .tether_length = 40e-3}).converged);
  EXPECT_EQ(g.length(), made);
  ASSERT_FALSE(g.events().empty());
  EXPECT_EQ(g.events().back().kind, GrowthEventKind::kRetract);
  const GrowthStatus r = g.advance(0.1, {.pressure = 0.5e3, .tether_length = 40e-3});
  ASSERT_TRUE(r.converged) << r.failure;
  std::printf("  %.1f mm pulled back to %.1f mm (%d edges inverted)\n", 1e3 * made, 1e3 * g.length(),
              r.edges_removed);
  EXPECT_LE(g.length(), 40e-3 + 1e-12);
  EXPECT_GT(g.length(), 40e-3 - g.edge_length());
  EXPECT_EQ(g.state().x.size(), static_cast<std::size_t>(std::lround(g.length() / g.edge_length())) + 1);
  // Pressurised again with the tether where it is: no growth past it.
  for (int i = 0; i < 20; ++i) ASSERT_TRUE(g.advance(0.1, {.pressure = 12e3, .tether_length = 40e-3}).converged);
  EXPECT_LE(g.length(), 40e-3 + 1e-12);
}


/// The node positions, frames and tissue forces of two states agree to the last bit (a determinism check: exact
/// equality is the point).
void expect_same_bits(const GrowthState& a, const GrowthState& b) {
  EXPECT_EQ(a.time, b.time);
  EXPECT_EQ(a.edges, b.edges);
  EXPECT_EQ(a.tip_length, b.tip_length);
  ASSERT_EQ(a.body.x.size(), b.body.x.size());
  for (std::size_t i = 0; i < a.body.x.size(); ++i) {
    EXPECT_TRUE(a.body.x[i] == b.body.x[i]) << "node " << i;
    EXPECT_TRUE(a.body.frames[std::min(i, a.body.frames.size() - 1)] ==
                b.body.frames[std::min(i, b.body.frames.size() - 1)]);
    EXPECT_TRUE(a.forces.normal_vector[i] == b.forces.normal_vector[i]) << "node " << i;
    EXPECT_TRUE(a.forces.shear_vector[i] == b.forces.shear_vector[i]) << "node " << i;
  }
}

/// The fluid vine leaning into the Y bifurcation's side wall (gravity across the parent, as
/// VineConformsIntoTheDaughterItLeansTowards): contacts, friction references and lagged forces to carry.
GrowthModel leaning_vine(const anatomy::CollisionWorld& world) {
  GrowthOptions o;
  o.gravity = Vec3(0.0, 9.81, 0.0);
  o.law.yield_pressure = 20e3;
  return make_growth_model(fluid_vine(), o, &world, Vec3(2e-3, 3e-3, 0.0), Mat3::Identity());
}

/// `steps` steps of 20 ms from `state`, the pressure a load of each step: 35 kPa, then 30 kPa for the second half.
GrowthState grow_on(const GrowthModel& model, GrowthState state, GrowthWorkspace& workspace, int steps) {
  for (int k = 0; k < steps; ++k) {
    const GrowthStatus s = grow_step(model, {}, {.pressure = k < steps / 2 ? 35e3 : 30e3}, state, workspace, 0.02);
    EXPECT_TRUE(s.converged) << s.failure;
  }
  return state;
}

TEST(GrowthStep, ACheckpointIsACopyOfTheStateAndRepeatsTheRunBitForBit) {
  // STYLE.md's state: everything that changes in time is in GrowthState, so a copy taken mid-run and grown on again
  // repeats the run exactly, with the workspace that made it or with a new one (nothing that steers the solve is
  // kept in the workspace), and the pressure changing as a step load (35 then 30 kPa) needs no new model.
  const anatomy::Phantom y = anatomy::make_y_bifurcation({});
  const anatomy::CollisionWorld world(y.mesh);
  const GrowthModel model = leaning_vine(world);
  GrowthState state;
  GrowthWorkspace workspace;
  const GrowthStatus start = start_growth(model, {}, fluid_vine().length, 35e3, state, workspace);
  ASSERT_TRUE(start.events.empty()) << start.events.front().detail;  // placed whole: no "solver" event
  state = grow_on(model, state, workspace, 30);
  const GrowthState checkpoint = state;
  ASSERT_GT(checkpoint.forces.nodes_in_contact, 0);  // there is contact history to carry
  const GrowthState a = grow_on(model, checkpoint, workspace, 30);
  GrowthWorkspace fresh;
  const GrowthState b = grow_on(model, checkpoint, fresh, 30);
  EXPECT_GT(a.edges, checkpoint.edges + 3);  // it grew on, in contact
  EXPECT_GT(a.forces.nodes_in_contact, 0);
  EXPECT_EQ(a.pressure, 30e3);
  EXPECT_NEAR(workspace.radius, extended_radius(fluid_vine(), 30e3), 1e-15);  // the body at the step's pressure
  expect_same_bits(a, b);
}

TEST(GrowthStep, TrialsInThreadsShareOneModelAndMatchTheSequentialRun) {
  // The model is immutable and the world's queries const: two threads growing from one model, each with its own
  // state and workspace, give the sequential run's result to the bit.
  const anatomy::Phantom y = anatomy::make_y_bifurcation({});
  const anatomy::CollisionWorld world(y.mesh);
  const GrowthModel model = leaning_vine(world);
  const auto trial = [&model] {
    GrowthState state;
    GrowthWorkspace workspace;
    start_growth(model, {}, fluid_vine().length, 35e3, state, workspace);
    return grow_on(model, state, workspace, 40);
  };
  const GrowthState sequential = trial();
  GrowthState in_thread[2];
  std::thread first([&] { in_thread[0] = trial(); });
  std::thread second([&] { in_thread[1] = trial(); });
  first.join();
  second.join();
  expect_same_bits(in_thread[0], sequential);
  expect_same_bits(in_thread[1], sequential);
}

}  // namespace
}  // namespace magvine::robot
