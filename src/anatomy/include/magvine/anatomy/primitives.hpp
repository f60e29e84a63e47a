#pragma once
/// Simple parametric meshes: the straight tube (a bench phantom and the analytic reference for contact and
/// distance tests).

#include "magvine/anatomy/triangle_mesh.hpp"

namespace magvine::anatomy {

/// Straight circular tube along +z from z = 0 to z = length, axis through the origin.
struct TubeSpec {
  double radius = 5e-3;  ///< [m]
  double length = 0.1;   ///< [m]
  int segments = 64;     ///< vertices around the circumference (≥ 3); vertices lie on the circle
  int rings = 0;         ///< rings of vertices along the length (≥ 2); 0 picks ~square triangles
  bool capped = true;    ///< close both ends with flat caps (watertight); false leaves two openings
};

/// Tube with outward normals (pointing away from the lumen). Capped: genus 0, watertight.
TriangleMesh make_tube(const TubeSpec& spec);

}  // namespace magvine::anatomy
