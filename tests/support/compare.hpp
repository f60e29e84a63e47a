#pragma once
// Comparison helpers in the spirit of Drake's CompareMatrices: absolute + relative tolerance, and a
// message that prints both values and the error.

#include <gtest/gtest.h>

#include <sstream>

#include "magvine/core/eigen_types.hpp"

namespace magvine::test {

/// |a − b| ≤ abs_tol + rel_tol·|b| elementwise-in-norm: ‖a − b‖ ≤ abs_tol + rel_tol·‖b‖.
template <class A, class B>
::testing::AssertionResult close(const A& a, const B& b, double rel_tol, double abs_tol = 0.0) {
  const double err = (a - b).norm();
  const double lim = abs_tol + rel_tol * b.norm();
  if (err <= lim && a.allFinite()) return ::testing::AssertionSuccess();
  std::ostringstream s;
  s << "\n  got      " << a.transpose() << "\n  expected " << b.transpose() << "\n  |error| " << err
    << " > limit " << lim << " (relative " << err / (b.norm() > 0 ? b.norm() : 1.0) << ")";
  return ::testing::AssertionFailure() << s.str();
}

inline Eigen::Matrix<double, 9, 1> flat(const Mat3& m) { return Eigen::Map<const Eigen::Matrix<double, 9, 1>>(m.data()); }

}  // namespace magvine::test
