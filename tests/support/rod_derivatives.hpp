#pragma once
// Shared by the rod and vine tests: the analytic gradient of the rod energy against central differences of the
// energy along every unknown (positions by δx, rotations by exp([δφ])R).

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "magvine/robot/rod.hpp"

namespace magvine::robot::testing {

/// Central differences (1e-9 m, 1e-6 rad): O(δ²) ≈ 1e-10 relative; asserted to 1e-6 relative plus 1e-9 of the
/// largest component (components near zero).
inline void expect_gradient_matches_energy(const RodModel& m, const RodField& field, const RodState& s,
                                           const std::string& label) {
  const VecX g = rod_gradient(m, field, s);
  for (Eigen::Index k = 0; k < g.size(); ++k) {
    const auto block = static_cast<std::size_t>(k / 6);
    const int axis = static_cast<int>(k % 3);
    const bool rotation = (k % 6) >= 3;
    const double step = rotation ? 1e-6 : 1e-9;
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
