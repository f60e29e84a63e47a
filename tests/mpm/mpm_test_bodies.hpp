#pragma once
// The bodies the MPM implicit-step tests share (test_mpm_implicit, test_mpm_total_lagrangian).

#include "magvine/mpm/cantilever.hpp"

namespace magvine::mpm::test_bodies {

/// A small soft block (4 × 2 × 2 mm, G 100 kPa, K 20 G) built as a cantilever (its clamp may be dropped).
inline CantileverSpec small_block() {
  CantileverSpec s;
  s.length = 0.004;
  s.thickness = 0.002;
  s.width = 0.002;
  s.material = {1e5, 2e6, 1000.0};
  return s;
}

/// A stiff magnetic catheter in plane strain: E ≈ 3 MPa (G = 1 MPa, K = 20 G), 1 mm thick, 10 mm long, 4 cells
/// through its thickness, B̃r = 0.1 T along it, in 20 mT across it (B̄ = Br B A L²/(μ0 E I) ≈ 0.65 with E the plane
/// strain modulus: a large deflection), damped near critically for its first bending mode.
inline CantileverSpec stiff_catheter() {
  CantileverSpec s;
  s.length = 0.01;
  s.thickness = 0.001;
  s.cells_through_thickness = 4;
  s.particles_per_cell = 2;
  s.material = {1e6, 2e7, 1100.0};
  s.remanence = Vec3(0.1, 0, 0);
  s.damping = 1000.0;
  return s;
}

/// A uniform field of b [T] across the catheter (along +y).
inline AppliedField across(double b = 0.02) {
  AppliedField f;
  f.kind = AppliedField::Kind::kUniform;
  f.uniform = Vec3(0, b, 0);
  return f;
}

}  // namespace magvine::mpm::test_bodies
