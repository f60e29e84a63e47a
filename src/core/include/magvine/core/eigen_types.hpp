#pragma once
/// Eigen aliases used across magvine. Everything is double precision.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace magvine {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using VecX = Eigen::VectorXd;
using MatX = Eigen::MatrixXd;

}  // namespace magvine
