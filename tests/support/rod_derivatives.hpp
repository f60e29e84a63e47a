#pragma once
// Shared by the rod and vine tests: the analytic gradient of the rod energy against central differences of the
// energy along every unknown (positions by δx, rotations by exp([δφ])R).

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "magvine/robot/rod.hpp"

namespace magvine::robot::testing {

/// Rebuilds the nodes along the frames (edge j = h R_j e1) plus `noise`·h of random offset: strains stay small, so
/// the stiff stretch and shear terms (EA ≫ EI/L²) do not dominate the gradient and hide errors in the others.
template <class Rng>
void nodes_along_frames(const RodModel& m, RodState& s, double noise, Rng& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double h = m.length / m.edges;
  for (std::size_t j = 0; j < s.frames.size(); ++j) {
    s.x[j + 1] = s.x[j] + h * s.frames[j].col(0) + noise * h * Vec3(u(rng), u(rng), u(rng));
  }
}

/// Central differences (3e-9 m, 1e-6 rad; a smaller position step lets the energy's round-off through, measured):
/// asserted to 1e-6 relative plus 1e-9 of the
/// largest component (components near zero).
inline void expect_gradient_matches_energy(const RodModel& m, const RodField& field, const RodState& s,
                                           const std::string& label) {
  const VecX g = rod_gradient(m, field, s);
  for (Eigen::Index k = 0; k < g.size(); ++k) {
    const auto block = static_cast<std::size_t>(k / 6);
    const int axis = static_cast<int>(k % 3);
    const bool rotation = (k % 6) >= 3;
    const double step = rotation ? 1e-6 : 3e-9;
    const auto shifted = [&](double d) {
      RodState t = s;
      if (rotation) {
        t.frames[block] = Eigen::AngleAxisd(d, Vec3::Unit(axis)).toRotationMatrix() * t.frames[block];
      } else {
        t.x[block + 1][axis] += d;
      }
      return rod_energy(m, field, t);
    };
    const double fd = (shifted(step) - shifted(-step)) / (2.0 * step);
    EXPECT_NEAR(g[k], fd, 1e-6 * (std::abs(fd) + g.cwiseAbs().maxCoeff() * 1e-3)) << label << ": unknown " << k;
  }
}

}  // namespace magvine::robot::testing
