#pragma once
/// Particle sampling: points filling a shape on a regular lattice (optionally jittered, deterministic for a seed).
/// Each point stands for one lattice cell, so a particle's rest volume is spacing^D.

#include <cstdint>
#include <string>
#include <vector>

#include "magvine/anatomy/triangle_mesh.hpp"
#include "magvine/core/eigen_types.hpp"

namespace magvine::mpm {

struct LatticeOptions {
  double spacing = 0.0;     ///< lattice step [m], > 0
  bool jitter = false;      ///< move each point uniformly within its cell (seeded)
  std::uint64_t seed = 0;
};

/// Cell centres of the lattice with step `spacing` anchored at `min`, inside the box [min, max] (its extent rounded
/// to whole cells: a box 0.84 mm thick at spacing 0.07 mm gets exactly 12 layers). In 2D pass z extents equal.
std::vector<Vec3> sample_box(const Vec3& min, const Vec3& max, const LatticeOptions& options, int dimension = 3);

/// Lattice points inside the solid cylinder of `radius` around the segment a–b [m].
std::vector<Vec3> sample_cylinder(const Vec3& a, const Vec3& b, double radius, const LatticeOptions& options);

/// Lattice points inside a closed mesh (crossing parity along x through each lattice column). Throws InputError
/// naming `who` when no point lies inside (open mesh, or spacing larger than the part).
std::vector<Vec3> sample_mesh(const anatomy::TriangleMesh& mesh, const LatticeOptions& options, const std::string& who);

}  // namespace magvine::mpm
