#include "magvine/magnetics/magnetisation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace magvine::magnetics {
double MagnetTip::volume() const { return kPi * 0.25 * diameter * diameter * length; }

Vec3 MagnetTip::moment(const Mat3& body_to_world) const {
  return hard_magnetic_moment(Vec3(direction_body.normalized() * polarisation), volume(), body_to_world);
}

double SkinLaw::area() const { return 2.0 * kPi * radius * thickness; }

Vec3 SkinLaw::outer_moment_per_length() const { return hard_magnetic_moment<3>(br_body, area()); }

Vec3 SkinLaw::tail_moment_per_length() const {
  return hard_magnetic_moment<3>(Vec3(-br_body.x(), 0.0, 0.0), area());
}

Vec3 SkinLaw::moment_per_length(bool with_tail) const {
  return with_tail ? Vec3(outer_moment_per_length() + tail_moment_per_length()) : outer_moment_per_length();
}

Vec3 InducedMagnetisation::magnetisation(const Vec3& b) const {
  Vec3 de_db;
  energy_density(b, de_db);
  return -de_db;
}

Vec3 InducedMagnetisation::moment(const Vec3& b, double volume, const Mat3& body_to_world) const {
  return body_to_world * magnetisation(body_to_world.transpose() * b) * volume;
}

InducedMagnetisation FluidThesisLaw::induced() const {
  const double x = volume_fraction * chi;
  return {.axial_susceptibility = x,
          .transverse_susceptibility = x,
          .saturation = std::numeric_limits<double>::infinity(),
          .reference_susceptibility = x};
}

Vec3 FluidThesisLaw::moment(const Vec3& b, double volume) const {
  return induced().moment(b, volume, Mat3::Identity());
}

double FluidBoundedLaw::suspension_susceptibility() const {
  const double beta = particle_susceptibility / (particle_susceptibility + 3.0);  // (μ_p − 1)/(μ_p + 2)
  return 3.0 * volume_fraction * beta / (1.0 - volume_fraction * beta);
}

InducedMagnetisation FluidBoundedLaw::induced() const {
  const double chi_s = suspension_susceptibility();
  return {.axial_susceptibility = chi_s / (1.0 + demag_axial * chi_s),
          .transverse_susceptibility = chi_s / (1.0 + demag_transverse * chi_s),
          .saturation = volume_fraction * saturation,
          .reference_susceptibility = chi_s};
}

Vec3 FluidBoundedLaw::moment(const Vec3& b, double volume, const Mat3& body_to_world) const {
  return induced().moment(b, volume, body_to_world);
}

double magnetorheological_yield_stress(double field_strength, double volume_fraction) {
  const double h = std::abs(field_strength);
  const double chains = std::sqrt(6.0) * volume_fraction * kMu0 * std::sqrt(kIronSaturation) * h * std::sqrt(h);
  const double saturated = 0.086 * volume_fraction * kMu0 * kIronSaturation * kIronSaturation;
  return std::min(chains, saturated);
}

}  // namespace magvine::magnetics
