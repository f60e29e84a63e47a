// The vine body (robot/vine.hpp, the inflated-beam joint law in robot/rod.hpp): the normalised law against the
// thesis's eq 4.6/4.8 and its own energy, the derivatives against finite differences, the discretised vine against
// the two-stage reference in its wrinkled range, the fill laws, and the refusals.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/robot/elastica.hpp"
#include "magvine/robot/inflated_beam.hpp"
#include "magvine/robot/vine.hpp"
#include "support/rod_derivatives.hpp"

namespace magvine::robot {
namespace {

// The thesis's skin MVR (thesis 4.6): Ø8 mm, LDPE 20 µm (E ≈ 0.2 GPa, ρ 920), NdFeB–Ecoflex skin 0.2 mm
// (E = 3 × 33 kPa, ρ 1840, Br 0.101 T), 80 mm, 12 kPa.
VineParameters skin_mvr(int edges = 80) { return thesis_skin_mvr(80e-3, edges); }

TEST(InflatedLaw, NormalisedLawIsTheThesisLawAndItsEnergyIntegratesTheMoment) {
  // Independent reference: eq 4.8 gives M(φ0) and eq 4.6 κ(M); their normalised pair must lie on the law.
  const double r = 4e-3;
  const double p = 12e3;
  const double ei = 1e-3;
  const double mc = collapse_moment(r, p);
  for (const double phi : {0.01, 0.5, 1.0, 2.0, 2.8, 3.1, 3.14}) {
    const double m = wrinkled_moment(phi, r, p);
    const double k = inflated_curvature(m, r, p, ei) * ei / mc;
    EXPECT_NEAR(normalised_inflated_bending(k).moment, m / mc, 1e-9) << "phi0 " << phi;
  }
  // dΦ/dk = m by central differences, across the linear range, the wrinkling point and far into the collapse.
  for (const double k : {0.2, 0.49, 0.51, 0.7, 1.0, 3.0, 30.0, 1e3, 1e5}) {
    const double step = 1e-5 * k;
    const double fd = (normalised_inflated_bending(k + step).energy - normalised_inflated_bending(k - step).energy) /
                      (2.0 * step);
    EXPECT_NEAR(fd, normalised_inflated_bending(k).moment, 1e-6) << "k " << k;
    // dm/dk (the tangent stiffness the rod's analytic Hessian uses) by central differences of m; relative, since it
    // falls like k^(-5/3) towards the collapse; k = 1e5 falls inside the series branch (ε ≈ 0.036 < 0.05).
    const double dm = (normalised_inflated_bending(k + step).moment - normalised_inflated_bending(k - step).moment) /
                      (2.0 * step);
    EXPECT_NEAR(normalised_inflated_bending(k).stiffness, dm, 1e-5 * std::abs(dm) + 1e-12) << "k " << k;
  }
  // Φ is continuous at the wrinkling point and the moment saturates at the collapse.
  EXPECT_NEAR(normalised_inflated_bending(0.5 + 1e-12).energy, 0.125, 1e-9);
  // (m = 1 − ε²/10 + O(ε⁴) with ε = (3π/2k)^⅓ ≈ 3.6e-3 at k = 1e8.)
  EXPECT_NEAR(normalised_inflated_bending(1e8).moment, 1.0 - std::pow(1.5 * kPi / 1e8, 2.0 / 3.0) / 10.0, 1e-9);
  // A trapezoid quadrature of m from 0 to 20 matches Φ(20) (second, independent route to the closed form).
  double integral = 0.0;
  const int n = 200000;
  for (int i = 0; i < n; ++i) {
    const double a = 20.0 * i / n;
    const double b = 20.0 * (i + 1) / n;
    integral += 0.5 * (b - a) * (normalised_inflated_bending(a).moment + normalised_inflated_bending(b).moment);
  }
  EXPECT_NEAR(integral, normalised_inflated_bending(20.0).energy, 1e-7);
}

TEST(Vine, GradientMatchesFiniteDifferencesOfTheEnergy) {
  // Skin moment, magnetic-fluid fill (bounded law, near saturation close to the dipole), inflated law with joints in
  // the linear, wrinkled and creased ranges, gravity; the air-filled one with a crease set (rest strain) at every
  // joint, up to a 0.4 rad turn.
  for (const FillKind fill : {FillKind::kMagneticFluid, FillKind::kAir}) {
    VineParameters v = skin_mvr(8);
    v.fill = fill;
    RodModel m = vine_rod(v);
    if (fill == FillKind::kAir) {
      const double h = m.length / m.edges;
      for (int j = 0; j < m.edges; ++j) {
        m.rest_strain.push_back(Vec3(0.0, 0.1 * j, -0.05 * j) * 2.0 / h);
      }
    }
    m.gravity = Vec3(0.5, -9.81, 1.0);
    magnetics::FieldModel magnets;
    magnets.add(magnetics::DipoleSource{Vec3(0.0, 0.0, 300.0)},
                magnetics::Pose::from_axis(Vec3(0.04, -0.03, 0.01), Vec3(0.2, 1.0, 0.1)));
    const RodField field = field_function(magnets, magnets.rest_poses);
    RodState s = straight_rod(m);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (std::size_t j = 0; j < s.frames.size(); ++j) {
      const double angle = j % 3 == 0 ? 1e-4 : (j % 3 == 1 ? 0.05 : 0.8);  // linear, wrinkled, creased joints
      s.frames[j] = Eigen::AngleAxisd(angle * (1.0 + 0.2 * u(rng)), Vec3(u(rng), u(rng), u(rng)).normalized())
                        .toRotationMatrix() *
                    (j > 0 ? s.frames[j - 1] : s.frames[j]);
    }
    testing::nodes_along_frames(m, s, 1e-6, rng);
    testing::expect_gradient_matches_energy(m, field, s, fill == FillKind::kAir ? "air" : "fluid");
    testing::expect_hessian_matches_finite_differences(m, field, s, fill == FillKind::kAir ? "air" : "fluid");
  }
}

TEST(Vine, ACreasedJointCarriesTheCreaseMomentOfEquation413) {
  // One joint of the skin MVR (6 kPa, h = 1 mm) folded by θ with the rest straight: its moment dW/dψ must be the crease
  // hinge's M_c(1 + tan²(θ/2)) (eq 4.13). The wrinkled law there is at k ≈ 10³ (m = 1 − ε²/10 ≈ 0.997) and the flat
  // film adds ~1e-6 M_c, so 1 %.
  VineParameters v = skin_mvr(80);
  v.pressure = 6e3;
  const RodModel m = vine_rod(v);
  for (const double degrees : {30.0, 60.0, 90.0}) {
    RodState s = straight_rod(m);
    const Mat3 turn = Eigen::AngleAxisd(degrees * kDegToRad, Vec3::UnitZ()).toRotationMatrix();
    for (std::size_t j = 40; j < s.frames.size(); ++j) s.frames[j] = turn * s.frames[j];
    const double moment = joint_bending_moments(m, s)[40];
    // (the tube pressurised: its radius with the diametric extension, as the model's)
    const double expected = crease_moment(degrees * kDegToRad, extended_radius(v, v.pressure), v.pressure);
    EXPECT_NEAR(moment, expected, 0.01 * expected) << degrees << "°";
  }
}

TEST(Vine, WrinkledCantileverMatchesTheTwoStageModel) {
  // Horizontal skin MVR under its own weight plus a uniform transverse load q chosen so the base moment is 0.8 M_c:
  // the base third wrinkles. Reference: stage 1 of the two-stage model (loads on the straight body, y'' = κ(M)).
  // Tolerance 2 % of the tip deflection: both are small-deflection here (θ ≈ 2°, geometric terms ~ θ²), and the
  // discretisation error at 200 edges is ~1e-4.
  VineParameters v = skin_mvr(200);
  RodModel m = vine_rod(v);
  const double radius = extended_radius(v, v.pressure);  // pressurised, as the model's
  const double mc = collapse_moment(radius, v.pressure);
  const double q = 2.0 * 0.8 * mc / (v.length * v.length);
  m.gravity = Vec3(0.0, -q / m.mass_per_length, 0.0);
  RodState s = straight_rod(m);
  const RodSolveReport report = solve_rod_statics(m, {}, s);
  ASSERT_TRUE(report.converged) << report.failure;
  TwoStageLoads loads;
  loads.force = [q](double) { return q; };
  const TwoStageResult ref =
      solve_two_stage({.radius = radius, .pressure = v.pressure, .bending_stiffness = m.bending_stiffness_3,
                       .length = v.length},
                      loads, 20000);
  ASSERT_EQ(ref.stage, 1);
  EXPECT_GT(ref.wrinkled_length, 0.2 * v.length);
  std::printf("  tip deflection %.4f mm, two-stage %.4f mm (wrinkled over %.1f mm)\n", -1e3 * s.tip().y(),
              1e3 * ref.tip_deflection, 1e3 * ref.wrinkled_length);
  EXPECT_NEAR(-s.tip().y(), ref.tip_deflection, 0.02 * ref.tip_deflection);
}

TEST(Vine, BoundedFluidLawIsLinearInWeakFieldsAndSaturates) {
  // A straight magnetic-fluid vine along x in a uniform field: the fill energy is −½ V χ B²/μ0 with Maxwell-Garnett's
  // χ = 3φβ/(1 − φβ), β = χ_p/(χ_p + 3) for iron particles (χ_p = 4999), along the axis and χ/(1 + χ/2) across (weak
  // field), and −V μ0 M_s |H|-like beyond saturation.
  VineParameters v = skin_mvr(10);
  v.skin_remanence = 0.0;
  v.fill = FillKind::kMagneticFluid;
  const RodModel m = vine_rod(v);
  const RodState s = straight_rod(m);
  const double volume = m.induced->volume_per_length * v.length;
  const double beta = 4999.0 / 5002.0;
  const double chi = 3.0 * 0.23 * beta / (1.0 - 0.23 * beta);
  const auto energy = [&](const Vec3& b) {
    return rod_energy(m, [b](const Vec3&) { magnetics::FieldSample f; f.b = b; return f; }, s);
  };
  const double b = 1e-3;
  EXPECT_NEAR(energy(Vec3(b, 0, 0)), -0.5 * volume * chi * b * b / kMu0, 1e-6 * volume * chi * b * b / kMu0);
  const double chi_t = chi / (1.0 + 0.5 * chi);
  EXPECT_NEAR(energy(Vec3(0, b, 0)), -0.5 * volume * chi_t * b * b / kMu0, 1e-6 * volume * chi_t * b * b / kMu0);
  // Deep saturation: dU/d|B| → −V M_s (the moment saturates at φ·M_s·V, M_s of iron 1.7 MA/m as PHYSICS.md gives it:
  // a literal here, independent of the code's constant).
  const double big = 50.0;
  const double slope = (energy(Vec3(big + 1e-3, 0, 0)) - energy(Vec3(big - 1e-3, 0, 0))) / 2e-3;
  EXPECT_NEAR(-slope, volume * 0.23 * 1.7e6, 1e-3 * volume * 0.23 * 1.7e6);
}

TEST(Vine, ItsMomentsPerLengthAreTheMagneticsLaws) {
  // One home per law: the vine's skin and fill take their magnetisation from magnetics/magnetisation.hpp. The skin
  // MVR's moment per everted length is the SkinLaw's with its tail (at the pressurised radius); the fluid vine's
  // induced moment, −dU/dB of a straight body in a uniform field, is the FluidBoundedLaw's for the fill's volume, in
  // an axial, a transverse and an oblique field, weak and near saturation.
  const VineParameters skin = skin_mvr(10);
  const RodModel ms = vine_rod(skin);
  const double r = extended_radius(skin, skin.pressure);
  const magnetics::SkinLaw law{.radius = r, .thickness = skin.skin.thickness,
                               .br_body = skin.skin_remanence * skin.skin_direction};
  ASSERT_EQ(ms.moment_per_length.size(), 10u);
  for (const Vec3& m : ms.moment_per_length) {
    EXPECT_NEAR((m - law.moment_per_length(true)).norm(), 0.0, 1e-12 * m.norm());
  }
  EXPECT_NEAR(ms.moment_per_length[0].norm(), skin.skin_remanence / kMu0 * 2.0 * kPi * r * skin.skin.thickness, 1e-9);

  VineParameters fluid = thesis_fluid_vine(50e-3, 10);
  const RodModel mf = vine_rod(fluid);
  const RodState s = straight_rod(mf);
  const double inner = extended_radius(fluid, fluid.pressure) - fluid.wall.thickness;
  const double volume = kPi * inner * inner * fluid.length;
  const magnetics::FluidBoundedLaw bounded{.volume_fraction = fluid.volume_fraction};
  for (const Vec3& b : {Vec3(0.05, 0.0, 0.0), Vec3(0.0, 0.05, 0.0), Vec3(0.03, -0.02, 0.04), Vec3(2.0, 1.0, 0.5)}) {
    // −dU/dB by central differences of the rod's energy (only the fill's term depends on B here).
    Vec3 moment;
    for (int k = 0; k < 3; ++k) {
      const double step = 1e-6 * b.norm();
      const auto energy = [&](const Vec3& field) {
        return rod_energy(mf, [field](const Vec3&) { magnetics::FieldSample f; f.b = field; return f; }, s);
      };
      moment[k] = -(energy(b + step * Vec3::Unit(k)) - energy(b - step * Vec3::Unit(k))) / (2.0 * step);
    }
    const Vec3 expected = bounded.moment(b, volume, mf.base_frame);
    EXPECT_NEAR((moment - expected).norm(), 0.0, 1e-6 * expected.norm()) << b.transpose();
  }
}

TEST(Vine, BadParametersAreRefusedWithTheirName) {
  VineParameters v = skin_mvr();
  v.pressure = 30e3;  // hoop stress 30 kPa × 4 mm / 20 µm = 6 MPa, strength 10 MPa: fine
  EXPECT_NO_THROW(vine_rod(v));
  v.pressure = 60e3;  // 12 MPa > 10 MPa
  try {
    vine_rod(v);
    ADD_FAILURE() << "no burst error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("burst"), std::string::npos) << e.what();
  }
  v = skin_mvr();
  v.length = 0.0;
  EXPECT_THROW(vine_rod(v), InputError);
  v = skin_mvr();
  v.wall.modulus = -1.0;
  EXPECT_THROW(vine_rod(v), InputError);
  v = skin_mvr();
  v.skin_direction = Vec3::UnitX();  // axial skin magnetisation cancels on eversion
  EXPECT_THROW(vine_rod(v), InputError);
}

}  // namespace
}  // namespace magvine::robot

