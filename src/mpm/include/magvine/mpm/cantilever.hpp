#pragma once
/// A clamped cantilever built for MPM (the validation scenes of thesis 3.6: the Zhao beam, a beam under gravity, the
/// 60 × 3 × 3 mm beam), and a driver that steps a model until it comes to rest.
///
/// The beam runs along +x from the clamp face x = 0, thickness along y, width along z (3D); `clamp_length` of
/// material behind the face sits in the clamp, whose grid nodes (x ≤ 0) are held.

#include <cstdint>
#include <deque>
#include <functional>
#include <vector>

#include "magvine/mpm/mpm.hpp"

namespace magvine::mpm {

struct CantileverSpec {
  double length = 0.0;       ///< free length L [m]
  double thickness = 0.0;    ///< along y [m]
  double width = 0.0;        ///< along z [m] (3D only)
  double clamp_length = 0.0; ///< material inside the clamp, behind x = 0 [m]; 0: two cells
  int cells_through_thickness = 4;
  int particles_per_cell = 2;  ///< per axis
  Material material;
  Vec3 remanence = Vec3::Zero();  ///< B̃r, world frame [T] (uniform along the beam)
  Vec3 gravity = Vec3::Zero();    ///< [m/s²]
  double damping = 0.0;           ///< [1/s]
  Plane plane = Plane::kStrain;   ///< 2D only: what the slice is (mpm.hpp)
};

template <int D>
struct Cantilever {
  MpmModel<D> model;
  MpmState<D> state;
  std::vector<std::uint32_t> tip;  ///< particles of the free end's last lattice layer
};

/// Builds the beam; the domain leaves L + 4 cells of room around it in every direction.
template <int D>
Cantilever<D> make_cantilever(const CantileverSpec& spec);

/// Mean position of the particles `ids` [m].
template <int D>
VecD<D> mean_position(const MpmState<D>& state, const std::vector<std::uint32_t>& ids);

/// When to stop stepping.
struct SettleOptions {
  double time_step = 0.0;        ///< [s]; 0: the model's stable step at `courant`
  double courant = 0.4;          ///< fraction of the CFL step δx / c_P
  double min_time = 0.0;         ///< never stop before [s]
  double max_time = 1.0;         ///< stop here even if still moving [s]
  double window = 0.02;          ///< rest: the probe moved less than `tolerance` over this long [s]
  double tolerance = 0.0;        ///< [m]
  bool implicit = false;         ///< implicit steps (implicit_step) of `time_step` (0: the explicit bound, as above),
                                 ///< a failed one taken again at half the length (ImplicitStepper)
  ImplicitSettings newton;       ///< for implicit steps
  /// Total-Lagrangian steps (total_lagrangian.hpp), explicit or implicit as above, on a reference grid made from the
  /// state as it is at the call (so settle an undeformed body).
  bool total_lagrangian = false;
};

/// Rest detection from probe samples taken every window/10: at rest once the last 11 samples all lie within
/// `tolerance` of the newest.
class RestWatch {
 public:
  explicit RestWatch(double tolerance) : m_tolerance(tolerance) {}
  /// Adds a sample (one point per probe) [m]; true when at rest.
  bool add(const std::vector<Vec3>& probes);

 private:
  double m_tolerance;
  std::deque<std::vector<Vec3>> m_history;
};

struct SettleResult {
  StepStatus status;
  bool settled = false;  ///< came to rest before max_time
  long steps = 0;
  long cg = 0;           ///< implicit steps: conjugate-gradient iterations (Hessian products) over the run
  long newton = 0;       ///< implicit steps: Newton iterations over the run
  long factorizations = 0;  ///< implicit steps: Hessian factorizations over the run
  long retries = 0;      ///< implicit steps taken again at half the length (ImplicitStepper)
  double time = 0.0;     ///< simulated [s]
  double time_step = 0.0;
};

/// Steps `state` under `field(t)` until the mean of the `probe` particles rests (or max_time, or a failure).
template <int D>
SettleResult settle(const MpmModel<D>& model, MpmState<D>& state, MpmWorkspace<D>& ws,
                    const std::function<AppliedField(double)>& field, const std::vector<std::uint32_t>& probe,
                    const SettleOptions& options);

}  // namespace magvine::mpm
