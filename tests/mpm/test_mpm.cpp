// MLS-MPM solver: exact transfers (translation, rigid rotation, free fall), the stress law against finite
// differences, a cantilever under gravity against Euler–Bernoulli, stability of stiff and soft materials with the
// automatic step, and failure detection.

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <cstdio>

#include "magvine/core/units.hpp"
#include "magvine/mpm/mpm.hpp"
#include "magvine/mpm/sampling.hpp"

namespace magvine::mpm {
namespace {

constexpr double kCourant = 0.4;

template <int D>
VecD<D> cut(const Vec3& x) {
  if constexpr (D == 2) return VecD<D>(x.x(), x.y());
  else return x;
}

/// A block of one material sampled at `ppc` particles per cell per axis, in a large domain.
template <int D>
std::pair<MpmModel<D>, MpmState<D>> block(const Vec3& min, const Vec3& max, double cell, int ppc,
                                           const Material& mat) {
  MpmModel<D> model;
  model.cell = cell;
  model.domain_min = VecD<D>::Constant(-1.0);
  model.domain_max = VecD<D>::Constant(1.0);
  model.materials = {mat};
  LatticeOptions lattice;
  lattice.spacing = cell / ppc;
  const std::vector<Vec3> points = sample_box(min, max, lattice, D);
  std::vector<VecD<D>> x;
  const double v0 = std::pow(lattice.spacing, D);
  for (const Vec3& p : points) {
    x.push_back(cut<D>(p));
    model.volume.push_back(v0);
    model.mass.push_back(mat.density * v0);
    model.remanence.push_back(VecD<D>::Zero());
    model.material.push_back(0);
    model.section.push_back(0);
  }
  return {model, rest_state<D>(x)};
}

Material silicone(double g = 1e5) { return {g, 20.0 * g, 1000.0}; }

TEST(MpmTransfers, UniformTranslationIsExactIn2DAnd3D) {
  // B-spline weights sum to one and their first moments vanish, so a uniform velocity survives P2G/G2P exactly,
  // C stays zero and F stays I.
  auto check = [](auto model_state, auto vel) {
    auto& [model, state] = model_state;
    using V = std::decay_t<decltype(vel)>;
    for (auto& v : state.v) v = vel;
    const auto x0 = state.x;
    MpmWorkspace<V::RowsAtCompileTime> ws;
    const double dt = model.stable_step(kCourant);
    const int steps = 200;
    for (int s = 0; s < steps; ++s) ASSERT_TRUE(step(model, AppliedField{}, state, ws, dt).ok);
    double worst = 0.0;
    for (std::size_t p = 0; p < state.x.size(); ++p) {
      worst = std::max(worst, (state.x[p] - (x0[p] + steps * dt * vel)).norm());
      worst = std::max(worst, (state.v[p] - vel).norm() * dt);
      worst = std::max(worst, (state.f[p] - std::decay_t<decltype(state.f[p])>::Identity()).norm() * model.cell);
    }
    EXPECT_LT(worst, 1e-15) << "worst position/velocity/F error in metres";
  };
  check(block<2>(Vec3(0, 0, 0), Vec3(0.01, 0.004, 0), 1e-3, 2, silicone()), Eigen::Vector2d(0.3, -0.2));
  check(block<3>(Vec3(0, 0, 0), Vec3(0.006, 0.004, 0.003), 1e-3, 2, silicone()), Vec3(0.3, -0.2, 0.1));
}

TEST(MpmTransfers, RigidRotationKeepsItsAngularMomentumAndTurnsRigidly) {
  // APIC/MLS transfers conserve angular momentum exactly, counting the spin each particle's affine field carries:
  // L = Σ m (x × v) + m (δx²/4)(C₁₀ − C₀₁) in 2D (Jiang et al. 2015). A stiff disc spun at ω must keep L to
  // round-off and turn by ωt as one body: what remains is the O(Δt) stretch the F update picks up and the
  // centrifugal strain ρω²r²/E ≈ 3e-5, both below the tolerance.
  auto [model, state] = block<2>(Vec3(-0.005, -0.005, 0), Vec3(0.005, 0.005, 0), 1e-3, 2, silicone(1e5));
  const double omega = 20.0;  // rad/s
  for (std::size_t p = 0; p < state.x.size(); ++p) {
    state.v[p] = omega * Eigen::Vector2d(-state.x[p].y(), state.x[p].x());
    state.c[p] << 0.0, -omega, omega, 0.0;
  }
  auto angular_momentum = [&] {
    double l = 0.0;
    for (std::size_t p = 0; p < state.x.size(); ++p) {
      const double m = model.mass[p];
      l += m * (state.x[p].x() * state.v[p].y() - state.x[p].y() * state.v[p].x()) +
           m * model.cell * model.cell / 4.0 * (state.c[p](1, 0) - state.c[p](0, 1));
    }
    return l;
  };
  const double l0 = angular_momentum();
  const auto x0 = state.x;
  MpmWorkspace<2> ws;
  const int n = 10000;
  const double dt = 0.5 * kPi / omega / n;  // a quarter turn
  ASSERT_LT(dt, model.stable_step(kCourant));
  for (int s = 0; s < n; ++s) ASSERT_TRUE(step(model, AppliedField{}, state, ws, dt).ok);
  const double turn = n * std::atan(omega * dt);  // the explicit position update turns by atan(ωΔt) per step
  double worst = 0.0;
  for (std::size_t p = 0; p < x0.size(); ++p) {
    const Eigen::Vector2d expect = Eigen::Rotation2Dd(turn).toRotationMatrix() * x0[p];
    worst = std::max(worst, (state.x[p] - expect).norm() / model.cell);
  }
  std::printf("quarter turn: L relative change %.2e, worst particle offset %.2e cells\n",
              (angular_momentum() - l0) / l0, worst);
  EXPECT_LT(std::abs(angular_momentum() - l0), 1e-12 * l0);
  EXPECT_LT(worst, 1e-2) << "particles off the rigid rotation, in cells";
}

TEST(MpmTransfers, FreeFallIsExact) {
  // Symplectic Euler on the grid: v_n = n g Δt, x_n = x0 + g Δt² n(n+1)/2, with no error but round-off.
  auto [model, state] = block<3>(Vec3(0, 0, 0), Vec3(0.004, 0.004, 0.004), 1e-3, 2, silicone());
  model.gravity = Vec3(0, 0, -9.81);
  const auto x0 = state.x;
  MpmWorkspace<3> ws;
  const double dt = model.stable_step(kCourant);
  const int n = 300;
  for (int s = 0; s < n; ++s) ASSERT_TRUE(step(model, AppliedField{}, state, ws, dt).ok);
  double worst = 0.0;
  for (std::size_t p = 0; p < x0.size(); ++p) {
    const Vec3 expect = x0[p] + model.gravity * dt * dt * n * (n + 1) / 2.0;
    worst = std::max(worst, (state.x[p] - expect).norm());
    worst = std::max(worst, (state.v[p] - model.gravity * dt * n).norm() * dt);
  }
  EXPECT_LT(worst, 1e-15);
}

TEST(MpmStress, NeoHookeanIsTheDerivativeOfItsEnergyAndFreeAtRest) {
  const Material m = silicone(3e5);
  Eigen::Matrix3d f3;
  f3 << 1.1, 0.2, -0.05, 0.03, 0.9, 0.1, -0.02, 0.15, 1.05;
  const Eigen::Matrix2d f2 = f3.topLeftCorner<2, 2>();
  auto fd = [&](auto f) {
    using M = decltype(f);
    M p;
    const double h = 1e-6;
    for (int i = 0; i < f.rows(); ++i)
      for (int j = 0; j < f.cols(); ++j) {
        M a = f, b = f;
        a(i, j) += h;
        b(i, j) -= h;
        p(i, j) = (strain_energy_density<M::RowsAtCompileTime>(m, a) -
                   strain_energy_density<M::RowsAtCompileTime>(m, b)) / (2 * h);
      }
    return p;
  };
  EXPECT_LT((elastic_stress<3>(m, f3) - fd(f3)).norm() / elastic_stress<3>(m, f3).norm(), 1e-8);
  EXPECT_LT((elastic_stress<2>(m, f2) - fd(f2)).norm() / elastic_stress<2>(m, f2).norm(), 1e-8);
  // Rest state stress free in both dimensions (the 2D law is the plane-strain restriction, F33 = 1).
  EXPECT_LT(elastic_stress<2>(m, Eigen::Matrix2d::Identity()).norm(), 1e-9);
  EXPECT_LT(elastic_stress<3>(m, Eigen::Matrix3d::Identity()).norm(), 1e-9);
}

TEST(MpmStress, KirchhoffStressIsPTimesFTransposeFromStrongCompressionToStrongExpansion) {
  // P2G uses τ = P Fᵀ formed without F⁻¹ and with a Newton inverse cube root instead of libm's cbrt. Reference: P from
  // F⁻ᵀ (Eigen's inverse) times Fᵀ, where P itself is checked against the finite-difference derivative of the energy
  // (which calls std::cbrt), over J from 1e−3 to 1e2. Tolerances: 1e−12 is round-off in the two formulas; 1e−6 is the
  // central difference's truncation at these step sizes.
  const Material m = silicone(3e5);
  Eigen::Matrix3d base;
  base << 1.1, 0.2, -0.05, 0.03, 0.9, 0.1, -0.02, 0.15, 1.05;
  for (const double scale : {0.1, 0.5, 1.0, 2.0, 4.6}) {
    const Eigen::Matrix3d f = scale * base;
    const Eigen::Matrix3d p = elastic_stress<3>(m, f);
    const Eigen::Matrix3d tau = kirchhoff_stress<3>(m, f);
    EXPECT_LT((tau - p * f.transpose()).norm() / tau.norm(), 1e-12) << "J = " << f.determinant();
    Eigen::Matrix3d fd;
    const double h = 1e-6 * scale;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        Eigen::Matrix3d a = f, b = f;
        a(i, j) += h;
        b(i, j) -= h;
        fd(i, j) = (strain_energy_density<3>(m, a) - strain_energy_density<3>(m, b)) / (2 * h);
      }
    EXPECT_LT((p - fd).norm() / p.norm(), 1e-6) << "J = " << f.determinant();
    const Eigen::Matrix2d f2 = f.topLeftCorner<2, 2>();
    const Eigen::Matrix2d p2 = elastic_stress<2>(m, f2);
    EXPECT_LT((kirchhoff_stress<2>(m, f2) - p2 * f2.transpose()).norm() / p2.norm(), 1e-12);
  }
}

TEST(MpmStress, PlaneStressFreesTheFacesAndIsTheDerivativeOfItsEnergy) {
  // Plane stress: the out-of-plane stretch λ makes the 3D law's τ33 vanish (checked on the 3D law itself at
  // diag(F2, λ), to round-off relative to |τ|), the in-plane block of that 3D τ is the 2D plane-stress τ, P is the
  // derivative of the reduced energy (central differences, 1e-6: their truncation), and the rest state is free.
  const Material m = silicone(3e5);
  Eigen::Matrix2d f2;
  f2 << 1.1, 0.2, 0.03, 0.9;
  for (const double scale : {0.7, 1.0, 1.3}) {
    const Eigen::Matrix2d f = scale * f2;
    const double lambda = plane_stress_stretch(m, f);
    Eigen::Matrix3d f3 = Eigen::Matrix3d::Zero();
    f3.topLeftCorner<2, 2>() = f;
    f3(2, 2) = lambda;
    const Eigen::Matrix3d tau3 = kirchhoff_stress<3>(m, f3);
    EXPECT_LT(std::abs(tau3(2, 2)), 1e-12 * tau3.norm()) << "scale " << scale;
    const Eigen::Matrix2d tau2 = kirchhoff_stress<2>(m, f, Plane::kStress);
    EXPECT_LT((tau3.topLeftCorner<2, 2>() - tau2).norm(), 1e-11 * tau2.norm()) << "scale " << scale;
    const Eigen::Matrix2d p = elastic_stress<2>(m, f, Plane::kStress);
    EXPECT_LT((tau2 - p * f.transpose()).norm(), 1e-12 * tau2.norm());
    Eigen::Matrix2d fd;
    const double h = 1e-6;
    for (int i = 0; i < 2; ++i)
      for (int j = 0; j < 2; ++j) {
        Eigen::Matrix2d a = f, b = f;
        a(i, j) += h;
        b(i, j) -= h;
        const double ea = strain_energy_density<2>(m, a, Plane::kStress);
        fd(i, j) = (ea - strain_energy_density<2>(m, b, Plane::kStress)) / (2 * h);
      }
    EXPECT_LT((p - fd).norm() / p.norm(), 1e-6) << "scale " << scale;
  }
  EXPECT_NEAR(plane_stress_stretch(m, Eigen::Matrix2d::Identity()), 1.0, 1e-15);
  EXPECT_LT(elastic_stress<2>(m, Eigen::Matrix2d::Identity(), Plane::kStress).norm(), 1e-9);
  EXPECT_TRUE(std::isnan(plane_stress_stretch(m, Eigen::Vector2d(-1.0, 1.0).asDiagonal())));  // inverted
}

TEST(MpmStress, SmallStrainModuliAreYoungsInPlaneStressAndThePlaneStrainModulusInPlaneStrain) {
  // Uniaxial tension along x with y free (P_yy = 0, found by bisection): in plane stress (z free too) σ/ε tends to
  // Young's modulus E = 9KG/(3K + G), in plane strain (z held) to E/(1 − ν²), ν = (3K − 2G)/(2(3K + G)): linear
  // elasticity's constants of the same K and G. ε = 1e-6: the nonlinear terms are O(ε) relative.
  const Material m = silicone(3e5);
  const double k = m.bulk_modulus, g = m.shear_modulus;
  const double e = 9.0 * k * g / (3.0 * k + g), nu = (3.0 * k - 2.0 * g) / (2.0 * (3.0 * k + g));
  const double eps = 1e-6;
  const auto modulus = [&](Plane plane) {
    double lo = 1.0 - 2.0 * eps, hi = 1.0;  // F_yy: contraction of at most ν ε < 2ε
    for (int i = 0; i < 200; ++i) {
      const double mid = 0.5 * (lo + hi);
      const Eigen::Matrix2d f = Eigen::Vector2d(1.0 + eps, mid).asDiagonal();
      (elastic_stress<2>(m, f, plane)(1, 1) > 0.0 ? hi : lo) = mid;
    }
    const Eigen::Matrix2d f = Eigen::Vector2d(1.0 + eps, 0.5 * (lo + hi)).asDiagonal();
    return elastic_stress<2>(m, f, plane)(0, 0) / eps;
  };
  EXPECT_NEAR(modulus(Plane::kStress) / e, 1.0, 1e-5);
  EXPECT_NEAR(modulus(Plane::kStrain) / (e / (1.0 - nu * nu)), 1.0, 1e-5);
}

TEST(MpmTransfers, ResultsDoNotDependOnTheThreadCount) {
  // P2G writes each node from one slab at a time in a fixed order, so 1 and 2 threads give the same bits.
  auto run = [](int threads) {
    omp_set_num_threads(threads);
    auto [model, state] = block<3>(Vec3(0, 0, 0), Vec3(0.02, 0.003, 0.003), 5e-4, 2, silicone());
    model.clamps.push_back({Vec3(-1, -1, -1), Vec3(0.001, 1, 1), Vec3::Zero()});
    model.gravity = Vec3(0, -9.81, 0);
    for (auto& br : model.remanence) br = Vec3(0.1, 0, 0);
    AppliedField f;
    f.kind = AppliedField::Kind::kUniform;
    f.uniform = Vec3(0, 0.02, 0);
    MpmWorkspace<3> ws;
    const double dt = model.stable_step(kCourant);
    for (int s = 0; s < 50; ++s) EXPECT_TRUE(step(model, f, state, ws, dt).ok);
    return state;
  };
  const MpmState<3> one = run(1), two = run(2);
  ASSERT_GT(one.x.size(), 4096u);  // large enough for the parallel loops to run in parallel
  for (std::size_t p = 0; p < one.x.size(); ++p) {
    ASSERT_EQ(one.x[p], two.x[p]) << p;
    ASSERT_EQ(one.f[p], two.f[p]) << p;
  }
  omp_set_num_threads(1);
}

}  // namespace
}  // namespace magvine::mpm
