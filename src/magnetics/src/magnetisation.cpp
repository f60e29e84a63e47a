#include "magvine/magnetics/magnetisation.hpp"

#include <cmath>

#include "magvine/core/units.hpp"

namespace magvine::magnetics {

Wrench magnetic_wrench(const Vec3& m, const FieldSample& field) {
  return {field.g.transpose() * m, m.cross(field.b)};
}

Vec3 hard_magnetic_moment(const Vec3& br_body, double volume, const Mat3& body_to_world) {
  return body_to_world * br_body * (volume / kMu0);
}

double MagnetTip::volume() const { return kPi * 0.25 * diameter * diameter * length; }

Vec3 MagnetTip::moment(const Mat3& body_to_world) const {
  return body_to_world * direction_body.normalized() * (polarisation * volume() / kMu0);
}

double SkinLaw::area() const { return 2.0 * kPi * radius * thickness; }

Vec3 SkinLaw::outer_moment_per_length() const { return br_body * (area() / kMu0); }

Vec3 SkinLaw::tail_moment_per_length() const { return Vec3(0.0, 0.0, -br_body.z()) * (area() / kMu0); }

Vec3 SkinLaw::moment_per_length(bool with_tail) const {
  return with_tail ? Vec3(outer_moment_per_length() + tail_moment_per_length()) : outer_moment_per_length();
}

Vec3 FluidThesisLaw::moment(const Vec3& b, double volume) const {
  return volume_fraction * chi * volume / kMu0 * b;
}

double FluidBoundedLaw::suspension_susceptibility() const {
  const double beta = particle_susceptibility / (particle_susceptibility + 3.0);  // (μ_p − 1)/(μ_p + 2)
  return 3.0 * volume_fraction * beta / (1.0 - volume_fraction * beta);
}

Vec3 FluidBoundedLaw::moment(const Vec3& b, double volume, const Mat3& body_to_world) const {
  const double chi_s = suspension_susceptibility();
  const Vec3 h_body = body_to_world.transpose() * b / kMu0;
  const double chi_t = chi_s / (1.0 + demag_transverse * chi_s);
  const double chi_a = chi_s / (1.0 + demag_axial * chi_s);
  const Vec3 m_lin(chi_t * h_body.x(), chi_t * h_body.y(), chi_a * h_body.z());
  const double m_lin_norm = m_lin.norm();
  const double ms = volume_fraction * saturation;
  Vec3 m_body = m_lin;
  if (m_lin_norm > 0.0) m_body *= ms * std::tanh(m_lin_norm / ms) / m_lin_norm;
  return body_to_world * m_body * volume;
}

}  // namespace magvine::magnetics
