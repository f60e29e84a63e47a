#pragma once
/// The everting vine body (PHYSICS.md §2–3): a thin-walled pressurised tube, optionally with a magnetic skin and a
/// fill, turned into the discretised rod of rod.hpp with the inflated-beam bending law. Free-space scenes and growth
/// build it the same way (vine_rod).
///
/// Geometry and stiffness (thin walls, radius R(P) to the outer surface, layers of thickness t_i and modulus E_i):
///   diametric extension (thesis 5.8.2): the film's hoop strain ε = σ/E = PR/(t_wall E_wall), R(P) = R(1 + ε), R the
///     radius as made (VineParameters::radius, unpressurised); everything below uses R(P) (the layers' thicknesses
///     are kept: the film's thinning as it stretches is not modelled);
///   EI = πR³ Σ E_i t_i (Comer & Levy's wall rigidity, skin included),  GJ = 2πR³ Σ G_i t_i (G = E/3),
///   EI_flat = (πR/6) Σ E_i t_i³ (the collapsed tube: two flat sheets of width πR), what is left at P = 0.
/// Magnetisation from magnetics/magnetisation.hpp: the skin (SkinLaw, its tail inside the everted body: only
/// orthogonal magnetisation survives eversion, (Br/μ0)·2πR·w per unit everted length, body-fixed); the fill
/// (FluidBoundedLaw by default, or FluidThesisLaw) as an induced magnetisation over the fill's section π(R − t)².
/// Pressure: the tip force PπR² is carried by the axial wall tension of the same size (reported, not applied: in
/// free space they cancel; growth applies it where the tip meets the anatomy). Burst: a hoop stress P·R(P)/t_wall
/// above the wall's strength (bursts, burst_pressure) is refused.

#include <string>
#include <utility>

#include "magvine/core/error.hpp"

#include "magvine/robot/rod.hpp"

namespace magvine::robot {

enum class FillKind { kAir, kWater, kMagneticFluid };
enum class FluidLaw { kBounded, kThesis };

/// One layer of the tube wall.
struct WallLayer {
  double thickness = 0.0;  ///< [m]
  double modulus = 0.0;    ///< Young's modulus [Pa]
  double density = 0.0;    ///< [kg/m³]
};

/// Default wall strength [Pa]: the hoop stress at which the thesis's Ø3 mm, 38 µm TPE vine burst at 75 kPa
/// (thesis 5.5: P·R/t = 75 kPa × 1.5 mm / 38 µm ≈ 2.96 MPa); override with the film's datasheet value.
inline constexpr double kDefaultWallStrength = 2.9e6;

struct VineParameters {
  double length = 0.0;    ///< everted length [m]
  double radius = 0.0;    ///< outer radius R as made (unpressurised) [m]; pressurised: extended_radius
  double pressure = 0.0;  ///< P [Pa]
  WallLayer wall;         ///< the film (LDPE, TPE)
  double wall_strength = kDefaultWallStrength;  ///< tensile strength of the film [Pa]
  WallLayer skin;         ///< magnetic skin (thickness 0: none)
  double skin_remanence = 0.0;             ///< Br of the skin [T]
  Vec3 skin_direction = Vec3::UnitY();     ///< its magnetisation in the body frame, ⟂ to the tangent (x)
  FillKind fill = FillKind::kAir;
  double fill_density = -1.0;              ///< [kg/m³]; < 0: the default of the fill kind
  double volume_fraction = 0.23;           ///< iron in a magnetic fluid
  FluidLaw law = FluidLaw::kBounded;
  int edges = 0;
};

/// The skin MVR of thesis 4.6 at its 12 kPa: Ø8 mm, LDPE 20 µm (E 0.2 GPa assumed, strength 10 MPa), magnetic skin
/// (NdFeB–Ecoflex) 0.2 mm, E 99 kPa, Br 0.101 T across the body (d2).
VineParameters thesis_skin_mvr(double length, int edges = 0);
/// The magnetic-fluid vine of thesis 5.5 at 35 kPa: Ø5 mm, TPE film (Stretchlon 200) 38 µm, E 10 MPa, strength
/// kDefaultWallStrength (2.9 MPa, from its Ø3 mm burst), filled with magnetic fluid (the bounded law).
VineParameters thesis_fluid_vine(double length, int edges = 0);

/// Whether the vine carries a magnetised skin (a skin layer with a remanence).
bool has_magnetic_skin(const VineParameters& v);
/// The radius at `pressure` with the diametric extension, R(1 + PR/(tE)) (the film's hoop strain, thesis 5.8.2) [m].
double extended_radius(const VineParameters& v, double pressure);
/// Hoop stress of the film at `pressure`, with the extension: σ = P·R(P)/t_wall [Pa].
double hoop_stress(const VineParameters& v, double pressure);
/// Whether `pressure` bursts the vine: its hoop stress exceeds the wall strength. The one burst criterion.
bool bursts(const VineParameters& v, double pressure);
/// The pressure at which the hoop stress reaches the wall strength S: the positive root of
/// (R²/(t²E))·P² + (R/t)·P − S = 0 [Pa] (bursts(v, P) ⟺ P > burst_pressure(v)).
double burst_pressure(const VineParameters& v);
/// The axial wall tension P·πR(P)² [N] that balances the pressure on the tip (at v.pressure).
double pressure_tip_force(const VineParameters& v);

/// Where a vine's wall has wrinkled and whether it has creased, from its joint moments (joint_bending_moments).
struct VineBendState {
  double wrinkled_length = 0.0;  ///< total length of joints carrying more than M_w = πR³P/2 [m]
  bool creased = false;          ///< some joint carries the collapse moment πR³P
  double largest_moment = 0.0;   ///< the largest joint moment over πR³P (≥ 1: creased)
};
VineBendState vine_bend_state(const RodModel& vine, const RodState& state);

/// A bad vine parameter: InputError with the parameter's name (length, diameter, pressure, wall, skin, fill, nodes).
class VineParameterError : public InputError {
 public:
  VineParameterError(std::string parameter, const std::string& message)
      : InputError(message), m_parameter(std::move(parameter)) {}
  const std::string& parameter() const { return m_parameter; }

 private:
  std::string m_parameter;
};

/// Builds the rod model of a vine at v.pressure (base frame, gravity, tip force left at their defaults; the radius
/// extended). Throws VineParameterError for bad parameters (non-positive or non-finite sizes, walls thicker than the
/// radius, a skin direction along the tangent, a pressure above burst).
RodModel vine_rod(const VineParameters& v, double stretch_shear_factor = kNearInextensible);

}  // namespace magvine::robot
