// MPM scenes: the gradient force (a bar stretched by a magnet's pull against the same energy reduced to a 1D bar,
// with the exact cylinder field), a cantilever under gravity against Euler–Bernoulli/Timoshenko, the Zhao beam against
// the elastica, stiff and soft materials with the automatic step, failure detection, and bad scenes.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "magvine/anatomy/collision_world.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/phantom.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/cylinder.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/mpm/cantilever.hpp"
#include "magvine/scene/design_scene.hpp"
#include "magvine/scene/magnets_file.hpp"
#include "magvine/scene/mpm_scene.hpp"
#include "magvine/studies/mpm_study.hpp"

namespace magvine::scene {
namespace {

std::string error_of(const std::string& text) {
  try {
    parse_mpm_scene(text, "bad.yaml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// An Ecoflex bar (G 33 kPa, Br 0.101 T along +z, ρ 1840; thesis 3.6.3) hanging from a clamp, its lower end
// 100 mm above the top face of a Ø100 × 100 mm magnet (J 1.44 T, axial, +z). Bar Ø8 mm, 40 mm long, the top 2 mm
// clamped.
constexpr const char* kBarScene = R"(
units: {length: mm}
mpm:
  dimension: 3
  cell: 1.0
  particles_per_cell: 2
  duration: 0.3
  damping: 400
  gravity: [0, 0, -9.81]
  domain: {min: [-12, -12, 90], max: [12, 12, 150]}
  settle: {window: 0.02, tolerance: 0.0005}
bodies:
  - name: bar
    shape: cylinder
    from: [0, 0, 100]
    to: [0, 0, 140]
    radius: 4
    material: {shear_modulus: 33000, density: 1840}
    magnetisation: {remanence: 0.101, direction: [0, 0, 1]}
clamps:
  - {min: [-12, -12, 138], max: [12, 12, 150]}
magnets:
  - kind: cylinder
    diameter: 100
    length: 100
    polarisation: 1.44
    position: [0, 0, -50]
    axis: [0, 0, 1]
probes:
  - {name: bottom, at: [0, 0, 100.25], radius: 0.6}
)";

/// Axial stretch λ of the solver's Neo-Hookean (K = 20 G) under a uniaxial nominal stress σ, the sides free:
/// Newton on (λ, lateral stretch) with P_xx = 0, P_zz = σ (central-difference Jacobian).
double uniaxial_stretch(const mpm::Material& m, double sigma) {
  Eigen::Vector2d s(1.0, 1.0);  // (λ, μ)
  auto residual = [&](const Eigen::Vector2d& u) {
    const Eigen::Matrix3d p = mpm::elastic_stress<3>(m, Eigen::Vector3d(u[1], u[1], u[0]).asDiagonal());
    return Eigen::Vector2d(p(2, 2) - sigma, p(0, 0));
  };
  for (int it = 0; it < 50; ++it) {
    const Eigen::Vector2d r = residual(s);
    if (r.norm() < 1e-12 * m.shear_modulus) break;
    Eigen::Matrix2d j;
    for (int c = 0; c < 2; ++c) {
      Eigen::Vector2d h = Eigen::Vector2d::Zero();
      h[c] = 1e-7;
      j.col(c) = (residual(s + h) - residual(s - h)) / 2e-7;
    }
    s -= j.lu().solve(r);
  }
  return s[0];
}

/// The bar scene's run against its 1D energy (below), in the updated- or the total-Lagrangian frame.
void bar_against_the_one_dimensional_energy(bool total_lagrangian) {
  std::string text = kBarScene;
  if (total_lagrangian) text.replace(text.find("  damping: 400"), 14, "  damping: 400\n  frame: total");
  const MpmScene sc = parse_mpm_scene(text, "bar.yaml");
  ASSERT_EQ(sc.total_lagrangian, total_lagrangian);
  const MpmResult r = run_mpm_scene(sc);
  ASSERT_TRUE(r.ok) << r.failure;
  EXPECT_TRUE(r.settled);
  const double moved = r.samples.back().probes[0].z() - r.samples.front().probes[0].z();

  // Reference: the same energy reduced to a 1D bar, E = ∫ [A ψ(λ) − A Br λ B(z)/μ0 + ρ A g z] dZ (axial
  // magnetisation: F B̃r = λ Br ẑ). Its Euler–Lagrange equation leaves the magnetic terms only at the free end: the
  // elastic nominal stress is σ(Z) = Br B(z_end)/μ0 + ρ g (Z − Z_end), uniform but for the weight — the pull acts
  // like magnetic charge on the end face (the stress −B ⊗ B̃r/μ0 and the body force ∇Bᵀ m cancel inside, eq 3.13 +
  // 3.15). B is the exact cylinder's on the axis at the deformed end, found by fixed-point iteration; λ(σ) is the
  // solver's Neo-Hookean under uniaxial stress. Midpoint rule on 4000 intervals from the probe's layer to the clamp.
  const magnetics::FieldModel magnet = parse_magnets(R"(
units: {length: mm}
magnets:
  - {kind: cylinder, diameter: 100, length: 100, polarisation: 1.44, position: [0, 0, -50], axis: [0, 0, 1]}
)",
                                                     "magnet");
  const mpm::Material mat{33000.0, 20.0 * 33000.0, 1840.0};
  const double z0 = 100.25e-3, zc = 138e-3, br = 0.101;
  const int n = 4000;
  const double h = (zc - z0) / n;
  double stretch = 0.0;
  for (int pass = 0; pass < 30; ++pass) {
    const double b_end = magnetics::field(magnet, magnet.rest_poses, Vec3(0, 0, z0 - stretch)).z();
    double next = 0.0;
    for (int i = 0; i < n; ++i) {
      const double sigma = br * b_end / kMu0 + mat.density * 9.81 * (i + 0.5) * h;
      next += (uniaxial_stretch(mat, sigma) - 1.0) * h;
    }
    stretch = next;
  }
  std::printf("bar above the magnet (%s-Lagrangian): the lower end moves %.4f mm, 1D energy %.4f mm (%.2f %%); %ld "
              "steps, %.1f s\n",
              total_lagrangian ? "total" : "updated", moved * 1e3, -stretch * 1e3, 100.0 * (-moved / stretch - 1.0),
              r.steps, r.runtime_s);
  // Tolerance 3 %: the clamp stops the lateral contraction over its last few millimetres, and the end face's pull
  // is spread over the last cell and a half of the grid.
  EXPECT_NEAR(-moved / stretch, 1.0, 0.03);
}

TEST(MpmScene, AMagnetsPullStretchesABarAsTheOneDimensionalEnergyPredicts) {
  bar_against_the_one_dimensional_energy(false);
}

TEST(MpmScene, InTheTotalLagrangianFrameTooTheBarStretchesAsTheEnergyPredicts) {
  // The same scene with mpm.frame: total (the magnet's field and gradient at each particle, the magnetic Piola stress
  // on the reference grid): the same reference, the same tolerance.
  bar_against_the_one_dimensional_energy(true);
}

/// The relative error of a settled cantilever's tip under gravity against Timoshenko's beam: L/t = 10, K = 20 G,
/// small deflection (δ/L ≈ 2–3 %), δ = qL⁴/(8E'I) + qL²/(2κGt), κ = 5/6, E' the bending modulus of the slice: E/(1 −
/// ν²) in plane strain, E in plane stress.
double cantilever_tip_error(int cells, mpm::Plane plane) {
  mpm::CantileverSpec s;
  s.length = 10e-3;
  s.thickness = 1e-3;
  s.cells_through_thickness = cells;
  s.particles_per_cell = 2;
  s.material = {2e5, 4e6, 1000.0};
  s.gravity = Vec3(0, -9.81, 0);
  s.plane = plane;
  const double ep = studies::zhao_reference_modulus(
      plane == mpm::Plane::kStress ? studies::ZhaoModel::kPlaneStress : studies::ZhaoModel::kPlaneStrain, s.material);
  const double i = std::pow(s.thickness, 3) / 12.0, q = 1000.0 * 9.81 * s.thickness;
  const double omega = 3.516 / (s.length * s.length) * std::sqrt(ep * i / (1000.0 * s.thickness));
  s.damping = 2.0 * omega;
  const double expect = q * std::pow(s.length, 4) / (8.0 * ep * i) +
                        q * s.length * s.length / (2.0 * 5.0 / 6.0 * s.material.shear_modulus * s.thickness);
  mpm::Cantilever<2> beam = mpm::make_cantilever<2>(s);
  mpm::MpmWorkspace<2> ws;
  mpm::SettleOptions o;
  o.min_time = 0.02;
  o.max_time = 0.5;
  o.window = 0.01;
  o.tolerance = 1e-3 * expect;
  const mpm::SettleResult r = mpm::settle<2>(
      beam.model, beam.state, ws, [](double) { return mpm::AppliedField{}; }, beam.tip, o);
  EXPECT_TRUE(r.status.ok) << r.status.cause;
  EXPECT_TRUE(r.settled);
  const double tip = -mpm::mean_position(beam.state, beam.tip).y();
  std::printf("cantilever under gravity, plane %s, %d cells: tip %.5f mm, Timoshenko %.5f mm (%.2f %%), %ld steps\n",
              plane == mpm::Plane::kStress ? "stress" : "strain", cells, tip * 1e3, expect * 1e3,
              100.0 * (tip / expect - 1.0), r.steps);
  return tip / expect - 1.0;
}

TEST(MpmScene, ACantileverUnderGravityConvergesToTimoshenkosBeam) {
  // Plane strain. The MPM beam is too stiff by a few per cent at 3 cells through the thickness (the clamp's grid nodes
  // and the quadratic splines' bending); refining to 5 cells must shrink the error, to within 3.5 %.
  const double coarse = cantilever_tip_error(3, mpm::Plane::kStrain);
  const double fine = cantilever_tip_error(5, mpm::Plane::kStrain);
  std::printf("observed order %.2f\n", std::log(std::abs(coarse / fine)) / std::log(5.0 / 3.0));
  EXPECT_LT(std::abs(fine), std::abs(coarse));
  EXPECT_LT(std::abs(fine), 0.035);
}

TEST(MpmScene, APlaneStressCantileverUnderGravityBendsWithYoungsModulus) {
  // The same beam in plane stress (a sheet thin along z) bends with E, 29 % more than with E/(1 − ν²) for K = 20 G
  // (ν = 0.475): against Timoshenko with E, the error shrinking with refinement, within the plane-strain test's 3.5 %.
  // Measured (2026-12-06): +2.64 % at 3 cells, +1.13 % at 5 (slightly soft, where plane strain is stiff: −4.7, −2.8 %).
  const double coarse = cantilever_tip_error(3, mpm::Plane::kStress);
  const double fine = cantilever_tip_error(5, mpm::Plane::kStress);
  EXPECT_LT(std::abs(fine), std::abs(coarse));
  EXPECT_LT(std::abs(fine), 0.035);
}

TEST(MpmScene, TheZhaoBeamBucklesAsTheElasticaPredicts) {
  // Closed form first (notes §9 table): δ/L = 0.7952 at B̄ = 5, 0.6230 at B̄ = 10, straight below π²/4.
  EXPECT_NEAR(studies::antiparallel_elastica_deflection(5.0), 0.7952, 1e-4);
  EXPECT_NEAR(studies::antiparallel_elastica_deflection(10.0), 0.6230, 1e-4);
  EXPECT_EQ(studies::antiparallel_elastica_deflection(2.4), 0.0);
  // MPM at 10 mT (B̄ = 4.96), 3 cells through the thickness and 3 particles per cell per axis. The study (docs/mpm.md:
  // "MPM") measures −8.6 % here, −5.4 % at 4 particles per cell and −4.4 % at 4 cells; the tolerance, 12 %, only
  // guards that resolution, the study carries the accuracy claim.
  const studies::ZhaoPoint p = studies::run_zhao_beam(3, 3, 10e-3);
  std::printf("Zhao beam at 10 mT: delta/L %.4f, elastica %.4f (%.2f %%), %ld steps, %.1f s\n", p.deflection,
              p.reference, 100.0 * (p.deflection / p.reference - 1.0), p.steps, p.seconds);
  ASSERT_TRUE(p.ok);
  EXPECT_TRUE(p.settled);
  EXPECT_NEAR(p.deflection / p.reference, 1.0, 0.12);
}

TEST(MpmScene, TheStudysImplicitBeamRestsWhereItsExplicitOneDoes) {
  // `study mpm-beam --implicit R`: the same beam, total-Lagrangian frame, plane stress, 10 mT, explicit and at 50
  // explicit steps per step. Both rest at stationary points of one energy, so they differ only by what the rest test
  // leaves: it stops when the tip moved < 1e-4 L over 20 ms, and with the beam's decay (≈ 70 /s, damping 140 /s) the
  // distance still to go can be ~1.3e-4 L per run, so 5e-4 of δ/L bounds the pair. The implicit run needs at least 10
  // times fewer steps (issue 34's criterion). Measured 2026-12-07: 0.73660 both (128 930 and 2559 steps); the elastica
  // with E 0.74534, −1.2 %; 3 % bounds the 3 × 2 resolution's error (plane strain's mean at 3 × 2: 1.4 %,
  // docs/validation.md).
  constexpr double kRestSpread = 5e-4;
  constexpr double kResolutionError = 0.03;
  const studies::ZhaoPoint e = studies::run_zhao_beam(3, 2, 10e-3, studies::ZhaoModel::kPlaneStress, true);
  const studies::ZhaoPoint i = studies::run_zhao_beam(3, 2, 10e-3, studies::ZhaoModel::kPlaneStress, true, 50.0);
  std::printf("Zhao beam, plane stress, 10 mT: explicit %.5f in %ld steps (%.1f s), implicit x%.0f %.5f in %ld steps "
              "(%ld Newton, %ld CG; %.1f s), elastica %.5f\n",
              e.deflection, e.steps, e.seconds, i.step_ratio, i.deflection, i.steps, i.newton, i.cg, i.seconds,
              e.reference);
  ASSERT_TRUE(e.ok) << e.failure;
  ASSERT_TRUE(i.ok) << i.failure;
  EXPECT_TRUE(e.settled && i.settled);
  EXPECT_NEAR(i.deflection, e.deflection, kRestSpread);
  EXPECT_LE(10 * i.steps, e.steps);
  EXPECT_GT(i.newton, 0);
  EXPECT_NEAR(e.deflection / e.reference, 1.0, kResolutionError);
}

TEST(MpmScene, StiffAndSoftBeamsRunStablyWithTheAutomaticStep) {
  // G from 10 kPa to 10 MPa (the issue's extremes): 3000 automatic steps of the 60 × 3 × 3 mm beam under gravity
  // and 10 mT across it; nothing may fail, and the clamp must hold.
  for (const double g : {1e4, 1e7}) {
    mpm::CantileverSpec s;
    s.length = 20e-3;
    s.thickness = 3e-3;
    s.width = 3e-3;
    s.cells_through_thickness = 3;
    s.particles_per_cell = 2;
    s.material = {g, 20.0 * g, 1882.0};
    s.remanence = Vec3(0.125, 0, 0);
    s.gravity = Vec3(0, -9.81, 0);
    s.damping = 20.0;
    mpm::Cantilever<3> beam = mpm::make_cantilever<3>(s);
    mpm::MpmWorkspace<3> ws;
    mpm::AppliedField f;
    f.kind = mpm::AppliedField::Kind::kUniform;
    f.uniform = Vec3(0, 10e-3, 0);
    const double dt = beam.model.stable_step(0.4);
    for (int k = 0; k < 3000; ++k) {
      const mpm::StepStatus st = mpm::step(beam.model, f, beam.state, ws, dt);
      ASSERT_TRUE(st.ok) << "G = " << g << ": " << st.cause;
    }
    double root = 0.0;  // the clamped material stays put
    for (std::size_t p = 0; p < beam.model.size(); ++p) {
      if (beam.model.section[p] == 0) root = std::max(root, beam.state.v[p].norm());
    }
    std::printf("G = %.0e Pa: dt %.2e s, %.3f ms simulated, tip y %.4f mm\n", g, dt, 3000 * dt * 1e3,
                mpm::mean_position(beam.state, beam.tip).y() * 1e3);
    EXPECT_LT(root * dt, 1e-6 * s.length);
  }
}

TEST(MpmScene, AStepAboveTheBoundIsCaughtAndNamed) {
  mpm::CantileverSpec s;
  s.length = 10e-3;
  s.thickness = 1e-3;
  s.material = {1e5, 2e6, 1000.0};
  s.gravity = Vec3(0, -9.81, 0);
  mpm::Cantilever<2> beam = mpm::make_cantilever<2>(s);
  mpm::MpmWorkspace<2> ws;
  const double dt = 6.0 * beam.model.stable_step(1.0);
  mpm::StepStatus st;
  for (int k = 0; k < 2000 && st.ok; ++k) st = mpm::step(beam.model, mpm::AppliedField{}, beam.state, ws, dt);
  ASSERT_FALSE(st.ok);
  EXPECT_NE(st.cause.find("particle"), std::string::npos) << st.cause;
  std::printf("6x the CFL step: %s\n", st.cause.c_str());
}

TEST(MpmScene, ImplicitStepsHalveWhereOneFailsAndEndAtTheDuration) {
  // A block falling freely for 0.1 s in steps of 50 ms: the first step would move it ~25 cells (g Δt² = 24.5 mm, cells
  // of 1 mm), so the runner halves it until a step moves less than a cell, and grows it back. Free fall under the
  // explicit step's symplectic Euler with steps h_k falls Σ_k h_k t_k (t_k the time at each step's end); the runner's
  // steps are not known in advance, so the check is the exact free fall ½ g t² within the first-order error of the
  // largest step it kept, g h t / 2 ≤ 2.5 mm, and the run's end at the duration.
  const std::string scene = R"(
units: {length: mm}
mpm:
  dimension: 2
  cell: 1.0
  duration: 0.1
  step: implicit
  time_step: 0.05
  gravity: [0, -9.81, 0]
  domain: {min: [-10, -100, 0], max: [10, 10, 0]}
bodies:
  - name: block
    shape: box
    min: [-2, -2, 0]
    max: [2, 2, 0]
    material: {shear_modulus: 10000, density: 1000}
probes:
  - {name: centre, at: [0, 0, 0], radius: 1}
)";
  const MpmScene sc = parse_mpm_scene(scene, "fall.yaml");
  const MpmResult r = run_mpm_scene(sc);
  ASSERT_TRUE(r.ok) << r.failure;
  EXPECT_GT(r.retries, 0);
  EXPECT_NEAR(r.time, 0.1, 1e-12);  // the summed steps, to round-off
  const double fell = r.samples.front().probes[0].y() - r.samples.back().probes[0].y();
  std::printf("implicit free fall: %ld steps, %ld retried, fell %.3f mm (1/2 g t^2 = %.3f mm)\n", r.steps, r.retries,
              fell * 1e3, 0.5 * 9.81 * 0.01 * 1e3);
  EXPECT_NEAR(fell, 0.5 * 9.81 * 0.1 * 0.1, 0.5 * 9.81 * 0.05 * 0.1);
}

TEST(MpmScene, BadScenesNameTheKey) {
  const std::string ok = kBarScene;
  auto with = [&](const std::string& from, const std::string& to) {
    std::string t = ok;
    const auto at = t.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return t.replace(at, from.size(), to);
  };
  EXPECT_EQ(error_of(ok), "");
  EXPECT_NE(error_of(with("  damping: 400", "  damping: 400\n  time_step: 0.01"))
                .find("mpm.time_step: is above the stable step"),
            std::string::npos);
  EXPECT_NE(error_of(with("shear_modulus: 33000", "shear_modulus: -1")).find("bodies[0].material.shear_modulus"),
            std::string::npos);
  EXPECT_NE(error_of(with("  damping: 400", "  dampign: 400")).find("damping"), std::string::npos);
  EXPECT_NE(error_of(with("to: [0, 0, 140]", "to: [0, 0, 160]")).find("domain"), std::string::npos);
  EXPECT_NE(error_of(with("{name: bottom, at: [0, 0, 100.25], radius: 0.6}", "{name: b, at: [9, 9, 9]}"))
                .find("probes[0].at"),
            std::string::npos);
  EXPECT_NE(error_of(with("dimension: 3", "dimension: 4")).find("mpm.dimension"), std::string::npos);
  EXPECT_NE(error_of(with("dimension: 3", "dimension: 3\n  plane: stress")).find("mpm.plane: is for dimension: 2"),
            std::string::npos);
  // A moving clamp cannot be watched for rest; `side` and `file` belong to mesh obstacles.
  EXPECT_NE(error_of(with("138], max: [12, 12, 150]}", "138], max: [12, 12, 150], velocity: [0, 0, -10]}"))
                .find("mpm.settle: cannot stop a run whose clamp moves"),
            std::string::npos);
  EXPECT_NE(error_of(ok + "obstacles:\n  - {shape: sphere, centre: [0, 0, 0], radius: 5, side: inside}\n")
                .find("obstacles[0].side: is for shape: mesh only"),
            std::string::npos);
  // Implicit steps: any time_step, a Newton tolerance only with them, and the step's default 10 explicit ones.
  EXPECT_EQ(error_of(with("  damping: 400", "  damping: 400\n  time_step: 0.01\n  step: implicit")), "");
  EXPECT_NE(error_of(with("  damping: 400", "  damping: 400\n  step: semi")).find("mpm.step"), std::string::npos);
  EXPECT_NE(error_of(with("  damping: 400", "  damping: 400\n  newton_tolerance: 1e-6"))
                .find("mpm.newton_tolerance: is for step: implicit only"),
            std::string::npos);
  // The total-Lagrangian frame: updated or total only, and no obstacles yet.
  EXPECT_NE(error_of(with("  damping: 400", "  damping: 400\n  frame: lagrange")).find("mpm.frame"), std::string::npos);
  EXPECT_NE(error_of(with("  damping: 400", "  damping: 400\n  frame: total") +
                     "obstacles:\n  - {shape: sphere, centre: [0, 0, 0], radius: 5}\n")
                .find("mpm.frame: total takes no obstacles yet"),
            std::string::npos);
  std::string walled = with("max: [12, 12, 150]}\n  settle", "max: [12, 12, 150], walls: slip}\n  settle");
  walled.replace(walled.find("  damping: 400"), 14, "  damping: 400\n  frame: total");
  EXPECT_NE(error_of(walled).find("mpm.domain.walls: is for frame: updated"), std::string::npos);
  EXPECT_TRUE(parse_mpm_scene(with("  damping: 400", "  damping: 400\n  frame: total"), "s.yaml").total_lagrangian);
  EXPECT_FALSE(parse_mpm_scene(ok, "s.yaml").total_lagrangian);
  const MpmScene implicit = parse_mpm_scene(with("  damping: 400", "  damping: 400\n  step: implicit"), "s.yaml");
  EXPECT_TRUE(implicit.implicit);
  EXPECT_DOUBLE_EQ(implicit.time_step, 10.0 * implicit.stable_step);
}

TEST(MpmScene, AFieldRampedThenRotatedFollowsTheKeyframesThenTurns) {
  // field: keyframes and a rotating field with `from`: the keyframes' linear ramp before `from` (hand values), then a
  // field of the rotation's amplitude turning about its axis from `start`: a quarter turn after `from` it points
  // along axis × start, half a turn later opposite `start`; the schedule is continuous at `from` when the ramp ends
  // on the rotation's start (here 10 mT along z).
  const std::string text =
      std::string(kBarScene) +
      "field:\n  keyframes: [{t: 0, b: [0, 0, 0]}, {t: 0.1, b: [0, 0, 0.01]}]\n"
      "  rotating: {amplitude: 0.01, frequency: 10, axis: [0, 1, 0], start: [0, 0, 1], from: 0.15}\n";
  const MpmScene s = parse_mpm_scene(text, "s.yaml");
  const auto near = [](const Vec3& a, const Vec3& b) { return (a - b).norm() < 1e-12; };
  EXPECT_TRUE(near(s.field.at(0.05), Vec3(0, 0, 0.005)));   // half way up the ramp
  EXPECT_TRUE(near(s.field.at(0.12), Vec3(0, 0, 0.01)));    // held
  EXPECT_TRUE(near(s.field.at(0.15), Vec3(0, 0, 0.01)));    // the rotation starts where the ramp ends
  EXPECT_TRUE(near(s.field.at(0.175), Vec3(0.01, 0, 0)));   // a quarter turn: y × z = x
  EXPECT_TRUE(near(s.field.at(0.2), Vec3(0, 0, -0.01)));    // half a turn
  // Without `from` the two kinds still exclude each other; `from` before the last keyframe is refused.
  std::string both = text;
  both.replace(both.find(", from: 0.15"), 12, "");
  EXPECT_NE(error_of(both).find("give exactly one of"), std::string::npos);
  std::string constant = text;  // a constant b and a rotation do not combine, `from` or not
  const std::string ramp = "keyframes: [{t: 0, b: [0, 0, 0]}, {t: 0.1, b: [0, 0, 0.01]}]";
  constant.replace(constant.find(ramp), ramp.size(), "b: [0, 0, 0.01]");
  EXPECT_NE(error_of(constant).find("give exactly one of"), std::string::npos);
  std::string early = text;
  early.replace(early.find("from: 0.15"), 10, "from: 0.05");
  EXPECT_NE(error_of(early).find("field.rotating.from: must not come before the last keyframe"), std::string::npos);
}

/// A folder of its own under the system's temporary folder for one test's files.
std::filesystem::path scratch(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("magvine_test_mpm_scene_" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

// A soft 40 × 3 × 3 mm cantilever (G 20 kPa) sagging under gravity onto a floor 4.5 mm below its axis, slip: it lies
// on the floor over most of its length. The floor is OBSTACLE, between two layers of grid nodes (a surface through a
// layer is a knife edge: an STL's single-precision vertices may put it a hair above or below those nodes).
constexpr const char* kFloorScene = R"(
units: {length: mm}
mpm:
  dimension: 3
  cell: 1.0
  particles_per_cell: 2
  duration: 1.5
  damping: 30
  gravity: [0, 0, -9.81]
  domain: {min: [-6, -10, -10], max: [50, 10, 10]}
  settle: {window: 0.05, tolerance: 0.005}
bodies:
  - name: beam
    shape: box
    min: [-2, -1.5, -1.5]
    max: [40, 1.5, 1.5]
    material: {shear_modulus: 20000, density: 1000}
clamps:
  - {min: [-6, -10, -10], max: [0, 10, 10]}
obstacles:
  - OBSTACLE
probes:
  - {name: x10, at: [10, 0, 0], radius: 1}
  - {name: x20, at: [20, 0, 0], radius: 1}
  - {name: x30, at: [30, 0, 0], radius: 1}
  - {name: tip, at: [39.75, 0, 0], radius: 1}
)";

TEST(MpmScene, AMeshFloorHoldsABeamAsTheAnalyticPlaneDoes) {
  // The same floor as an analytic half-space and as a mesh (two triangles, an open mesh: signed by its normal),
  // sampled on the grid: the beam's rest shape (four probes along it) the same within 1 % of how far each moved.
  const std::filesystem::path dir = scratch("floor");
  anatomy::TriangleMesh floor;
  floor.vertices = {Vec3(-0.02, -0.03, -0.0045), Vec3(0.06, -0.03, -0.0045), Vec3(0.06, 0.03, -0.0045),
                    Vec3(-0.02, 0.03, -0.0045)};
  floor.triangles = {{0, 1, 2}, {0, 2, 3}};  // outward normal +z: the solid below
  anatomy::write_stl(dir / "floor.stl", floor);
  const auto run = [&](const std::string& obstacle) {
    std::string text = kFloorScene;
    text.replace(text.find("OBSTACLE"), 8, obstacle);
    const MpmScene sc = parse_mpm_scene(text, "floor.yaml", dir);
    const MpmResult r = run_mpm_scene(sc);
    EXPECT_TRUE(r.ok) << r.failure;
    EXPECT_TRUE(r.settled);
    return r;
  };
  const MpmResult plane = run("{shape: plane, point: [0, 0, -4.5], normal: [0, 0, 1], boundary: slip}");
  const MpmResult mesh = run("{shape: mesh, file: floor.stl, boundary: slip}");
  const std::vector<Vec3>& start = plane.samples.front().probes;
  for (std::size_t q = 0; q < start.size(); ++q) {
    const Vec3 moved = plane.samples.back().probes[q] - start[q];
    const Vec3 differ = mesh.samples.back().probes[q] - plane.samples.back().probes[q];
    std::printf("probe %zu: moved %.4f mm on the plane, the mesh's %.6f mm away\n", q, moved.norm() * 1e3,
                differ.norm() * 1e3);
    EXPECT_LT(differ.norm(), 0.01 * moved.norm()) << "probe " << q;
  }
  // The floor held the tip: its centre rests above the floor by half the thickness and the grid boundary's offset
  // (the particles' stencil meets the nodes in the floor up to a cell and a half early), not lower.
  const double above = mesh.samples.back().probes[3].z() - (-4.5e-3 + 1.5e-3);
  EXPECT_GT(above, 0.0);
  EXPECT_LT(above, 2e-3);
}

TEST(MpmScene, ARodPushedIntoTheYPhantomStaysInsideIt) {
  // A Ø3 × 30 mm rod (G 30 kPa) in the generated Y phantom's parent tube (Ø12 mm along +x, the bifurcation at
  // x = 66 mm, daughters Ø9.5 mm at ±35° in x–y), 1.5 mm to −y of the axis, its base clamp pushed along +x at 0.2 m/s
  // for 0.25 s (50 mm): the tip meets the carina's −y face and slides into the −y daughter. The lumen is an obstacle
  // `side: inside` (the mesh closed, signed by ray parity), slip. The body stays in the lumen: every particle at every
  // snapshot, to the grid's resolution of the wall — a particle may sit up to half a cell past it (its stencil's nodes
  // in the wall stop it there; the analytic obstacles do the same), none farther.
  const std::filesystem::path dir = scratch("y_phantom");
  const anatomy::Phantom y = anatomy::make_y_bifurcation({});
  anatomy::write_stl(dir / "y.stl", y.mesh);
  const MpmScene sc = parse_mpm_scene(R"(
units: {length: mm}
mpm:
  dimension: 3
  cell: 1.0
  particles_per_cell: 2
  duration: 0.25
  damping: 20
  domain: {min: [0, -60, -15], max: [130, 60, 15]}
  snapshots: 0.025
bodies:
  - name: rod
    shape: cylinder
    from: [3, -1.5, 0]
    to: [33, -1.5, 0]
    radius: 1.5
    material: {shear_modulus: 30000, density: 1100}
clamps:
  - {min: [2, -3.5, -2], max: [6, 0.5, 2], velocity: [200, 0, 0]}
obstacles:
  - {name: lumen, shape: mesh, file: y.stl, side: inside, boundary: slip}
probes:
  - {name: tip, at: [33, -1.5, 0], radius: 1}
)",
                                      "y_rod.yaml", dir);
  const MpmResult r = run_mpm_scene(sc);
  ASSERT_TRUE(r.ok) << r.failure;
  const anatomy::CollisionWorld lumen(y.mesh);
  std::size_t outside = 0, checked = 0;
  double deepest = 0.0;
  for (const auto& [t, x] : r.snapshots) {
    for (const Vec3& p : x) {
      ++checked;
      if (lumen.contains(p)) continue;
      ++outside;
      anatomy::NearTriangle near[1];
      deepest = std::max(deepest, lumen.triangles_within(p, 1.0, near) > 0 ? near[0].distance : 1.0);
    }
  }
  const Vec3 tip = r.samples.back().probes[0];
  std::printf(
      "rod pushed into the Y phantom: tip at (%.1f, %.1f, %.1f) mm after %.2f s; %zu of %zu particle "
      "positions outside the lumen, the deepest %.3f mm; %ld steps, %.1f s\n",
      tip.x() * 1e3, tip.y() * 1e3, tip.z() * 1e3, r.time, outside, checked, deepest * 1e3, r.steps, r.runtime_s);
  EXPECT_LT(deepest, 0.5e-3);
  EXPECT_GT(tip.x(), 0.070);   // past the bifurcation
  EXPECT_LT(tip.y(), -0.004);  // in the −y daughter (its axis at y = −0.70 (x − 66 mm))
}

TEST(MpmScene, EveryBundledMpmSceneLoads) {
  int n = 0;
  for (const auto& entry : std::filesystem::directory_iterator(std::string(MAGVINE_SOURCE_DIR) + "/assets/scenes")) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("mpm_", 0) != 0) continue;
    EXPECT_NO_THROW(load_mpm_scene(entry.path())) << name;
    EXPECT_TRUE(is_mpm_scene(entry.path())) << name;
    ++n;
  }
  EXPECT_GE(n, 4);
}

