// Stiff and extreme inputs for the rod and vine solvers (issue 4): moduli over three decades, pressures from zero to
// 100 kPa, a magnet 1 mm from the body, lengths from 1 mm to 1 m, 2 to 2000 nodes. Each must end without NaN in a
// bounded number of iterations, either converged or with a named cause, and give nearly the same answer at a
// neighbouring setting (no jumps from the solver).

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "magvine/core/units.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/robot/elastica.hpp"
#include "magvine/robot/rod.hpp"
#include "magvine/robot/vine.hpp"

namespace magvine::robot {
namespace {

RodField uniform(const Vec3& b) {
  return [b](const Vec3&) {
    magnetics::FieldSample s;
    s.b = b;
    return s;
  };
}

/// Every node finite.
bool finite(const RodState& s) {
  for (const Vec3& x : s.x) {
    if (!x.allFinite()) return false;
  }
  return true;
}

struct Outcome {
  RodState state;
  RodSolveReport report;
};

Outcome solve(const RodModel& m, const RodField& field) {
  Outcome o{straight_rod(m), {}};
  o.report = solve_rod_statics(m, field, o.state);
  EXPECT_TRUE(finite(o.state));
  EXPECT_TRUE(o.report.converged || !o.report.failure.empty());  // a failure always names its cause
  EXPECT_LE(o.report.iterations, RodSolveOptions{}.max_iterations);
  return o;
}

RodModel beam(double length, double shear_modulus, int edges) {
  RodModel m = rectangular_rod(length, 3e-3, 3e-3, shear_modulus, 1882.0, 0.125, Vec3::UnitX(), edges);
  m.gravity = Vec3(0.0, -9.81, 0.0);
  return m;
}

TEST(RobotExtremes, ModulusFromTenKilopascalsToTenMegapascals) {
  // 60 mm beam, gravity and 10 mT across it. Neighbour: G × 1.01 moves the tip by < 1 % of L (the response is
  // smooth in G: the tip's sensitivity dy/dlnG is at most ~L/4 here).
  for (const double g : {1e4, 1e5, 1e6, 1e7}) {
    const Outcome a = solve(beam(0.06, g, 50), uniform(Vec3(0.0, 0.01, 0.0)));
    const Outcome b = solve(beam(0.06, 1.01 * g, 50), uniform(Vec3(0.0, 0.01, 0.0)));
    ASSERT_TRUE(a.report.converged) << g << ": " << a.report.failure;
    ASSERT_TRUE(b.report.converged) << g << ": " << b.report.failure;
    EXPECT_LT((a.state.tip() - b.state.tip()).norm(), 0.01 * 0.06) << g;
    std::printf("  G %8.0f Pa: tip (%6.2f, %6.2f) mm, %d iterations\n", g, 1e3 * a.state.tip().x(),
                1e3 * a.state.tip().y(), a.report.iterations);
  }
}

TEST(RobotExtremes, LengthFromOneMillimetreToOneMetre) {
  for (const double length : {1e-3, 1e-2, 0.1, 1.0}) {
    const Outcome a = solve(beam(length, 120e3, 50), uniform(Vec3(0.0, 0.01, 0.0)));
    const Outcome b = solve(beam(1.01 * length, 120e3, 50), uniform(Vec3(0.0, 0.01, 0.0)));
    ASSERT_TRUE(a.report.converged) << length << ": " << a.report.failure;
    ASSERT_TRUE(b.report.converged) << length << ": " << b.report.failure;
    EXPECT_LT((a.state.tip() - b.state.tip()).norm(), 0.03 * length) << length;
    std::printf("  L %6.3f m: tip (%8.4f, %8.4f) L, %d iterations, %d load steps\n", length,
                a.state.tip().x() / length, a.state.tip().y() / length, a.report.iterations, a.report.load_steps);
  }
}

TEST(RobotExtremes, TwoToTwoThousandNodes) {
  // The same beam at 2, 20, 200 and 2000 nodes: all converge and approach the elastica (second order).
  RodModel m = beam(0.06, 120e3, 1);
  ElasticaProblem p;
  p.length = 0.06;
  p.bending_stiffness = m.bending_stiffness_3;
  p.area = 9e-6;
  p.density = 1882.0;
  p.gravity = Eigen::Vector2d(0.0, -9.81);
  p.remanence = 0.125;
  p.field = uniform(Vec3(0.0, 0.01, 0.0));
  const ElasticaSolution ref = solve_elastica(p);
  ASSERT_TRUE(ref.converged);
  double previous = 1.0;
  for (const int nodes : {2, 20, 200, 2000}) {
    const Outcome a = solve(beam(0.06, 120e3, nodes - 1), p.field);
    ASSERT_TRUE(a.report.converged) << nodes << ": " << a.report.failure;
    const double error = (a.state.tip().head<2>() - ref.tip()).norm() / 0.06;
    std::printf("  %4d nodes: tip error %.2e L, %d iterations\n", nodes, error, a.report.iterations);
    EXPECT_LT(error, nodes == 2 ? 0.5 : previous) << nodes;
    previous = error;
  }
  EXPECT_LT(previous, 1e-5);
}

TEST(RobotExtremes, MagnetOneMillimetreFromTheBody) {
  // The Ø101.6 mm N52 EPM (exact cylinder) with its face 1 mm below the beam's tip, moment along the beam: fields
  // of ~0.5 T and gradients of ~10 T/m. The beam has an equilibrium (it bends down to the magnet's face region or is
  // held by its stiffness); the solver must reach one or stop with a cause — never NaN.
  magnetics::FieldModel magnet;
  magnet.add(magnetics::CylinderMagnet(50.8e-3, 101.6e-3, Vec3(0.0, 0.0, 1.48)),
             magnetics::Pose::from_axis(Vec3(0.06, -1.5e-3 - 1e-3 - 50.8e-3, 0.0), Vec3::UnitX()), "EPM");
  const RodField field = field_function(magnet, magnet.rest_poses);
  const Outcome a = solve(beam(0.06, 120e3, 50), field);
  std::printf("  %s after %d iterations; tip (%.2f, %.2f) mm\n",
              a.report.converged ? "converged" : a.report.failure.c_str(), a.report.iterations,
              1e3 * a.state.tip().x(), 1e3 * a.state.tip().y());
  // Measured: the beam is pulled into the magnet (no free-space equilibrium without contact); the solver stops with
  // a cause (with the analytic Hessian: the load ramp exhausted at load factor 0.005 after ~320 iterations; with the
  // finite-difference one it ran into the iteration budget) and keeps the last equilibrium, already bent towards the
  // magnet, finite.
  EXPECT_LE(a.report.iterations, RodSolveOptions{}.max_iterations);
  if (!a.report.converged) {
    EXPECT_TRUE(a.report.failure.find("iteration budget") != std::string::npos ||
                a.report.failure.find("load ramp exhausted") != std::string::npos)
        << a.report.failure;
  }
  for (const Vec3& x : a.state.x) EXPECT_TRUE(x.allFinite());
  EXPECT_LT(a.state.tip().y(), 0.0);
}

VineParameters horizontal_vine(double pressure) {
  VineParameters v;
  v.length = 50e-3;
  v.radius = 2.5e-3;
  v.pressure = pressure;
  v.wall = {.thickness = 38e-6, .modulus = 10e6, .density = 1000.0};
  // A strong film, so 100 kPa does not burst: hoop stress P·R(P)/t = 10.9 MPa with the diametric extension (66 %).
  v.wall_strength = 20e6;
  v.fill = FillKind::kWater;
  v.edges = 25;
  return v;
}

TEST(RobotExtremes, VinePressureFromZeroToOneHundredKilopascals) {
  // A horizontal water-filled Ø5 mm vine under its own weight. At 100 kPa it barely sags; as P falls the wrinkled
  // base softens it; at 0 kPa only the flat film resists and it hangs (a limp vine still gives an answer).
  double previous_sag = 0.0;
  // Neighbour: 1 % more pressure; for 0 kPa, 10 Pa (the sweep's next setting).
  for (const double kpa : {100.0, 10.0, 1.0, 0.1, 0.01, 0.0}) {
    RodModel m = vine_rod(horizontal_vine(kpa * kKpaToPa));
    m.gravity = Vec3(0.0, -9.81, 0.0);
    const Outcome a = solve(m, {});
    ASSERT_TRUE(a.report.converged) << kpa << " kPa: " << a.report.failure;
    RodModel near = vine_rod(horizontal_vine(kpa > 0.0 ? 1.01 * kpa * kKpaToPa : 10.0));
    near.gravity = m.gravity;
    const Outcome b = solve(near, {});
    ASSERT_TRUE(b.report.converged) << kpa << " kPa (neighbour): " << b.report.failure;
    const double sag = -a.state.tip().y();
    std::printf("  %7.2f kPa: sag %.3f mm, %d iterations, %d load steps\n", kpa, 1e3 * sag, a.report.iterations,
                a.report.load_steps);
    EXPECT_GE(sag, previous_sag - 1e-9) << "lower pressure must not sag less";
    EXPECT_LT((a.state.tip() - b.state.tip()).norm(), 0.02 * 50e-3) << kpa;
    previous_sag = sag;
  }
}

}  // namespace
}  // namespace magvine::robot
