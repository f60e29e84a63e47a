// The inflated-beam law (Comer & Levy; thesis eq 4.6, 4.8, 4.13) and the thesis's two-stage vine model
// (robot/inflated_beam.hpp): the law's limits and inverse, and the two stages against Euler–Bernoulli and the crease
// closed forms.

#include <gtest/gtest.h>

#include <cmath>

#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "magvine/robot/inflated_beam.hpp"

namespace magvine::robot {
namespace {

// The thesis's skin MVR: Ø8 mm, 80 mm, 12 kPa; wall EI of 20 µm LDPE (E ≈ 0.2 GPa): E·πR³t.
constexpr double kR = 4e-3;
constexpr double kP = 12e3;
constexpr double kL = 80e-3;
constexpr double kEI = 0.2e9 * kPi * kR * kR * kR * 20e-6;

TEST(InflatedBeam, WrinkledMomentRunsFromTheWrinklingToTheCollapseMoment) {
  const double m_w = wrinkling_moment(kR, kP);
  const double m_c = collapse_moment(kR, kP);
  EXPECT_NEAR(m_w, 0.5 * m_c, 1e-18);
  EXPECT_NEAR(wrinkled_moment(0.0, kR, kP), m_w, 1e-14 * m_w);  // eq 4.8 at φ0 = 0: π·2π/(4π) = π/2
  EXPECT_NEAR(wrinkled_moment(kPi - 1e-6, kR, kP), m_c, 1e-10 * m_c);
  // Monotone: the law has one inverse, and wrinkle_angle is it.
  double previous = 0.0;
  for (int i = 0; i <= 1000; ++i) {
    const double phi = kPi * i / 1000.0;
    const double m = wrinkled_moment(phi, kR, kP);
    EXPECT_GE(m, previous) << phi;
    previous = m;
    if (i > 0 && i < 1000) {
      EXPECT_NEAR(wrinkle_angle(m, kR, kP), phi, 1e-9) << phi;
    }
  }
}

TEST(InflatedBeam, SeriesNearTheCollapseJoinsTheClosedForm) {
  // Just outside the series range (ε = π − φ0 = 0.05) the formula of eq 4.8 in its original form.
  for (const double e : {0.0501, 0.06, 0.1}) {
    const double phi = kPi - e;
    const double direct = kP * kR * kR * kR * kPi * (2 * kPi - 2 * phi + std::sin(2 * phi)) /
                          (4 * (std::sin(phi) + (kPi - phi) * std::cos(phi)));
    EXPECT_NEAR(wrinkled_moment(phi, kR, kP), direct, 1e-9 * direct) << e;
  }
  // Across the switch the law is continuous to the series' truncation error.
  const double below = wrinkled_moment(kPi - 0.05 * (1 - 1e-12), kR, kP);
  const double above = wrinkled_moment(kPi - 0.05 * (1 + 1e-12), kR, kP);
  EXPECT_NEAR(below, above, 1e-10 * above);
}

TEST(InflatedBeam, CurvatureIsLinearBelowWrinklingSoftensAboveAndDivergesAtCollapse) {
  const double m_w = wrinkling_moment(kR, kP);
  const double m_c = collapse_moment(kR, kP);
  EXPECT_DOUBLE_EQ(inflated_curvature(0.5 * m_w, kR, kP, kEI), 0.5 * m_w / kEI);
  EXPECT_DOUBLE_EQ(inflated_curvature(-0.5 * m_w, kR, kP, kEI), -0.5 * m_w / kEI);
  // Continuous at M_w (the factor 2π/(2π − 2φ0 + sin 2φ0) → 1 as φ0 → 0) ...
  EXPECT_NEAR(inflated_curvature(m_w * (1 + 1e-9), kR, kP, kEI), m_w / kEI, 1e-6 * m_w / kEI);
  // ... softer than linear in the wrinkled range, and unbounded at the collapse.
  EXPECT_GT(inflated_curvature(0.9 * m_c, kR, kP, kEI), 0.9 * m_c / kEI * 1.5);
  EXPECT_GT(inflated_curvature(m_c * (1 - 1e-9), kR, kP, kEI), 1e3 * m_c / kEI);
  EXPECT_TRUE(std::isinf(inflated_curvature(m_c, kR, kP, kEI)));
}

TEST(InflatedBeam, CreaseMomentClosedForm) {
  const double m_c = collapse_moment(kR, kP);
  EXPECT_DOUBLE_EQ(crease_moment(0.0, kR, kP), m_c);
  EXPECT_NEAR(crease_moment(0.5 * kPi, kR, kP), 2.0 * m_c, 1e-15 * m_c);
}

// Stage 1 integrates by trapezoids on 2000 intervals: O(h²) = 2.5e-7 relative for smooth loads.
constexpr double kStageTol = 1e-6;

TEST(TwoStageModel, SmallLoadsAreEulerBernoulli) {
  const TwoStageVine vine{kR, kP, kEI, kL};
  const double m_w = wrinkling_moment(kR, kP);
  {
    const double q = 0.5 * m_w / kL;  // uniform torque: M_e = q(l − x) ≤ M_w/2
    const TwoStageResult r = solve_two_stage(vine, {.torque = [q](double) { return q; }});
    EXPECT_EQ(r.stage, 1);
    EXPECT_EQ(r.wrinkled_length, 0.0);
    const double expected = q * kL * kL * kL / (3.0 * kEI);
    EXPECT_NEAR(r.tip_deflection, expected, kStageTol * expected);
    EXPECT_NEAR(r.angle, std::asin(expected / kL), kStageTol);
  }
  {
    const double q = m_w / (kL * kL);  // uniform force: M_e = q(l − x)²/2 ≤ M_w/2
    const TwoStageResult r = solve_two_stage(vine, {.force = [q](double) { return q; }});
    EXPECT_EQ(r.stage, 1);
    const double expected = q * std::pow(kL, 4) / (8.0 * kEI);
    EXPECT_NEAR(r.tip_deflection, expected, kStageTol * expected);
    EXPECT_NEAR(r.base_moment, 0.5 * q * kL * kL, kStageTol * 0.5 * q * kL * kL);
  }
  {
    // Load rising linearly to q0 at the tip: δ = 11·q0·l⁴/(120 EI). Needs the lever arm u − x of PHYSICS.md (the
    // thesis's printed l − u gives a different moment for any non-uniform load).
    const double q0 = m_w / (kL * kL);
    const TwoStageResult r = solve_two_stage(vine, {.force = [q0](double u) { return q0 * u / kL; }});
    EXPECT_EQ(r.stage, 1);
    const double expected = 11.0 * q0 * std::pow(kL, 4) / (120.0 * kEI);
    EXPECT_NEAR(r.tip_deflection, expected, kStageTol * expected);
  }
}

TEST(TwoStageModel, WrinklingStartsWhereTheMomentReachesMwAndSoftensTheBeam) {
  const TwoStageVine vine{kR, kP, kEI, kL};
  const double m_c = collapse_moment(kR, kP);
  const double q = 0.8 * m_c / kL;  // M_e(x) = q(l − x): wrinkled from the clamp to x_w = l − M_w/q
  const TwoStageResult r = solve_two_stage(vine, {.torque = [q](double) { return q; }});
  EXPECT_EQ(r.stage, 1);
  EXPECT_NEAR(r.wrinkled_length, kL - wrinkling_moment(kR, kP) / q, kL / 2000.0);  // one grid step
  EXPECT_GT(r.tip_deflection, q * kL * kL * kL / (3.0 * kEI));                     // softer than linear
}

TEST(TwoStageModel, CreaseAngleMatchesTheCreaseLaw) {
  const TwoStageVine vine{kR, kP, kEI, kL};
  const double m_c = collapse_moment(kR, kP);
  // A constant base moment 2·M_c: 1 + tan²(θ/2) = 2 → θ = π/2.
  {
    const double q = 2.0 * m_c / kL;
    TwoStageLoads loads{.torque = [q](double) { return q; },
                        .creased_base_moment = [m_c](double) { return 2.0 * m_c; }};
    const TwoStageResult r = solve_two_stage(vine, loads);
    EXPECT_EQ(r.stage, 2);
    EXPECT_NEAR(r.angle, 0.5 * kPi, 1e-12);
    // Mirrored loads bend the other way by the same angle.
    loads.torque = [q](double) { return -q; };
    loads.creased_base_moment = [m_c](double) { return -2.0 * m_c; };
    EXPECT_NEAR(solve_two_stage(vine, loads).angle, -0.5 * kPi, 1e-12);
  }
  // A moment that falls as the body turns (a transverse tip-like load: M0·cos θ) stops where M0·cos θ = M_c(θ).
  {
    const double m0 = 3.0 * m_c;
    const TwoStageResult r =
        solve_two_stage(vine, {.torque = [&](double) { return m0 / kL; },
                               .creased_base_moment = [m0](double t) { return m0 * std::cos(t); }});
    EXPECT_EQ(r.stage, 2);
    EXPECT_NEAR(m0 * std::cos(r.angle), crease_moment(r.angle, kR, kP), 1e-9 * m_c);
    EXPECT_GT(r.angle, 0.0);
    EXPECT_LT(r.angle, 0.5 * kPi);
  }
}

TEST(TwoStageModel, BadInputIsRejected) {
  EXPECT_THROW(solve_two_stage({0.0, kP, kEI, kL}, {}), InputError);
  EXPECT_THROW(solve_two_stage({kR, -1.0, kEI, kL}, {}), InputError);
  EXPECT_THROW(solve_two_stage({kR, kP, kEI, 0.0}, {}), InputError);
}

}  // namespace
}  // namespace magvine::robot
