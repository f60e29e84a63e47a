#pragma once
/// Computational design of magnetic soft rods (thesis appendix A.1; docs/design.md): the magnetisation direction
/// (and optionally magnitude) of each of S equal sections along a clamped rod, and optionally the uniform field,
/// chosen so that the rod's static equilibrium lies on a target shape.
///
/// Objective: J(p) = (1/K) Σ_k |x(s_k) − t_k|² over K target points t_k equally spaced in arc length from the base
/// (s_k = k L/(K − 1)), x(s) the equilibrium's nodes interpolated linearly in arc length (thesis eq A.3 divided by K;
/// RMS = √J). The equilibrium is solved from the straight rod each time, as `magvine run` does, so the objective is a
/// function of p alone. Its gradient is exact: dJ/dp = −λᵀ ∂g/∂p with H λ = ∂J/∂x at the equilibrium
/// (rod_hessian_solve), ∂g/∂p from rod_moment_sensitivity and rod_uniform_field_sensitivity through the
/// parametrisation below.
///
/// Parameters p (bounded): per section its direction in the body frame d = (sin θ cos φ, sin θ sin φ, cos θ),
/// θ ∈ [0, π], φ ∈ [−2π, 2π] (x = d1 along the rod, y = d2 the base normal), then its remanence Br ∈ [min, max] when
/// the magnitudes are free; then, with a free field, B = |B| (sin θ_B cos φ_B, sin θ_B sin φ_B, cos θ_B) (world),
/// |B| ∈ [0, max]; then, with a designed magnet, its centre (3 coordinates in a box) and, with its orientation, its
/// axis a = (sin θ_a cos φ_a, sin θ_a sin φ_a, cos θ_a) (world). The moment per length of an edge in section s is
/// Br_s d_s A/μ0 (the hard-magnetic law), A the rod's cross-section; an edge belongs to the section that holds its
/// midpoint. ∂g/∂(θ_a, φ_a), a turn of the magnet's whole field (its value and gradient at every edge), is the central
/// difference (1e-4 rad) of the analytic gradient rod_gradient at the fixed configuration, as calibration.hpp's
/// material parameters are; every other ∂g/∂p is exact.

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "magvine/core/eigen_types.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/robot/rod.hpp"

namespace magvine::design {

/// What the design may change and the shape it aims at (DESIGN.yaml's `design:`; SI).
struct DesignSpec {
  int sections = 5;
  double remanence = 0.125;  ///< |Br| of every section when the magnitudes are fixed [T]
  /// The magnitudes are free within [min, max] [T] (then `remanence` is unused).
  std::optional<std::pair<double, double>> remanence_bounds;
  std::vector<Vec3> target;         ///< ≥ 2 points equally spaced in arc length from the base to the tip [m]
  std::optional<double> field_max;  ///< the uniform field joins the unknowns, |B| ≤ field_max [T]
};

/// A design problem: the rod (its moment_per_length is what the design sets), the fixed field (the scene's magnets;
/// empty with a free field), the free field's start, the cross-section for the hard-magnetic law.
///
/// Follow-the-leader insertion (thesis A.1.5.2; `insertion_steps` > 0, with a free field): the rod is pushed out of
/// its base in `insertion_steps` equal steps, its distal end first. At step c the distal c/steps of it is out, a
/// clamped rod of that length with about the full rod's edge length, its edges magnetised by the section of the
/// material they carry; it has its own uniform field (|B| ≤ field_max), and the target points within its length
/// (the path, from the base) are its targets. J is the mean over every step's targets: one shared profile, one field
/// per step.
struct DesignProblem {
  robot::RodModel model;
  robot::RodField field;            ///< the fixed field (not with a free one)
  Vec3 start_field = Vec3::Zero();  ///< a free field's first value [T]
  double area = 0.0;                ///< the magnetised cross-section [m²]
  DesignSpec spec;
  robot::RodSolveOptions solver;
  int insertion_steps = 0;  ///< 0: the static design; n: follow-the-leader in n steps
  /// A magnet whose pose joins the unknowns (a design of where the EPM goes): the scene's magnets with their rest
  /// poses (`field` is then theirs, unused), the designed one's index and the box its centre may move in [m]; with
  /// `orientation`, its axis too (the direction of its moment, world; the pose turned from the rest pose by the
  /// shortest rotation, magnetics::pose_at). Not with a free field.
  struct MagnetPosition {
    magnetics::FieldModel magnets;
    std::size_t index = 0;
    Vec3 min = Vec3::Zero();
    Vec3 max = Vec3::Zero();
    bool orientation = false;
  };
  std::optional<MagnetPosition> magnet;
};

/// Checks a problem: sections within [1, edges] each holding an edge midpoint, remanence and bounds in (0, 3] T
/// with min ≤ max, a field to act (fixed or free), and a target a rod of this length can lie on: ≥ 2 finite points,
/// the first at the base, none farther from the base than its arc length, consecutive points no farther apart than
/// their arc spacing (1 % slack each: the rod is nearly inextensible). InputError naming `where` and the field.
void check_design_problem(const DesignProblem& problem, const std::string& where);

/// What check_design_problem refuses: the key under `design.` ("sections", "target.points[3]", ...) and why.
struct DesignProblemIssue {
  std::string key;
  std::string what;
};
/// The first issue check_design_problem would throw for, or none (a file parser names the key's line).
std::optional<DesignProblemIssue> design_problem_issue(const DesignProblem& problem);

/// A design: per section its unit direction (body frame) and remanence [T]; the uniform fields [T] when free (one,
/// or one per insertion step).
struct Design {
  std::vector<Vec3> directions;
  std::vector<double> remanences;
  std::vector<Vec3> fields;
  std::optional<Vec3> magnet_position;  ///< the designed magnet's centre [m]
  std::optional<Vec3> magnet_axis;      ///< its axis (unit, world), when the orientation is designed
};

/// The objective and its exact gradient at parameters p (the layout above; free fields one after another). Holds the
/// last equilibria, one per configuration: the whole rod, or each insertion step.
class DesignObjective {
 public:
  explicit DesignObjective(const DesignProblem& problem);

