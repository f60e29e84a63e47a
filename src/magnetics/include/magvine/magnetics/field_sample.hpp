#pragma once

#include "magvine/core/eigen_types.hpp"

namespace magvine::magnetics {

/// Flux density and its spatial gradient at one point.
struct FieldSample {
  /// Flux density B [T], in the frame of the query.
  Vec3 b = Vec3::Zero();
  /// Gradient G_ij = ∂B_i/∂x_j [T/m]. Symmetric and traceless wherever no magnet material is present.
  Mat3 g = Mat3::Zero();

  FieldSample& operator+=(const FieldSample& o) {
    b += o.b;
    g += o.g;
    return *this;
  }
};

}  // namespace magvine::magnetics
