#pragma once
// The thesis's vine bodies, shared by the vine and growth tests and the growth benchmark.

#include "magvine/robot/vine.hpp"

namespace magvine::robot::testing {

/// The Ø8 mm skin MVR of thesis 4.6 at its 12 kPa: LDPE 20 µm (E 0.2 GPa assumed, 10 MPa strength), magnetic
/// silicone skin 0.2 mm (Br 0.101 T, orthogonal).
inline VineParameters thesis_skin_mvr(double length, int edges = 0) {
  VineParameters v;
  v.length = length;
  v.radius = 4e-3;
  v.pressure = 12e3;
  v.wall = {.thickness = 20e-6, .modulus = 0.2e9, .density = 920.0};
  v.wall_strength = 10e6;
  v.skin = {.thickness = 0.2e-3, .modulus = 99e3, .density = 1840.0};
  v.skin_remanence = 0.101;
  v.skin_direction = Vec3::UnitY();
  v.edges = edges;
  return v;
}

/// The Ø5 mm magnetic-fluid vine of thesis 5.5 at 35 kPa: TPE film 38 µm, E = 10 MPa, magnetic fluid fill.
inline VineParameters thesis_fluid_vine(double length) {
  VineParameters v;
  v.length = length;
  v.radius = 2.5e-3;
  v.pressure = 35e3;
  v.wall = {.thickness = 38e-6, .modulus = 10e6, .density = 1000.0};
  v.wall_strength = 10e6;
  v.fill = FillKind::kMagneticFluid;
  return v;
}

}  // namespace magvine::robot::testing