  int parameters() const { return m_parameters; }
  /// Lower and upper bounds of p.
  VecX lower() const;
  VecX upper() const;
  /// p of a design (directions, magnitudes and fields as in `design`).
  VecX parameters_of(const Design& design) const;
  Design design_of(const VecX& p) const;
  /// The configurations: 1 (statics) or the insertion steps.
  std::size_t configurations() const { return m_configurations.size(); }
  /// A configuration's model with the design's moments, and the field it acts in (default: the last, the whole rod).
  robot::RodModel model_of(const Design& design, std::size_t configuration) const;
  robot::RodModel model_of(const Design& design) const { return model_of(design, configurations() - 1); }
  robot::RodField field_of(const Design& design, std::size_t configuration) const;
  robot::RodField field_of(const Design& design) const { return field_of(design, configurations() - 1); }

  /// J(p) [m²]; with `gradient`, dJ/dp. Infinite when an equilibrium fails or is unstable. Counts evaluations (the p
  /// of the last solve is not solved again).
  double evaluate(const VecX& p, VecX* gradient);
  /// The residuals (x(s_k) − t_k)/√T over every configuration's targets (T of them: |r|² = J) and, with `jacobian`,
  /// dr/dp from the forward sensitivities dx*/dp = −H⁻¹ ∂g/∂p (one factorisation per configuration, one
  /// back-substitution per parameter). False when an equilibrium fails or is unstable. Counts as evaluate does.
  bool residuals(const VecX& p, VecX& r, MatX* jacobian);
  /// The number of residuals, 3T.
  int residual_count() const { return 3 * static_cast<int>(m_target_count); }
  /// Whether parameter i is bounded on both sides by nature (a free remanence, |B|, a magnet's coordinate) rather than
  /// an angle.
  bool is_bounded(int i) const;
  /// The last evaluation's equilibria (one per configuration) and the last configuration's.
  std::vector<robot::RodState> states() const;
  const robot::RodState& state() const { return m_configurations.back().state; }
  int evaluations() const { return m_evaluations; }
  /// The points on a configuration's body at its targets' arc lengths (default: the last configuration).
  std::vector<Vec3> points_on(std::size_t configuration, const robot::RodState& state) const;
  std::vector<Vec3> points_on(const robot::RodState& state) const { return points_on(configurations() - 1, state); }
  /// Where each section lies on the whole rod [m from the base]: from its first edge's start to its last edge's end
  /// (node positions, so that no edge midpoint sits on a boundary: a scene written with these spans magnetises every
  /// edge as the design did).
  std::vector<std::pair<double, double>> section_spans() const;
  /// The target indices of a configuration (into spec.target).
  std::vector<std::size_t> targets_of(std::size_t configuration) const;
  /// The largest distance of any configuration's body from its targets [m].
  double max_error(const std::vector<robot::RodState>& states) const;

 private:
  /// A target point on a configuration's body: its index in spec.target, node i and the weight w of node i + 1.
  struct TargetOnBody {
    std::size_t index;
    int node;
    double weight;
  };
  struct Configuration {
    robot::RodModel model;  ///< without moments (model_of sets them)
    std::vector<int> section_of_edge;
    std::vector<TargetOnBody> targets;
    int field = -1;              ///< which free field acts on it (−1: the fixed field)
    robot::RodModel magnetised;  ///< the last solve's model (model_of) and the field it acted in (field_of)
    robot::RodField acting;
    robot::RodState state;
  };
  /// Solves every configuration's equilibrium of p from the straight rod; false when one fails or, unless
  /// `sensitivities_follow` (their factorisation tells: mark_unstable), is not stable.
  bool equilibria(const VecX& p, Design& design, bool sensitivities_follow);
  /// A sensitivity solve found the last equilibria unstable: they fail from now on, for every caller.
  void mark_unstable();
  /// ∂g/∂p at a configuration's equilibrium (6N × P): the moments through m̂ = Br d A/μ0, its field's through
  /// B(|B|, θ, φ).
  MatX gradient_sensitivity(const Design& design, const VecX& p, std::size_t configuration) const;
  /// Where free field f's three parameters start in p.
  int field_offset(int field) const;
  /// Where the magnet's position starts in p (after the fields); its axis angles follow it.
  int magnet_offset() const { return field_offset(m_fields); }
  /// The magnet's pose of a design (its position and, when designed, its axis).
  magnetics::Pose magnet_pose(const Design& design) const;

