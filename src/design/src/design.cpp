#include "magvine/design/design.hpp"

#include <LBFGSB.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <variant>

#include "design_internal.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/stopwatch.hpp"
#include "magvine/core/text.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/magnet_motion.hpp"
#include "magvine/magnetics/magnetisation.hpp"

namespace magvine::design {

namespace detail {

Vec3 spherical(double theta, double phi) {
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}
Vec3 spherical_d_theta(double theta, double phi) {
  return {std::cos(theta) * std::cos(phi), std::cos(theta) * std::sin(phi), -std::sin(theta)};
}
Vec3 spherical_d_phi(double theta, double phi) {
  return {-std::sin(theta) * std::sin(phi), std::sin(theta) * std::cos(phi), 0.0};
}
std::pair<double, double> angles_of(const Vec3& d) {
  const double n = d.norm();
  if (!(n > 0.0)) return {0.5 * kPi, 0.0};
  return {std::acos(std::clamp(d.z() / n, -1.0, 1.0)), std::atan2(d.y(), d.x())};
}

}  // namespace detail

namespace {

constexpr double kReachSlack = 0.01;   // the target may stretch the rod by 1 % (it is nearly inextensible)
constexpr double kMaxRemanence = 3.0;  // [T], as the scene files' range
constexpr double kTwoPi = 2.0 * kPi;

/// Per section: θ, φ and (free magnitudes) Br.
int per_section(const DesignSpec& spec) {
  return spec.remanence_bounds ? 3 : 2;
}

}  // namespace

void check_design_problem(const DesignProblem& problem, const std::string& where) {
  if (const std::optional<DesignProblemIssue> issue = design_problem_issue(problem)) {
    throw InputError(where, 0, "design." + issue->key, issue->what);
  }
}

std::optional<DesignProblemIssue> design_problem_issue(const DesignProblem& problem) {
  const DesignSpec& spec = problem.spec;
  const robot::RodModel& m = problem.model;
  using Issue = std::optional<DesignProblemIssue>;
  const auto issue = [](std::string key, std::string what) {
    return Issue(DesignProblemIssue{std::move(key), std::move(what)});
  };
  if (spec.sections < 1 || spec.sections > m.edges) {
    return issue("sections", "must be within [1, " + std::to_string(m.edges) + "] (the rod's edges; give more nodes)");
  }
  if (spec.remanence_bounds) {
    const auto [lo, hi] = *spec.remanence_bounds;
    if (!(lo >= 0.0 && hi > 0.0 && hi <= kMaxRemanence))
      return issue("remanence", "bounds must lie within [0, 3] T, max > 0");
    if (lo > hi) return issue("remanence", "min exceeds max: the bounds exclude every design");
  } else if (!(spec.remanence > 0.0 && spec.remanence <= kMaxRemanence)) {
    return issue("remanence", "must be within (0, 3] T");
  }
  if (spec.field_max) {
    if (!(*spec.field_max > 0.0 && *spec.field_max <= 10.0)) return issue("field.free.max", "must be within (0, 10] T");
    if (problem.field)
      return issue("field", "a free field replaces the scene's magnets: give at most a uniform field there");
  } else if (!problem.field) {
    return issue("field", "the scene has no magnets and the field is not free: nothing would move the rod");
  }
  if (!(problem.area > 0.0)) return issue("sections", "the rod has no cross-section to magnetise");
  const std::vector<Vec3>& t = spec.target;
  if (t.size() < 2) return issue("target.points", "needs at least 2 points (base to tip)");
  const double spacing = m.length / static_cast<double>(t.size() - 1);
  for (std::size_t k = 0; k < t.size(); ++k) {
    const std::string key = "target.points[" + std::to_string(k) + "]";
    if (!t[k].allFinite()) return issue(key, "must be finite");
    const double s = spacing * static_cast<double>(k);
    const double reach = (t[k] - m.base_position).norm();
    if (reach > s + kReachSlack * m.length) {
      return issue(key, printf_string("is %.2f mm from the base (robot.base.position), beyond the rod's reach at its "
                                      "arc length %.2f mm (the points run from the base to the tip, equally spaced)",
                                      reach * 1e3, s * 1e3));
    }
    if (k > 0 && (t[k] - t[k - 1]).norm() > spacing * (1.0 + kReachSlack)) {
      return issue(key, printf_string("is %.2f mm from the point before, more than the rod's %.2f mm between them: a "
                                      "target of the wrong length",
                                      (t[k] - t[k - 1]).norm() * 1e3, spacing * 1e3));
    }
  }
  if (m.induced) return issue("sections", "a rod with an induced fill cannot be designed (hard magnetisation only)");
  if (problem.insertion_steps < 0 || problem.insertion_steps > m.edges) {
    return issue("insertion.steps", "must be within [1, " + std::to_string(m.edges) + "] (the rod's edges)");
  }
  if (problem.magnet) {
    const DesignProblem::MagnetPosition& mp = *problem.magnet;
    if (mp.index >= mp.magnets.size()) return issue("magnet.index", "names no magnet of the scene");
    if (std::holds_alternative<magnetics::UniformSource>(mp.magnets.sources[mp.index])) {
      return issue("magnet.index", "names a uniform field, which has no position to design");
    }
    if (!(mp.min.array() <= mp.max.array()).all()) return issue("magnet.min", "exceeds max: the box holds no position");
    if (spec.field_max) return issue("magnet", "a designed magnet and a free uniform field exclude each other");
  }
  if (problem.insertion_steps > 0 && !spec.field_max) {
    return issue("insertion.steps", "a follow-the-leader insertion needs design.field.free (one field per step)");
  }
  return std::nullopt;
}

DesignObjective::DesignObjective(const DesignProblem& problem) : m_problem(problem) {
  const DesignSpec& spec = problem.spec;
  const int steps = problem.insertion_steps;
  m_fields = spec.field_max ? std::max(1, steps) : 0;
  m_parameters =
      spec.sections * per_section(spec) + 3 * m_fields + (problem.magnet ? (problem.magnet->orientation ? 5 : 3) : 0);
  const robot::RodModel& full = problem.model;
  const int n = full.edges;
  const std::size_t k_count = spec.target.size();
  const double spacing = full.length / static_cast<double>(k_count - 1);
  const int configurations = std::max(1, steps);
  for (int c = 0; c < configurations; ++c) {
    Configuration conf;
    // Follow-the-leader: step c + 1 of `steps` has the distal (c + 1)/steps of the rod inserted (its distal end went
    // in first), with about the full rod's edge length; statics: the whole rod.
    const double inserted = steps > 0 ? full.length * (c + 1) / steps : full.length;
    const int edges = steps > 0 ? std::max(1, static_cast<int>(std::lround(n * inserted / full.length))) : n;
    conf.model = full;
    conf.model.length = inserted;
    conf.model.edges = edges;
    conf.model.moment_per_length.clear();
    const double h = inserted / edges;
    for (int j = 0; j < edges; ++j) {
      // The section holding the edge's midpoint, in the material's own coordinate from the proximal end.
      const double material = full.length - inserted + (j + 0.5) * h;
      const int section = static_cast<int>(std::floor(material * spec.sections / full.length));
      conf.section_of_edge.push_back(std::clamp(section, 0, spec.sections - 1));
    }
    for (std::size_t k = 0; k < k_count; ++k) {
      const double s = spacing * static_cast<double>(k);
      if (s > inserted * (1.0 + 1e-9)) break;
      const double u = std::min(s / h, static_cast<double>(edges));  // arc length in edges
      const int i = std::min(static_cast<int>(std::floor(u)), edges - 1);
      conf.targets.push_back({k, i, u - i});
    }
    conf.field = spec.field_max ? (steps > 0 ? c : 0) : -1;
    conf.state = robot::straight_rod(conf.model);
    m_target_count += conf.targets.size();
    m_configurations.push_back(std::move(conf));
  }
}

VecX DesignObjective::lower() const {
  VecX out(m_parameters);
  const DesignSpec& spec = m_problem.spec;
  int at = 0;
  for (int s = 0; s < spec.sections; ++s) {
    out[at++] = 0.0;
    out[at++] = -kTwoPi;
    if (spec.remanence_bounds) out[at++] = spec.remanence_bounds->first;
  }
  for (int f = 0; f < m_fields; ++f) {
    out[at++] = 0.0;
    out[at++] = 0.0;
    out[at++] = -kTwoPi;
  }
  if (m_problem.magnet) out.segment<3>(at) = m_problem.magnet->min;
  if (m_problem.magnet && m_problem.magnet->orientation) out.tail<2>() = Eigen::Vector2d(0.0, -kTwoPi);
  return out;
}

VecX DesignObjective::upper() const {
  VecX out(m_parameters);
  const DesignSpec& spec = m_problem.spec;
  int at = 0;
  for (int s = 0; s < spec.sections; ++s) {
    out[at++] = kPi;
    out[at++] = kTwoPi;
    if (spec.remanence_bounds) out[at++] = spec.remanence_bounds->second;
  }
  for (int f = 0; f < m_fields; ++f) {
    out[at++] = *spec.field_max;
    out[at++] = kPi;
    out[at++] = kTwoPi;
  }
  if (m_problem.magnet) out.segment<3>(at) = m_problem.magnet->max;
  if (m_problem.magnet && m_problem.magnet->orientation) out.tail<2>() = Eigen::Vector2d(kPi, kTwoPi);
  return out;
}

int DesignObjective::field_offset(int field) const {
  return m_problem.spec.sections * per_section(m_problem.spec) + 3 * field;
}

VecX DesignObjective::parameters_of(const Design& design) const {
  const DesignSpec& spec = m_problem.spec;
  VecX p(m_parameters);
  int at = 0;
  for (int s = 0; s < spec.sections; ++s) {
    const auto [theta, phi] = detail::angles_of(design.directions[static_cast<std::size_t>(s)]);
    p[at++] = theta;
    p[at++] = phi;
    if (spec.remanence_bounds) p[at++] = design.remanences[static_cast<std::size_t>(s)];
  }
  for (int f = 0; f < m_fields; ++f) {
    const Vec3 b = static_cast<std::size_t>(f) < design.fields.size() ? design.fields[static_cast<std::size_t>(f)]
                   : design.fields.empty()                            ? Vec3::Zero()
                                                                      : design.fields.back();
    const auto [theta, phi] = detail::angles_of(b);
    p[at++] = b.norm();
    p[at++] = theta;
    p[at++] = phi;
  }
  if (m_problem.magnet) {
    const magnetics::FieldModel& magnets = m_problem.magnet->magnets;
    const magnetics::Pose& rest = magnets.rest_poses[m_problem.magnet->index];
    p.segment<3>(at) = design.magnet_position.value_or(rest.position);
    if (m_problem.magnet->orientation) {
      const auto [theta, phi] = detail::angles_of(design.magnet_axis.value_or(rest.rotation.col(2)));
      p[at + 3] = theta;
      p[at + 4] = phi;
    }
  }
  return p.cwiseMax(lower()).cwiseMin(upper());
}

Design DesignObjective::design_of(const VecX& p) const {
  const DesignSpec& spec = m_problem.spec;
  Design d;
  int at = 0;
  for (int s = 0; s < spec.sections; ++s) {
    d.directions.push_back(detail::spherical(p[at], p[at + 1]));
    at += 2;
    d.remanences.push_back(spec.remanence_bounds ? p[at++] : spec.remanence);
  }
  for (int f = 0; f < m_fields; ++f) {
    d.fields.push_back(p[at] * detail::spherical(p[at + 1], p[at + 2]));
    at += 3;
  }
  if (m_problem.magnet) d.magnet_position = p.segment<3>(at);
  if (m_problem.magnet && m_problem.magnet->orientation) d.magnet_axis = detail::spherical(p[at + 3], p[at + 4]);
  return d;
}

magnetics::Pose DesignObjective::magnet_pose(const Design& design) const {
  const magnetics::Pose& rest = m_problem.magnet->magnets.rest_poses[m_problem.magnet->index];
  return magnetics::pose_at(rest, design.magnet_position.value_or(rest.position),
                            design.magnet_axis.value_or(rest.rotation.col(2)));
}

robot::RodModel DesignObjective::model_of(const Design& design, std::size_t configuration) const {
  const Configuration& conf = m_configurations[configuration];
  robot::RodModel m = conf.model;
  m.moment_per_length.assign(static_cast<std::size_t>(m.edges), Vec3::Zero());
  for (std::size_t j = 0; j < m.moment_per_length.size(); ++j) {
    const auto s = static_cast<std::size_t>(conf.section_of_edge[j]);
    m.moment_per_length[j] =
        magnetics::hard_magnetic_moment<3>(Vec3(design.remanences[s] * design.directions[s]), m_problem.area);
  }
  return m;
}

robot::RodField DesignObjective::field_of(const Design& design, std::size_t configuration) const {
  const int f = m_configurations[configuration].field;
  if (f < 0 && m_problem.magnet && design.magnet_position) {
    std::vector<magnetics::Pose> poses = m_problem.magnet->magnets.rest_poses;
    poses[m_problem.magnet->index] = magnet_pose(design);
    return magnetics::field_function(m_problem.magnet->magnets, std::move(poses));
  }
  if (f < 0) return m_problem.field;
  const Vec3 b = design.fields[static_cast<std::size_t>(f)];
  return robot::RodField([b](const Vec3&) { return magnetics::FieldSample{b, Mat3::Zero()}; });
}

std::vector<Vec3> DesignObjective::points_on(std::size_t configuration, const robot::RodState& state) const {
  const Configuration& conf = m_configurations[configuration];
  std::vector<Vec3> out;
  for (const TargetOnBody& t : conf.targets) {
    const auto i = static_cast<std::size_t>(t.node);
    out.push_back((1.0 - t.weight) * state.x[i] + t.weight * state.x[i + 1]);
  }
  return out;
}

std::vector<std::pair<double, double>> DesignObjective::section_spans() const {
  const Configuration& whole = m_configurations.back();
  const double h = whole.model.length / whole.model.edges;
  std::vector<std::pair<double, double>> out(static_cast<std::size_t>(m_problem.spec.sections), {-1.0, -1.0});
  for (std::size_t j = 0; j < whole.section_of_edge.size(); ++j) {
    auto& span = out[static_cast<std::size_t>(whole.section_of_edge[j])];
    if (span.first < 0.0) span.first = static_cast<double>(j) * h;
    span.second = j + 1 == whole.section_of_edge.size() ? whole.model.length : static_cast<double>(j + 1) * h;
  }
  return out;
}

std::vector<std::size_t> DesignObjective::targets_of(std::size_t configuration) const {
  std::vector<std::size_t> out;
  for (const TargetOnBody& t : m_configurations[configuration].targets) out.push_back(t.index);
  return out;
}

double DesignObjective::max_error(const std::vector<robot::RodState>& states) const {
  double worst = 0.0;
  for (std::size_t c = 0; c < m_configurations.size() && c < states.size(); ++c) {
    const std::vector<Vec3> x = points_on(c, states[c]);
    for (std::size_t k = 0; k < x.size(); ++k) {
      worst = std::max(worst, (x[k] - m_problem.spec.target[m_configurations[c].targets[k].index]).norm());
    }
  }
  return worst;
}

bool DesignObjective::is_bounded(int i) const {
  const DesignSpec& spec = m_problem.spec;
  const int stride = per_section(spec);
  if (i < spec.sections * stride) return spec.remanence_bounds && i % stride == 2;
  if (m_problem.magnet && i >= magnet_offset()) return i < magnet_offset() + 3;  // its box's coordinates, not its axis
  return (i - spec.sections * stride) % 3 == 0;                                  // |B| of a field (then θ_B, φ_B)
}

std::vector<robot::RodState> DesignObjective::states() const {
  std::vector<robot::RodState> out;
  for (const Configuration& c : m_configurations) out.push_back(c.state);
  return out;
}

bool DesignObjective::equilibria(const VecX& p, Design& design, bool sensitivities_follow) {
  design = design_of(p);
  // The same p as the last solve (Levenberg–Marquardt asks for the Jacobian where it has just taken the residuals):
  // the same equilibria, not solved or counted again.
  if (!(m_solved_p.size() == p.size() && m_solved_p == p)) {
    ++m_evaluations;
    m_solved_p = p;
    m_solved_ok = true;
    m_stability_known = false;
    for (std::size_t c = 0; c < m_configurations.size(); ++c) {
      Configuration& conf = m_configurations[c];
      conf.magnetised = model_of(design, c);
      conf.acting = field_of(design, c);
      // From the straight rod, as `magvine run` solves the scene: J is a function of p alone.
      conf.state = robot::straight_rod(conf.magnetised);
      m_solved_ok =
          m_solved_ok && robot::solve_rod_statics(conf.magnetised, conf.acting, conf.state, m_problem.solver).converged;
    }
  }
  // Stable as well: an equilibrium whose Hessian is not positive definite (a saddle the solver stopped on) has no
  // sensitivity and would not stay where it is; every method refuses it alike. A caller about to solve with the
  // Hessian learns it from that factorisation, so the check costs a factorisation only where none follows.
  if (m_solved_ok && !m_stability_known && !sensitivities_follow) {
    for (const Configuration& conf : m_configurations) {
      const MatX none = MatX::Zero(6 * conf.magnetised.edges, 1);
      m_solved_ok = m_solved_ok && robot::rod_hessian_solve(conf.magnetised, conf.acting, conf.state, none).has_value();
    }
    m_stability_known = true;
  }
  return m_solved_ok;
}

void DesignObjective::mark_unstable() {
  m_solved_ok = false;
  m_stability_known = true;
}

MatX DesignObjective::gradient_sensitivity(const Design& design, const VecX& p, std::size_t configuration) const {
  const DesignSpec& spec = m_problem.spec;
  const Configuration& conf = m_configurations[configuration];
  const robot::RodModel& model = conf.magnetised;
  const robot::RodField& field = conf.acting;
  const int n = model.edges;
  MatX out = MatX::Zero(6 * n, m_parameters);
  const MatX by_moment = robot::rod_moment_sensitivity(model, field, conf.state);                  // 6N × 3N
  const double per_tesla = magnetics::hard_magnetic_moment<3>(Vec3::UnitX(), m_problem.area).x();  // A/μ0
  const int stride = per_section(spec);
  for (int j = 0; j < n; ++j) {
    const int s = conf.section_of_edge[static_cast<std::size_t>(j)];
    const int at = s * stride;
    const auto block = by_moment.middleCols<3>(3 * j);
    const double br = design.remanences[static_cast<std::size_t>(s)];
    out.col(at) += br * per_tesla * (block * detail::spherical_d_theta(p[at], p[at + 1]));
    out.col(at + 1) += br * per_tesla * (block * detail::spherical_d_phi(p[at], p[at + 1]));
    if (spec.remanence_bounds) out.col(at + 2) += per_tesla * (block * design.directions[static_cast<std::size_t>(s)]);
  }
  if (m_problem.magnet && design.magnet_position) {
    // Moving the magnet by δ translates its own field by δ (the others stay): the sensitivity to that source alone.
    const magnetics::FieldModel& all = m_problem.magnet->magnets;
    magnetics::FieldModel one;
    one.add(all.sources[m_problem.magnet->index], all.rest_poses[m_problem.magnet->index]);
    const magnetics::Pose pose = magnet_pose(design);
    out.middleCols<3>(magnet_offset()) =
        robot::rod_field_translation_sensitivity(model, magnetics::field_function(one, {pose}), conf.state);
    if (m_problem.magnet->orientation) {
      // A turn of the whole field: central differences of the analytic gradient over the axis angles, 1e-4 rad: the
      // truncation ~h²/6 ≈ 2e-9 relative, and the field's own rounding (the exact cylinder's, ~1e-11 relative, which
      // differs between builds: at 1e-6 rad it reached 1.5e-5 in the minimal build) divided by h stays ~1e-7.
      const int at = magnet_offset() + 3;
      constexpr double kTurn = 1e-4;
      for (int k = 0; k < 2; ++k) {
        VecX plus = p;
        VecX minus = p;
        plus[at + k] += kTurn;
        minus[at + k] -= kTurn;
        out.col(at + k) = (robot::rod_gradient(model, field_of(design_of(plus), configuration), conf.state) -
                           robot::rod_gradient(model, field_of(design_of(minus), configuration), conf.state)) /
                          (2.0 * kTurn);
      }
    }
  }
  if (conf.field >= 0) {
    const int at = field_offset(conf.field);
    const MatX by_field = robot::rod_uniform_field_sensitivity(model, conf.state);  // 6N × 3
    out.col(at) = by_field * detail::spherical(p[at + 1], p[at + 2]);
    out.col(at + 1) = p[at] * (by_field * detail::spherical_d_theta(p[at + 1], p[at + 2]));
    out.col(at + 2) = p[at] * (by_field * detail::spherical_d_phi(p[at + 1], p[at + 2]));
  }
  return out;
}

double DesignObjective::evaluate(const VecX& p, VecX* gradient) {
  const DesignSpec& spec = m_problem.spec;
  if (gradient != nullptr) *gradient = VecX::Zero(m_parameters);
  const double failed = std::numeric_limits<double>::infinity();
  Design design;
  if (!equilibria(p, design, gradient != nullptr)) return failed;
  const double count = static_cast<double>(m_target_count);
  double j_value = 0.0;
  for (std::size_t c = 0; c < m_configurations.size(); ++c) {
    const Configuration& conf = m_configurations[c];
    const std::vector<Vec3> x = points_on(c, conf.state);
    for (std::size_t k = 0; k < x.size(); ++k)
      j_value += (x[k] - spec.target[conf.targets[k].index]).squaredNorm() / count;
    if (gradient == nullptr) continue;
    // ∂J/∂x_i through the interpolation; the adjoint H λ = ∂J/∂x; dJ/dp = −(∂g/∂p)ᵀ λ.
    std::vector<Vec3> per_node(static_cast<std::size_t>(conf.model.edges) + 1, Vec3::Zero());
    for (std::size_t k = 0; k < x.size(); ++k) {
      const TargetOnBody& t = conf.targets[k];
      const Vec3 r = 2.0 / count * (x[k] - spec.target[t.index]);
      per_node[static_cast<std::size_t>(t.node)] += (1.0 - t.weight) * r;
      per_node[static_cast<std::size_t>(t.node) + 1] += t.weight * r;
    }
    const std::optional<MatX> lambda =
        robot::rod_hessian_solve(conf.magnetised, conf.acting, conf.state, robot::rod_position_covector(per_node));
    if (!lambda) {  // not a stable equilibrium
      mark_unstable();
      return failed;
    }
    *gradient -= gradient_sensitivity(design, p, c).transpose() * lambda->col(0);
  }
  if (gradient != nullptr) m_stability_known = true;  // every configuration's Hessian factored
  return j_value;
}

bool DesignObjective::residuals(const VecX& p, VecX& r, MatX* jacobian) {
  const DesignSpec& spec = m_problem.spec;
  Design design;
  if (!equilibria(p, design, jacobian != nullptr)) return false;
  const auto count = static_cast<Eigen::Index>(m_target_count);
  const double scale = 1.0 / std::sqrt(static_cast<double>(count));
  r.resize(3 * count);
  if (jacobian != nullptr) jacobian->setZero(3 * count, m_parameters);
  Eigen::Index row = 0;
  for (std::size_t c = 0; c < m_configurations.size(); ++c) {
    const Configuration& conf = m_configurations[c];
    const std::vector<Vec3> x = points_on(c, conf.state);
    for (std::size_t k = 0; k < x.size(); ++k) {
      r.segment<3>(3 * (row + static_cast<Eigen::Index>(k))) = scale * (x[k] - spec.target[conf.targets[k].index]);
    }
    if (jacobian != nullptr) {
      const std::optional<MatX> dx =
          robot::rod_hessian_solve(conf.magnetised, conf.acting, conf.state, -gradient_sensitivity(design, p, c));
      if (!dx) {  // not a stable equilibrium
        mark_unstable();
        return false;
      }
      for (std::size_t k = 0; k < x.size(); ++k) {
        const TargetOnBody& t = conf.targets[k];
        const Eigen::Index at = 3 * (row + static_cast<Eigen::Index>(k));
        // Node i's position unknowns sit in block i − 1 (node 0 is clamped).
        if (t.node >= 1) jacobian->middleRows<3>(at) += scale * (1.0 - t.weight) * dx->middleRows<3>(6 * (t.node - 1));
        jacobian->middleRows<3>(at) += scale * t.weight * dx->middleRows<3>(6 * t.node);
      }
    }
    row += static_cast<Eigen::Index>(x.size());
  }
  if (jacobian != nullptr) m_stability_known = true;  // every configuration's Hessian factored
  return true;
}

Design random_design(const DesignProblem& problem, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const auto on_sphere = [&] {
    Vec3 v;
    do {
      v = Vec3(normal(rng), normal(rng), normal(rng));
    } while (!(v.norm() > 1e-6));
    return Vec3(v.normalized());
  };
  Design d;
  const DesignSpec& spec = problem.spec;
  for (int s = 0; s < spec.sections; ++s) {
    d.directions.push_back(on_sphere());
    d.remanences.push_back(spec.remanence_bounds ? 0.5 * (spec.remanence_bounds->first + spec.remanence_bounds->second)
                                                 : spec.remanence);
  }
  if (spec.field_max) {
    const Vec3 b = problem.start_field.isZero() ? Vec3(0.5 * *spec.field_max * on_sphere()) : problem.start_field;
    d.fields.assign(static_cast<std::size_t>(std::max(1, problem.insertion_steps)), b);
  }
  if (problem.magnet) {  // where the scene puts it, within its box
    const Vec3 at = problem.magnet->magnets.rest_poses[problem.magnet->index].position;
    d.magnet_position = at.cwiseMax(problem.magnet->min).cwiseMin(problem.magnet->max);
    if (problem.magnet->orientation)
      d.magnet_axis = problem.magnet->magnets.rest_poses[problem.magnet->index].rotation.col(2);
  }
  return d;
}

DesignResult optimise_design(const DesignProblem& problem, const Design& start, const DesignOptions& options) {
  const Stopwatch clock;
  DesignObjective objective(problem);
  detail::BestTracker best(objective, clock, options.progress);
  LBFGSpp::LBFGSBParam<double> param;
  param.m = 10;
  param.max_iterations = options.max_iterations;
  // Converged when the projected gradient is below 1e-6 mm²/rad (J in mm²), or J has fallen by less than 1e-10 of
  // itself over the last 3 iterations.
  param.epsilon = 1e-6;
  param.epsilon_rel = 0.0;
  param.past = 3;
  param.delta = 1e-10;
  param.max_linesearch = 40;
  LBFGSpp::LBFGSBSolver<double> solver(param);
  const double to_mm2 = 1e6;  // the optimiser sees J in mm² (its tolerances are absolute)
  const auto f = [&](const VecX& p, VecX& grad) {
    const double j = objective.evaluate(p, &grad);
    best.record(p, j);
    grad *= to_mm2;
    return std::isfinite(j) ? to_mm2 * j : std::numeric_limits<double>::max();
  };
  VecX p = objective.parameters_of(start);
  double fx = 0.0;
  DesignResult out;
  try {
    out.iterations = solver.minimize(f, p, fx, objective.lower(), objective.upper());
    out.converged = out.iterations < options.max_iterations;
    out.message = out.converged ? "converged (the projected gradient or J's decrease below tolerance)"
                                : "stopped at the iteration limit";
  } catch (const std::exception& e) {  // LBFGSpp's line search gives up where no descent is left
    out.iterations = -1;
    out.converged = false;
    out.message = std::string("the optimiser stopped: ") + e.what();
  }
  best.finish(out);
  return out;
}

namespace {

/// The problem in the field scaled by s: a fixed field's value, gradient and curvature, or a free field's bound and
/// start.
DesignProblem scaled_field(const DesignProblem& problem, double s) {
  DesignProblem out = problem;
  if (problem.spec.field_max) {
    out.spec.field_max = s * *problem.spec.field_max;
    out.start_field = s * problem.start_field;
    return out;
  }
  const robot::RodField field = problem.field;
  magnetics::FieldFunction::Curvature curvature;
  if (field.curvature()) {
    curvature = [field, s](const Vec3& x, const Vec3& w) { return Mat3(s * field.curvature()(x, w)); };
  }
  out.field = robot::RodField(
      [field, s](const Vec3& x) {
        magnetics::FieldSample f = field(x);
        return magnetics::FieldSample{s * f.b, s * f.g};
      },
      curvature);
  return out;
}

/// One start by `method`, with the field continuation of options.field_stages: the stages' counts and histories joined
/// (the history's RMS is each stage's, in its own field), the last stage's design.
DesignResult continued_design(const DesignProblem& problem, DesignMethod method, const Design& first,
                              const DesignOptions& options) {
  const auto run = [&](const DesignProblem& p, const Design& from) {
    return method == DesignMethod::lbfgsb ? optimise_design(p, from, options) : least_squares_design(p, from, options);
  };
  const int stages = std::max(1, options.field_stages);
  if (stages == 1) return run(problem, first);
  if (problem.magnet)
    throw InputError("design: the field continuation scales a fixed or free field, not a designed magnet's");
  DesignResult out;
  Design from = first;
  std::vector<DesignResult::Step> history;
  int iterations = 0;
  int evaluations = 0;
  double runtime = 0.0;
  for (int k = 1; k <= stages; ++k) {
    const DesignProblem stage = k == stages ? problem : scaled_field(problem, static_cast<double>(k) / stages);
    DesignResult r = run(stage, from);
    for (DesignResult::Step step : r.history) {
      step.iteration += iterations;
      step.evaluation += evaluations;
      step.time_s += runtime;
      history.push_back(step);
    }
    iterations += std::max(0, r.iterations);
    evaluations += r.evaluations;
    runtime += r.runtime_s;
    from = r.design;
    out = std::move(r);
  }
  out.iterations = iterations;
  out.evaluations = evaluations;
  out.runtime_s = runtime;
  out.history = std::move(history);
  out.message += " (field continuation, " + std::to_string(stages) + " stages)";
  return out;
}

}  // namespace

DesignResult design_start(const DesignProblem& problem, DesignMethod method, const DesignOptions& options, int start) {
  if (method == DesignMethod::bayesian) throw InputError("design: the Bayesian baseline runs once; it has no starts");
  if (start < 0) throw InputError("design: a start's index must be >= 0");
  DesignOptions one = options;
  one.seed = options.seed + static_cast<std::uint64_t>(start);
  return continued_design(problem, method, random_design(problem, one.seed), one);
}

DesignResult join_starts(std::vector<DesignResult> starts) {
  if (starts.empty()) throw InputError("design: no start to join");
  const std::size_t count = starts.size();
  std::size_t best = 0;
  double best_rms = std::numeric_limits<double>::infinity();  // of the starts before this one
  int iterations = 0;
  int evaluations = 0;
  double runtime = 0.0;
  std::vector<DesignResult::Step> history;
  for (std::size_t k = 0; k < count; ++k) {
    const DesignResult& r = starts[k];
    const int iteration_offset = history.empty() ? 0 : history.back().iteration;
    for (DesignResult::Step s : r.history) {
      s.iteration += iteration_offset;
      s.evaluation += evaluations;
      s.time_s += runtime;
      s.best_rms = std::min(s.best_rms, k == 0 ? s.best_rms : best_rms);
      history.push_back(s);
    }
    iterations += std::max(0, r.iterations);
    evaluations += r.evaluations;
    runtime += r.runtime_s;
    if (k == 0 || r.rms < best_rms) {  // the first of equal RMS
      best = k;
      best_rms = r.rms;
    }
  }
  DesignResult out = std::move(starts[best]);
  out.iterations = iterations;
  out.evaluations = evaluations;
  out.runtime_s = runtime;
  out.history = std::move(history);
  if (count > 1) out.message += " (the best of " + std::to_string(count) + " starts)";
  return out;
}

DesignResult multi_start_design(const DesignProblem& problem, DesignMethod method, const DesignOptions& options) {
  if (method == DesignMethod::bayesian) return bayesian_design(problem, options);
  std::vector<DesignResult> starts;
  int evaluations = 0;  // of the starts before this one
  double best_rms = std::numeric_limits<double>::infinity();
  for (int start = 0; start < std::max(1, options.starts); ++start) {
    DesignOptions one = options;
    if (options.progress) {
      one.progress = [&, evaluations](int e, double rms) {
        options.progress(evaluations + e, std::min(rms, best_rms));
      };
    }
    starts.push_back(design_start(problem, method, one, start));
    evaluations += starts.back().evaluations;
    best_rms = std::min(best_rms, starts.back().rms);
  }
  return join_starts(std::move(starts));
}

namespace detail {

BestTracker::BestTracker(DesignObjective& objective, const Stopwatch& clock, std::function<void(int, double)> progress,
                         bool counts_iterations)
    : m_objective(objective), m_clock(clock), m_progress(std::move(progress)), m_counts_iterations(counts_iterations) {}

void BestTracker::record(const VecX& p, double j) {
  const double rms = std::isfinite(j) ? std::sqrt(j) : std::numeric_limits<double>::infinity();
  if (rms < m_best_rms) {
    m_best_rms = rms;
    m_best_p = p;
    m_best_states = m_objective.states();
  }
  const int iteration = m_counts_iterations ? m_iterations : m_objective.evaluations();
  m_history.push_back({iteration, m_objective.evaluations(), rms, m_best_rms, m_clock.seconds()});
  if (m_progress) m_progress(m_objective.evaluations(), m_best_rms);
}

void BestTracker::finish(DesignResult& out) const {
  out.evaluations = m_objective.evaluations();
  out.history = m_history;
  out.runtime_s = m_clock.seconds();
  if (m_best_p.size() == 0) {
    out.rms = std::numeric_limits<double>::infinity();
    out.max_error = std::numeric_limits<double>::infinity();
    out.message = "no design had an equilibrium: " + out.message;
    out.converged = false;
    return;
  }
  out.design = m_objective.design_of(m_best_p);
  out.states = m_best_states;
  out.state = m_best_states.back();
  out.rms = m_best_rms;
  out.max_error = m_objective.max_error(m_best_states);
}

}  // namespace detail

}  // namespace magvine::design