TEST(MpmScene, ADesignWrittenAsAnMpmSceneCarriesItsSections) {
  // `magvine design --mpm-check` (issue 29): the bundled catheter design with five known directions, as an MPM scene:
  // every particle of the rod past the clamp carries its section's B̃r = Br R_base d_s, the clamp's particles none, and
  // a probe sits at each target point past the base.
  const DesignScene d = load_design_scene(std::string(MAGVINE_SOURCE_DIR) + "/assets/scenes/design_catheter.yaml");
  design::Design design;
  for (int s = 0; s < 5; ++s) {
    design.directions.push_back(Vec3(std::cos(s), std::sin(s), 0.1 * s).normalized());
    design.remanences.push_back(0.125);
  }
  const MpmScene m = parse_mpm_scene(design_mpm_scene_yaml(d, design, 1e-3, 2), "design-check.yaml");
  ASSERT_EQ(m.dimension, 3);
  EXPECT_EQ(m.probes.size(), 8u);
  const double length = d.problem.model.length;
  int magnetised = 0;
  for (std::size_t i = 0; i < m.positions.size(); ++i) {
    const double s = m.positions[i].x();  // the base at the origin, along x
    const Vec3& br = m.model3.remanence[i];
    if (s < 0.0) {
      EXPECT_TRUE(br.isZero()) << "a clamp particle at " << s;
      continue;
    }
    const auto section = static_cast<std::size_t>(std::min(4.0, std::floor(s / length * 5.0)));
    EXPECT_LT((br - 0.125 * design.directions[section]).norm(), 1e-12) << "particle at " << s;
    ++magnetised;
  }
  EXPECT_GT(magnetised, 1000);
  // The clamp holds the grid behind the base only (padded along the axis as well, it once held 3 mm of the free rod).
  ASSERT_EQ(m.model3.clamps.size(), 1u);
  EXPECT_LE(m.model3.clamps[0].max.x(), 1e-12);
  EXPECT_GT(m.model3.clamps[0].max.y(), 0.002);  // and across it, the whole section
  for (std::size_t k = 0; k < m.probes.size(); ++k) {
    EXPECT_NEAR(m.probes[k].at.x(), length * static_cast<double>(k + 1) / 8.0, 1e-12);
  }
}

}  // namespace
}  // namespace magvine::scene
