// The rod's energy terms one by one (src/robot/src/terms/): each term's gradient against central differences of its
// own energy, and its Hessian against central differences of its own gradient, on a bent, twisted, slightly
// stretched rod or vine with every load a term reads (a dipole field, gravity, tip loads, an inertial prediction,
// anchors, friction, the wall barrier). The whole rod's derivatives are checked in test_rod and test_vine; here a term
// that is wrong cannot hide behind a stiffer one.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "magvine/anatomy/collision_world.hpp"
#include "magvine/magnetics/field_function.hpp"
#include "magvine/robot/vine.hpp"
#include "rod_terms.hpp"
#include "support/rod_derivatives.hpp"

namespace magvine::robot::detail {
namespace {

/// A term's energy and gradient at state s.
template <class Term>
double term_energy(const TermContext& c, System* sys) {
  double e = 0.0;
  Term::add_energy(c, e, sys);
  return e;
}

using testing::moved_state;

/// The inputs every term reads, kept alive for the contexts.
struct TermSetup {
  RodModel model;
  RodField field;
  RodState state;
  Inertia inertia;
  RodConstraints constraints;
};

TermSetup make_setup(bool vine) {
  TermSetup s;
  const int edges = 6;
  if (vine) {
    VineParameters v = thesis_skin_mvr(60e-3, edges);
    v.fill = FillKind::kMagneticFluid;
    s.model = vine_rod(v);
  } else {
    s.model = testing::acceptance_rod(Vec3(1.0, 0.3, 0.0), edges);
    s.model.tip_moment = Vec3(1e-4, -2e-4, 3e-4);
    for (int j = 0; j < edges; ++j) s.model.rest_strain.push_back(Vec3(0.5, -1.0, 2.0) * (j + 1));
  }
  // Stretch and shear as soft as the bending, so their derivatives are of the same size as the rest (not a
  // requirement of the check, which is per term, but it keeps the differences' round-off small).
  const double h = s.model.length / s.model.edges;
  s.model.axial_stiffness = s.model.bending_stiffness_3 / (h * h);
  s.model.shear_stiffness = s.model.axial_stiffness;
  s.model.gravity = Vec3(0.5, -9.81, 1.0);
  s.model.tip_force = Vec3(1e-3, 2e-3, -1e-3);
  magnetics::FieldModel magnets;
  magnets.add(magnetics::DipoleSource{Vec3(0.0, 0.0, 300.0)},
              magnetics::Pose::from_axis(Vec3(0.04, -0.05, 0.02), Vec3(0.2, 1.0, 0.1)));
  s.field = magnetics::field_function(magnets, magnets.rest_poses);
  s.state = straight_rod(s.model);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (std::size_t j = 0; j < s.state.frames.size(); ++j) {
    // Joints in a vine's linear, wrinkled and creased ranges; a rod bent and twisted.
    const double angle = vine ? (j % 3 == 0 ? 1e-4 : (j % 3 == 1 ? 0.05 : 0.8)) : 0.3;
    s.state.frames[j] = Eigen::AngleAxisd(angle, Vec3(u(rng), u(rng), u(rng)).normalized()).toRotationMatrix() *
                        (j > 0 ? s.state.frames[j - 1] : s.state.frames[j]);
    s.state.x[j + 1] = s.state.x[j] + h * s.state.frames[j].col(0) + 0.02 * h * Vec3(u(rng), u(rng), u(rng));
  }
  // An inertial prediction near the state, anchors with unit and short normals, friction.
  s.inertia.dt = 1e-2;
  s.inertia.rotational = 1e-9;
  for (std::size_t i = 0; i < s.state.x.size(); ++i) {
    s.inertia.x.push_back(s.state.x[i] + 1e-4 * Vec3(u(rng), u(rng), u(rng)));
    s.inertia.mass.push_back(1e-4 * (1.0 + 0.1 * i));
  }
  for (const Mat3& r : s.state.frames) {
    s.inertia.frames.push_back(Eigen::AngleAxisd(0.05, Vec3(u(rng), u(rng), u(rng)).normalized()).toRotationMatrix() * r);
  }
  const double k = 100.0 * s.model.bending_stiffness_3 / (h * h * h);
  for (int i = 1; i <= edges; ++i) {
    const Vec3 n = Vec3(u(rng), u(rng), u(rng)).normalized();
    s.constraints.anchors.push_back(
        {i, s.state.x[static_cast<std::size_t>(i)] + 1e-4 * Vec3(u(rng), u(rng), u(rng)), (i % 2 == 0 ? 1.0 : 0.4) * n, k});
    // Friction: static (slip below ε) at odd nodes, sliding at even ones (slips of ~0.1 mm: the finite differences'
    // steps stay far from the kink of |u| at 0; with 0.01 mm, sliding node 2's gradient missed its differences by
    // 1.5e-6 relative once the wall planes no longer raised the gradient's scale).
    const double slip = i % 2 == 1 ? 1e-3 : 1e-6;
    s.constraints.friction.push_back(
        {i, s.state.x[static_cast<std::size_t>(i)] + 1e-4 * Vec3(u(rng), u(rng), u(rng)), n, 0.05 * i, 0.3, slip});
  }
  // The growth law on the tip edge (TipGrowth), its limit inside the tip edge's extension so the tether branch is
  // read too; the tip edge 1.2 h long.
  s.model.tip_edge_length = 1.2 * h;
  s.model.length += 0.2 * h;
  s.state.x.back() += 0.23 * h * s.state.frames.back().col(0);
  const double extension = s.state.frames.back().col(0).dot(s.state.x.back() - s.state.x[s.state.x.size() - 2]) -
                           1.2 * h;
  s.constraints.growth = TipGrowth{0.2, 50.0, 0.5 * extension};
  // A contact ahead of the tip (a needle's tissue, TipContact): 1 mm deep along an axis off the tip's tangent, a
  // convex law F = 300 N/m · d + 40 N/m² · d² (smooth there).
  TipContact tissue;
  tissue.axis = Vec3(0.3, -0.2, 1.0).normalized();
  tissue.origin = s.state.x.back() - 0.4e-3 * tissue.axis;
  tissue.depth = 0.6e-3;
  tissue.law = [](double d) {
    return ContactLaw{150.0 * d * d + 40.0 / 3.0 * d * d * d, 300.0 * d + 40.0 * d * d, 300.0 + 80.0 * d};
  };
  s.constraints.tip_contact = tissue;
  return s;
}

template <class Term>
void expect_term_derivatives(const TermSetup& s, const std::string& label) {
  const int n = s.model.edges;
  const auto context = [&](const RodState& state) {
    return TermContext{s.model, s.field, state, 0.8, &s.inertia, &s.constraints, nullptr};
  };
  System analytic(n);
  const double e0 = term_energy<Term>(context(s.state), &analytic);
  ASSERT_TRUE(std::isfinite(e0)) << label;
  Term::add_hessian(context(s.state), analytic);
  const double g_scale = analytic.gradient.cwiseAbs().maxCoeff();
  const VecX& g = analytic.gradient;
  for (Eigen::Index k = 0; k < g.size(); ++k) {
    const double step = (k % 6) >= 3 ? 1e-6 : 1e-8;
    // Gradient: central differences of the term's energy.
    const RodState plus = moved_state(s.state, k, step);
    const RodState minus = moved_state(s.state, k, -step);
    const double fd = (term_energy<Term>(context(plus), nullptr) - term_energy<Term>(context(minus), nullptr)) /
                      (2.0 * step);
    EXPECT_NEAR(g[k], fd, 1e-6 * std::abs(fd) + 1e-8 * g_scale) << label << ": gradient, unknown " << k;
  }
  // The Hessian: central differences of the term's gradient, symmetrised (with world-frame rotation increments the
  // derivative of the gradient differs from the Hessian by an antisymmetric part), against the analytic blocks
  // entry by entry.
  MatX fd_h(g.size(), g.size());
  for (Eigen::Index k = 0; k < g.size(); ++k) {
    const double step = (k % 6) >= 3 ? 1e-6 : 1e-8;
    System gp(n, false);
    System gm(n, false);
    (void)term_energy<Term>(context(moved_state(s.state, k, step)), &gp);
    (void)term_energy<Term>(context(moved_state(s.state, k, -step)), &gm);
    fd_h.col(k) = (gp.gradient - gm.gradient) / (2.0 * step);
  }
  fd_h = (0.5 * (fd_h + fd_h.transpose())).eval();
  MatX h(g.size(), g.size());
  h.setZero();
  for (Eigen::Index j = 0; j < n; ++j) {
    const Mat6 d = analytic.diag[static_cast<std::size_t>(j)].selfadjointView<Eigen::Lower>();
    h.block<6, 6>(6 * j, 6 * j) = d;
    if (j > 0) {
      h.block<6, 6>(6 * j, 6 * (j - 1)) = analytic.sub[static_cast<std::size_t>(j)];
      h.block<6, 6>(6 * (j - 1), 6 * j) = analytic.sub[static_cast<std::size_t>(j)].transpose();
    }
  }
  const double h_scale = fd_h.cwiseAbs().maxCoeff();
  for (Eigen::Index i = 0; i < g.size(); ++i) {
    for (Eigen::Index k = 0; k < g.size(); ++k) {
      EXPECT_NEAR(h(i, k), fd_h(i, k), 1e-5 * std::abs(fd_h(i, k)) + 1e-7 * h_scale)
          << label << ": Hessian entry (" << i << ", " << k << ")";
    }
  }
}

template <class Term>
void expect_for_rod_and_vine(const std::string& name) {
  for (const bool vine : {false, true}) {
    const TermSetup s = make_setup(vine);
    expect_term_derivatives<Term>(s, name + (vine ? " (vine)" : " (rod)"));
  }
}

TEST(RodTerms, StretchShear) { expect_for_rod_and_vine<StretchShear>("stretch-shear"); }
TEST(RodTerms, BendTwist) { expect_for_rod_and_vine<BendTwist>("bend-twist"); }
TEST(RodTerms, Magnetic) { expect_for_rod_and_vine<Magnetic>("magnetic"); }
TEST(RodTerms, Inertia) { expect_for_rod_and_vine<InertiaTerm>("inertia"); }
TEST(RodTerms, Anchors) { expect_for_rod_and_vine<AnchorTerm>("anchors"); }
TEST(RodTerms, Gravity) { expect_for_rod_and_vine<GravityTerm>("gravity and tip force"); }
TEST(RodTerms, TipMoment) { expect_for_rod_and_vine<TipMomentTerm>("tip moment"); }
TEST(RodTerms, Friction) { expect_for_rod_and_vine<FrictionTerm>("friction"); }
TEST(RodTerms, TipContact) {
  expect_for_rod_and_vine<TipContactTerm>("tip contact");
  // Its force at the tip is the one the balance counts (tip_contact_force): −F(d)·a, d = 1 mm here.
  const TermSetup s = make_setup(true);
  const TipContact& t = *s.constraints.tip_contact;
  EXPECT_NEAR(tip_contact_depth(t, s.state.x.back()), 1e-3, 1e-15);
  EXPECT_TRUE(tip_contact_force(t, s.state.x.back()).isApprox(-(0.3 + 40e-6) * t.axis, 1e-12));
}

TEST(RodTerms, WallBarrier) {
  // One large triangle below the body; each node's radius set so that its gap lies in (0, d̂), all closest points
  // inside the face (where the dropped curvature term is exactly zero): gradient and Hessian exact.
  for (const bool vine : {false, true}) {
    TermSetup s = make_setup(vine);
    const Vec3 n = Vec3(0.1, 0.2, 1.0).normalized();
    const Vec3 p0 = Vec3(0.0, 0.0, -0.05);
    const Vec3 a = n.unitOrthogonal();
    const Vec3 b = n.cross(a);
    anatomy::TriangleMesh mesh;
    mesh.vertices = {p0 - 1.0 * a - 1.0 * b, p0 + 2.0 * a - 1.0 * b, p0 - 1.0 * a + 2.0 * b};
    mesh.triangles = {anatomy::Triangle{0, 1, 2}};
    const anatomy::CollisionWorld world(mesh);
    WallBarrier w;
    w.world = &world;
    w.activation = 1e-4;
    w.stiffness = 50.0;
    w.radius.assign(s.state.x.size(), 0.0);
    for (std::size_t i = 1; i < s.state.x.size(); ++i) {
      const double distance = n.dot(s.state.x[i] - p0);
      w.radius[i] = distance - 1e-4 * (0.15 + 0.12 * static_cast<double>(i));
    }
    s.constraints = RodConstraints{};
    s.constraints.wall = w;
    expect_term_derivatives<WallBarrierTerm>(s, vine ? "wall barrier (vine)" : "wall barrier (rod)");
    if (!vine) continue;
    // The film flattening (WallBarrier::flattening): each sphere's radius s minimises the barrier plus the film's
    // Ψ(r − s) inside the energy, so the gradient is the envelope's and the Hessian the Schur complement of s.
    // P and ℓ are chosen so that the films give way by about d̂ (both laws in play): the tip's a cap.
    w.flattening.assign(s.state.x.size(), FlatteningSection{1e3, 1e-3, false});
    w.flattening.back().cap = true;
    w.flattening.back().pressure = 0.1;
    s.constraints.wall = w;
    const std::vector<NodeWallForce> f = wall_barrier_forces(s.state, w);
    for (std::size_t i = 1; i < f.size(); ++i) {
      // Each sphere gave way by a fraction of d̂, and the wall's push is the film's force there (to the root's
      // tolerance, 1e-13 of the forces, or its bracket at 1e-15 of r times the barrier's stiffness).
      const double depth = w.radius[i] - f[i].radius;
      EXPECT_GT(depth, 1e-3 * w.activation) << i;
      EXPECT_LT(depth, 10.0 * w.activation) << i;
      EXPECT_NEAR(f[i].magnitude, flattening_law(w.flattening[i], w.radius[i], depth).force, 1e-8 * f[i].magnitude)
          << i;
    }
    expect_term_derivatives<WallBarrierTerm>(s, "wall barrier (vine, flattening)");
  }
}

TEST(RodTerms, AFlatteningFilmCarriesItsPressureOverThePatch) {
  // flattening_law against an independent reference: the exact section of an inextensible pressurised membrane
  // (no bending stiffness) pressed on a flat wall. Its free part has one tension, so one curvature (Laplace): a
  // circular arc of radius ρ over the flat patch a, the perimeter kept, 2πR = ρ(2π − 2φ) + a with a = 2ρ sin φ;
  // the arc's centre is ρ cos φ from the wall, δ = R − ρ cos φ, and the patch carries P·a per length.
  const double radius = 2.5e-3;
  const double pressure = 35e3;
  const double length = 2.5e-3;
  const FlatteningSection side{pressure, length, false};
  for (const double phi : {0.05, 0.2, 0.5, 0.8, 1.0, 1.3, 1.57}) {
    const double rho = kPi * radius / (kPi - phi + std::sin(phi));
    const double depth = radius - rho * std::cos(phi);
    const double exact = pressure * length * 2.0 * rho * std::sin(phi);
    const double law = flattening_law(side, radius, depth).force;
    // To leading order in δ the law is exact; the stated bound is 3 % up to δ = 0.3R, 16 % to δ = R.
    const double bound = depth <= 0.3 * radius ? 0.03 : 0.16;
    std::printf("  membrane: delta/R %.3f, exact %.4f N, law %.4f N (%+.1f %%)\n", depth / radius, exact, law,
                100.0 * (law / exact - 1.0));
    EXPECT_NEAR(law / exact, 1.0, bound) << "phi " << phi;
  }
  // Each law's force is its energy's derivative, and its stiffness the force's (central differences).
  for (const bool cap : {false, true}) {
    const FlatteningSection section{pressure, length, cap};
    for (const double depth : {1e-5, 3e-4, 1.2e-3}) {
      const double step = 1e-9;
      const FlatteningLaw plus = flattening_law(section, radius, depth + step);
      const FlatteningLaw minus = flattening_law(section, radius, depth - step);
      const FlatteningLaw at = flattening_law(section, radius, depth);
      EXPECT_NEAR(at.force, (plus.energy - minus.energy) / (2.0 * step), 1e-6 * at.force);
      EXPECT_NEAR(at.stiffness, (plus.force - minus.force) / (2.0 * step), 1e-5 * at.stiffness);
    }
  }
  // The cap: a spherical membrane cut by the wall at depth δ presses a disc of radius² 2Rδ − δ² at P.
  const double depth = 0.05 * radius;
  EXPECT_NEAR(flattening_law(FlatteningSection{pressure, length, true}, radius, depth).force,
              pressure * kPi * (2.0 * radius * depth - depth * depth), 0.03 * pressure * kPi * 2.0 * radius * depth);
}

TEST(RodTerms, TheSolversEnergyIsTheSumOfTheTerms) {
  // rod_terms.hpp: evaluate is the fold over the list; the public rod_energy is that sum.
  const TermSetup s = make_setup(true);
  const TermContext c{s.model, s.field, s.state, 1.0, nullptr, &s.constraints, nullptr};
  const double sum = term_energy<StretchShear>(c, nullptr) + term_energy<BendTwist>(c, nullptr) +
                     term_energy<Magnetic>(c, nullptr) + term_energy<AnchorTerm>(c, nullptr) +
                     term_energy<GravityTerm>(c, nullptr) + term_energy<TipMomentTerm>(c, nullptr) +
                     term_energy<FrictionTerm>(c, nullptr) + term_energy<TipContactTerm>(c, nullptr);
  EXPECT_NEAR(rod_energy(s.model, s.field, s.state, 1.0, &s.constraints), sum, 1e-12 * std::abs(sum));
}

}  // namespace
}  // namespace magvine::robot::detail