namespace magvine::robot {
namespace {

/// The fig 4.8 sequence: the skin MVR, 80 mm, vertical against gravity, in the torque setup (EPM axis vertical,
/// 65 mm above the base, the skin's moment in the bending plane), the EPM moved through `distances` in turn, each
/// equilibrium starting from the last. Returns the chord angles [deg].
std::vector<double> figure_48_sequence(double pressure, const std::vector<double>& distances) {
  VineParameters v = skin_mvr(40);
  v.pressure = pressure;
  RodModel m = vine_rod(v);
  m.base_frame.col(0) = Vec3::UnitZ();
  m.base_frame.col(1) = Vec3::UnitX();
  m.base_frame.col(2) = m.base_frame.col(0).cross(m.base_frame.col(1));
  m.gravity = Vec3(0.0, 0.0, -9.81);
  RodState s = straight_rod(m);
  std::vector<double> out;
  for (const double d : distances) {
    magnetics::FieldModel epm;
    epm.add(magnetics::CylinderMagnet(50.8e-3, 101.6e-3, Vec3(0.0, 0.0, 1.48)),
            magnetics::Pose::from_axis(Vec3(d, 0.0, 65e-3), Vec3::UnitZ()), "EPM");
    const RodSolveReport r = solve_rod_statics(m, field_function(epm, epm.rest_poses), s);
    EXPECT_TRUE(r.converged) << d << " m: " << r.failure;
    out.push_back(std::atan2(s.tip().x(), s.tip().z()) / kDegToRad);
  }
  return out;
}

TEST(Vine, BentByTheMagnetAndLetGoItKeepsItsCreaseAsInFigure48) {
  // Thesis fig 4.8 (torque setup, h = 65 mm, with the internal tail and tether): EPM at 270 mm → 8°, 218 → 11°,
  // 190 → 72°, then back to 252 mm → 56°: hysteresis, which the thesis puts down to the tensioned tether and leaves
  // out of its model. The pressure is not stated; 2 kPa is where this model's crease onset falls between 218 and
  // 190 mm, as the experiment's did (at 1.75 and 2.25 kPa it keeps 58° and 46° at 252 mm instead of 54°). Nothing
  // else is fitted: the crease holds because the creased body's own weight, tilted, adds to the moment that creased
  // it, so the crease hinge (eq 4.13) stays loaded past M_c when the magnet withdraws. Asserted: straight before the
  // snap, creased beyond 45° at 190 mm, and at 252 mm within 10° of the thesis's 56° (the spread over 1.75–2.25 kPa);
  // then, far enough away, it does straighten. Gap reported, not tuned: before the crease the thesis's vine bent
  // 8–11°, this one under 1° (the tail and tether the thesis's setup had are not modelled).
  const std::vector<double> a = figure_48_sequence(2e3, {0.270, 0.218, 0.190, 0.252, 0.300});
  std::printf("  2 kPa: 270 mm %.1f deg (thesis 8), 218 mm %.1f (11), 190 mm %.1f (72), back to 252 mm %.1f (56); "
              "300 mm %.1f\n",
              a[0], a[1], a[2], a[3], a[4]);
  EXPECT_LT(a[0], 15.0);
  EXPECT_LT(a[1], 15.0);
  EXPECT_GT(a[2], 45.0);
  EXPECT_NEAR(a[3], 56.0, 10.0);
  EXPECT_LT(a[4], 15.0);
}

}  // namespace
}  // namespace magvine::robot
