#pragma once
/// The everting vine body in free space (PHYSICS.md §2–3): a thin-walled pressurised tube, optionally with a
/// magnetic skin and a fill, turned into the discretised rod of rod.hpp with the inflated-beam bending law.
///
/// Geometry and stiffness (thin walls, radius R to the outer surface, layers of thickness t_i and modulus E_i):
///   EI = πR³ Σ E_i t_i (Comer & Levy's wall rigidity, skin included),  GJ = 2πR³ Σ G_i t_i (G = E/3),
///   EI_flat = (πR/6) Σ E_i t_i³ (the collapsed tube: two flat sheets of width πR), what is left at P = 0.
/// Skin magnetisation (thesis 4.4.2): only orthogonal magnetisation survives eversion; the moment per unit everted
/// length is (Br/μ0)·2πR·w along a body-fixed transverse direction. Fill (thesis 5.4.2, 5.8.1; PHYSICS.md §2):
///   bounded (default): χ_s = 3φ/(1 − φ) (Maxwell-Garnett, highly permeable spheres at volume fraction φ), shape
///     demagnetisation of a long cylinder (N = 0 along the axis, ½ across): χ_eff = χ_s/(1 + Nχ_s), saturating at
///     φ·M_s(iron), M_s = 1.7 MA/m;
///   thesis: m = σχHV with χ = 4999, isotropic, no demagnetisation or saturation (overestimates by ~10³; kept to
///     reproduce the thesis's figures).
/// Pressure: the tip force PπR² is carried by the axial wall tension of the same size (reported, not applied:
/// in free space they cancel; the growth issue applies it where the tip meets the anatomy). Burst: hoop stress
/// PR/t_wall above the wall's strength is refused.

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

inline constexpr double kIronSaturation = 1.7e6;      ///< M_s of carbonyl iron [A/m] (PHYSICS.md §2)
inline constexpr double kIronDensity = 7870.0;        ///< [kg/m³]
inline constexpr double kThesisIronSusceptibility = 4999.0;  ///< bulk iron χ of the thesis law
/// Default wall strength [Pa]: the hoop stress at which the thesis's Ø3 mm, 38 µm TPE vine burst at 75 kPa
/// (thesis 5.5: P·R/t = 75 kPa × 1.5 mm / 38 µm ≈ 2.96 MPa); override with the film's datasheet value.
inline constexpr double kDefaultWallStrength = 2.9e6;

struct VineParameters {
  double length = 0.0;    ///< everted length [m]
  double radius = 0.0;    ///< outer radius R [m]
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
/// Hoop stress at pressure P [Pa].
double hoop_stress(const VineParameters& v);
/// The axial wall tension PπR² [N] that balances the pressure on the tip.
double pressure_tip_force(const VineParameters& v);

/// Where a vine's wall has wrinkled and whether it has creased, from its joint moments (joint_bending_moments).
struct VineBendState {
  double wrinkled_length = 0.0;  ///< total length of joints carrying more than M_w = πR³P/2 [m]
  bool creased = false;          ///< some joint carries the collapse moment πR³P
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

/// Builds the rod model of a vine (base frame, gravity, tip force left at their defaults). Throws
/// VineParameterError for bad parameters (non-positive sizes, walls thicker than the radius, a skin direction along
/// the tangent, a pressure above burst).
RodModel vine_rod(const VineParameters& v, double stretch_shear_factor = kNearInextensible);

}  // namespace magvine::robot
