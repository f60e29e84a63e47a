#pragma once
/// Breathing: a displacement field of the airway driven by a respiratory phase (issue 31, item 4; docs/ct.md,
/// "Breathing").
///
/// Profile (Lujan et al., Med. Phys. 26(5), 1999): the position of a point moving with the lung is
/// z(t) = z0 − b·cos^{2n}(πt/τ − φ), τ the period: a brief peak of inspiration and a long rest near exhalation, the
/// longer the larger n (Lujan fit n = 1–3). `inspiration(t)` = cos^{2n}(πt/τ) is the fraction of the inspiration
/// reached, 1 at t = 0.
///
/// Reference and direction: the mesh is the planning CT's airway, taken at full inspiration (breath-hold); breathing
/// moves it towards exhalation, the lung rising with the diaphragm: u(x, t) = A(x)·(1 − inspiration(t))·ŝ, ŝ the
/// superior direction (cranio-caudal motion dominates; the anterior–posterior and lateral components, a few mm, are
/// left out).
///
/// Amplitude A(x), growing with depth below the carina: from the airway's entry (the clamp, fixed: 0) to the carina
/// linearly up to A_c, then linearly with the depth below the carina along −ŝ up to A_l at `lower_depth`, and A_l
/// beyond. Sources: the carina's 3D motion range is 5 (SD 3) mm (PMC4476088, tumour and lymph-node motion in the
/// same patients 4 (3) and 5 (3) mm); nodules move 17.6 mm on average between full inspiration and tidal
/// exhalation, lower-lobe ones more than 2 cm (Chen et al., Chest 148(6), 2015, in electromagnetic navigation
/// bronchoscopy). Defaults A_c = 5 mm, A_l = 22 mm. The depth at which the lower lobes reach A_l is not published in
/// those sources: 80 mm below the carina is an assumption (the basal segmental bronchi of an adult lie 60–100 mm
/// below the carina).

#include <span>
#include <vector>

#include "magvine/core/eigen_types.hpp"

namespace magvine::anatomy {

struct BreathingParams {
  double period = 4.0;             ///< τ [s]
  int profile = 2;                 ///< n of cos^{2n}, ≥ 1
  double carina_amplitude = 5e-3;  ///< A_c [m]
  double lower_amplitude = 22e-3;  ///< A_l [m]
  double lower_depth = 0.08;       ///< depth below the carina where A_l is reached [m]
  Vec3 superior = Vec3::UnitZ();   ///< ŝ, unit (RAS: +z)
  Vec3 entry = Vec3::Zero();       ///< the airway's entry (fixed) [m]
  Vec3 carina = Vec3::Zero();      ///< the carina [m]
};

/// Checks the parameters (InputError naming the field).
void check_breathing(const BreathingParams& params);

/// cos^{2n}(πt/τ): 1 at full inspiration (t = 0, τ, 2τ, …), 0 at exhalation [−] (Lujan et al. 1999).
double inspiration(const BreathingParams& params, double time);

/// A(x) [m] (see the file comment).
double breathing_amplitude(const BreathingParams& params, const Vec3& x);

/// u(x, t) = A(x)·(1 − inspiration(t))·ŝ [m].
Vec3 breathing_displacement(const BreathingParams& params, const Vec3& x, double time);
/// The same law from a point's amplitude A(x) (breathing_amplitude, time-independent: a moving mesh keeps its
/// vertices') and the phase's inspiration(t): u = A·(1 − inspiration)·ŝ.
Vec3 breathing_displacement(const BreathingParams& params, double amplitude, double inspiration);

/// The rest point X that breathing moves to x at `time`: X + u(X, t) = x, by the fixed-point iteration
/// X ← x − u(X, t), a contraction where the amplitude's slope along ŝ times (1 − inspiration) is below 1
/// (check_breathing asks it of the trachea's and the lobes' slopes; the defaults' 17 mm over 80 mm is 0.21). One step
/// of it, x − u(x, t), is off by that slope times u: up to 4.7 mm at exhalation in the lower lobes with the defaults.
Vec3 breathing_rest_point(const BreathingParams& params, const Vec3& x, double time);

/// Each rest vertex's amplitude, for moving a mesh at every step or frame (breathing_vertices).
std::vector<double> breathing_amplitudes(const BreathingParams& params, std::span<const Vec3> rest);
/// The mesh's vertices at `time`: rest + u, from the amplitudes (the phase evaluated once); `out` resized.
void breathing_vertices(const BreathingParams& params, std::span<const Vec3> rest, std::span<const double> amplitudes,
                        double time, std::vector<Vec3>& out);

}  // namespace magvine::anatomy