  const DesignProblem& m_problem;
  int m_parameters = 0;
  int m_fields = 0;
  std::vector<Configuration> m_configurations;
  std::size_t m_target_count = 0;
  VecX m_solved_p;  ///< the parameters the states were solved for
  bool m_solved_ok = false;
  bool m_stability_known = false;  ///< m_solved_ok includes the stability of the states
  int m_evaluations = 0;
};

struct DesignOptions {
  int max_iterations = 100;  ///< per start
  int starts = 1;            ///< random starts (seeds seed, seed + 1, …): multi_start_design keeps the best
  std::uint64_t seed = 1;    ///< the random first design (directions uniform on the sphere, field start)
  /// Called after every evaluation: evaluations so far, the best RMS so far [m].
  std::function<void(int, double)> progress;
  /// A continuation in the field for snapping designs (multi_start_design): each start is designed first in the field
  /// scaled by 1/stages (a fixed field's value and gradient, or a free field's bound), then 2/stages, …, 1, each stage
  /// from the last one's design, so that a design whose shape lies past a snap is approached from the weak-field side,
  /// where the equilibrium is unique. 1: none. Not with a designed magnet.
  int field_stages = 1;
};

struct DesignResult {
  Design design;
  robot::RodState state;  ///< the design's equilibrium (from the straight rod: what `magvine run` gives); the last
                          ///< insertion step's with insertion
  std::vector<robot::RodState> states;  ///< every configuration's (statics: one)
  double rms = 0.0;                     ///< [m]
  double max_error = 0.0;               ///< [m]
  int iterations = 0;
  int evaluations = 0;  ///< equilibria solved (each with its adjoint for the gradient optimiser)
  double runtime_s = 0.0;
  bool converged = false;  ///< the optimiser's test met (not: the target reached)
  std::string message;     ///< how it ended
  /// One equilibrium solved (an evaluation of J, with its adjoint for the gradient optimiser).
  struct Step {
    int iteration;  ///< gradient (or Jacobian) evaluations so far; the Bayesian baseline: evaluations
    int evaluation;
    double rms;       ///< this evaluation's [m] (infinite where the equilibrium failed)
    double best_rms;  ///< the best so far [m]
    double time_s;    ///< since the start
  };
  std::vector<Step> history;
};

/// A random first design (seeded): directions uniform on the sphere, magnitudes mid-range, a free field at half its
/// bound along a random direction.
Design random_design(const DesignProblem& problem, std::uint64_t seed);

/// Minimises J by L-BFGS-B (LBFGSpp) with the exact gradient from `start`.
DesignResult optimise_design(const DesignProblem& problem, const Design& start, const DesignOptions& options);

/// Minimises J as the least-squares problem it is: Levenberg–Marquardt (Eigen's unsupported module, a port of
/// MINPACK's lmder) with the exact Jacobian of the residuals (DesignObjective::residuals); bounded magnitudes as
/// lo + (hi − lo)(1 + sin u)/2, the angles free (the spherical map is periodic). One Jacobian per iteration.
DesignResult least_squares_design(const DesignProblem& problem, const Design& start, const DesignOptions& options);

enum class DesignMethod { least_squares, lbfgsb, bayesian };

/// `options.starts` designs by `method` from the random designs of seeds seed, seed + 1, …; the best one, with the
/// iterations, evaluations, time and history of all (the history's evaluations counted on across the starts). The
/// Bayesian baseline runs once (its own initial designs are its starts).
DesignResult multi_start_design(const DesignProblem& problem, DesignMethod method, const DesignOptions& options);

/// One of multi_start_design's starts: `method` (not the Bayesian baseline) from the random design of seed
/// options.seed + start, with options.field_stages; its own counts and history, from 0. A sweep split over machines
/// (`magvine design --shard I/N`, docs/cluster.md) runs its starts with this and joins them with join_starts.
DesignResult design_start(const DesignProblem& problem, DesignMethod method, const DesignOptions& options, int start);

/// The starts' results, in start order, as multi_start_design reports them: the best (the first of equal RMS) with
/// every start's iterations, evaluations, time and history counted on across the starts, each history step's best RMS
/// the best so far over the starts.
DesignResult join_starts(std::vector<DesignResult> starts);

/// The derivative-free baseline (the thesis's kind, appendix A.1.4): Bayesian optimisation, a Gaussian-process
/// surrogate of log J (squared-exponential kernel, length scales fitted by marginal likelihood over a grid) and
/// expected improvement maximised over random candidates, from `initial` random designs; one equilibrium per
/// evaluation, no gradient. options.max_iterations counts evaluations after the initial ones.
DesignResult bayesian_design(const DesignProblem& problem, const DesignOptions& options, int initial = 10);

}  // namespace magvine::design
