#include "magvine/robot/vine.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "magvine/core/error.hpp"
#include "magvine/core/text.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/magnetisation.hpp"
#include "magvine/robot/inflated_beam.hpp"

namespace magvine::robot {
namespace {

void require(bool ok, const char* parameter, const std::string& what) {
  if (!ok) throw VineParameterError(parameter, "vine: " + what);
}

double fill_density_of(const VineParameters& v) {
  if (v.fill_density >= 0.0) return v.fill_density;
  switch (v.fill) {
    case FillKind::kAir: return 0.0;  // ~1.2 kg/m³ plus P/(R_s T): negligible against the wall
    case FillKind::kWater: return 1000.0;
    case FillKind::kMagneticFluid:
      return (1.0 - v.volume_fraction) * 1000.0 + v.volume_fraction * magnetics::kIronDensity;  // ≈ 2580 at φ = 0.23
  }
  return 0.0;
}

}  // namespace

VineParameters thesis_skin_mvr(double length, int edges) {
  return {.length = length, .radius = 4e-3, .pressure = 12e3,
          .wall = {.thickness = 20e-6, .modulus = 0.2e9, .density = 920.0}, .wall_strength = 10e6,
          .skin = {.thickness = 0.2e-3, .modulus = 99e3, .density = 1840.0}, .skin_remanence = 0.101,
          .skin_direction = Vec3::UnitY(), .edges = edges};
}

VineParameters thesis_fluid_vine(double length, int edges) {
  // The TPE film's strength is kDefaultWallStrength, from the thesis's Ø3 mm burst.
  return {.length = length, .radius = 2.5e-3, .pressure = 35e3,
          .wall = {.thickness = 38e-6, .modulus = 10e6, .density = 1000.0}, .wall_strength = kDefaultWallStrength,
          .skin = {},
          .fill = FillKind::kMagneticFluid, .edges = edges};
}

bool has_magnetic_skin(const VineParameters& v) { return v.skin.thickness > 0.0 && v.skin_remanence != 0.0; }

double extended_radius(const VineParameters& v, double pressure) {
  return v.radius * (1.0 + pressure * v.radius / (v.wall.thickness * v.wall.modulus));
}

double hoop_stress(const VineParameters& v, double pressure) {
  return pressure * extended_radius(v, pressure) / v.wall.thickness;
}

bool bursts(const VineParameters& v, double pressure) { return hoop_stress(v, pressure) > v.wall_strength; }

double burst_pressure(const VineParameters& v) {
  const double a = v.radius * v.radius / (v.wall.thickness * v.wall.thickness * v.wall.modulus);
  const double b = v.radius / v.wall.thickness;
  // 2S/(b + √(b² + 4aS)): the root without the cancellation of (−b + √(b² + 4aS))/(2a) for a small a.
  return 2.0 * v.wall_strength / (b + std::sqrt(b * b + 4.0 * a * v.wall_strength));
}

double pressure_tip_force(const VineParameters& v) {
  const double r = extended_radius(v, v.pressure);
  return v.pressure * kPi * r * r;
}

RodModel vine_rod(const VineParameters& v, double stretch_shear_factor) {
  const auto finite_positive = [](double x) { return x > 0.0 && std::isfinite(x); };
  require(finite_positive(v.length), "length", "length must be > 0");
  require(finite_positive(v.radius), "diameter", "radius must be > 0");
  require(v.pressure >= 0.0 && std::isfinite(v.pressure), "pressure", "pressure must be >= 0");
  require(finite_positive(v.wall.thickness), "wall", "wall thickness must be > 0");
  require(finite_positive(v.wall.modulus), "wall", "wall modulus must be > 0");
  require(v.wall.density >= 0.0, "wall", "wall density must be >= 0");
  require(v.skin.thickness >= 0.0 && v.skin.modulus >= 0.0 && v.skin.density >= 0.0, "skin",
          "skin thickness, modulus and density must be >= 0");
  require(v.wall.thickness + v.skin.thickness < v.radius, "diameter", "wall and skin must be thinner than the radius");
  require(finite_positive(v.wall_strength), "wall", "wall strength must be > 0");
  require(v.edges >= 1, "nodes", "edges must be >= 1");
  require(v.volume_fraction > 0.0 && v.volume_fraction < 1.0, "fill", "fluid volume fraction must be in (0, 1)");
  if (bursts(v, v.pressure)) {
    throw VineParameterError(
        "pressure", printf_string("vine: pressure %.4g kPa is above burst: hoop stress %.4g MPa exceeds the wall "
                                  "strength %.4g MPa (burst at %.4g kPa, with the diametric extension)",
                                  v.pressure / kKpaToPa, hoop_stress(v, v.pressure) / 1e6, v.wall_strength / 1e6,
                                  burst_pressure(v) / kKpaToPa));
  }
  const double r = extended_radius(v, v.pressure);
  const double r3 = r * r * r;
  const double et = v.wall.modulus * v.wall.thickness + v.skin.modulus * v.skin.thickness;
  const double et3 = v.wall.modulus * std::pow(v.wall.thickness, 3) + v.skin.modulus * std::pow(v.skin.thickness, 3);
  RodModel m;
  m.length = v.length;
  m.edges = v.edges;
  m.bending_stiffness_2 = kPi * r3 * et;
  m.bending_stiffness_3 = m.bending_stiffness_2;
  m.torsional_stiffness = 2.0 * kPi * r3 * et / 3.0;
  m.axial_stiffness = stretch_shear_factor * 2.0 * kPi * r * et;
  m.shear_stiffness = stretch_shear_factor * kPi * r * et / 3.0;  // thin tube: shear area ≈ half the wall
  const double inner = r - v.wall.thickness - v.skin.thickness;
  const double inner_area = kPi * inner * inner;
  m.mass_per_length = 2.0 * kPi * r * (v.wall.density * v.wall.thickness + v.skin.density * v.skin.thickness) +
                      fill_density_of(v) * inner_area;
  m.rotational_inertia_per_length = 0.5 * m.mass_per_length * r * r;  // a thin tube (and its fill) about a diameter
  m.inflated = InflatedBending{.radius = r, .pressure = v.pressure, .flat_bending_stiffness = kPi * r * et3 / 6.0};
  if (has_magnetic_skin(v)) {
    require(v.skin_direction.norm() > 0.0, "skin", "skin magnetisation direction must not be zero");
    const Vec3 d = v.skin_direction.normalized();
    require(std::abs(d.x()) < 1e-6, "skin",
            "skin magnetisation must be orthogonal to the body axis (axial magnetisation cancels on eversion, "
            "thesis 4.4.2)");
    const magnetics::SkinLaw skin{.radius = r, .thickness = v.skin.thickness, .br_body = v.skin_remanence * d};
    m.moment_per_length.assign(static_cast<std::size_t>(v.edges), skin.moment_per_length(/*with_tail=*/true));
  }
  if (v.fill == FillKind::kMagneticFluid) {
    InducedFill f;
    f.volume_per_length = inner_area;
    f.law = v.law == FluidLaw::kThesis ? magnetics::FluidThesisLaw{.volume_fraction = v.volume_fraction}.induced()
                                       : magnetics::FluidBoundedLaw{.volume_fraction = v.volume_fraction}.induced();
    m.induced = f;
  }
  return m;
}

VineBendState vine_bend_state(const RodModel& vine, const RodState& state) {
  VineBendState out;
  if (!vine.inflated) return out;
  const double m_w = wrinkling_moment(vine.inflated->radius, vine.inflated->pressure);
  const double m_c = collapse_moment(vine.inflated->radius, vine.inflated->pressure);
  const double h = vine.length / vine.edges;
  const std::vector<double> moments = joint_bending_moments(vine, state);
  for (std::size_t i = 0; i < moments.size(); ++i) {
    if (moments[i] > m_w) out.wrinkled_length += i == 0 ? 0.5 * h : h;
    out.creased = out.creased || (m_c > 0.0 && moments[i] >= m_c);
    if (m_c > 0.0) out.largest_moment = std::max(out.largest_moment, moments[i] / m_c);
  }
  return out;
}

}  // namespace magvine::robot
