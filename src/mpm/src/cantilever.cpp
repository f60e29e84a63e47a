#include "magvine/mpm/cantilever.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "magvine/core/error.hpp"
#include "magvine/mpm/sampling.hpp"
#include "magvine/mpm/total_lagrangian.hpp"

namespace magvine::mpm {

template <int D>
Cantilever<D> make_cantilever(const CantileverSpec& spec) {
  if (!(spec.length > 0.0 && spec.thickness > 0.0 && (D == 2 || spec.width > 0.0))) {
    throw InputError("cantilever: length, thickness (and width in 3D) must be positive");
  }
  if (spec.cells_through_thickness < 1 || spec.particles_per_cell < 1) {
    throw InputError("cantilever: cells_through_thickness and particles_per_cell must be at least 1");
  }
  Cantilever<D> c;
  MpmModel<D>& m = c.model;
  m.cell = spec.thickness / spec.cells_through_thickness;
  const double clamp = spec.clamp_length > 0.0 ? spec.clamp_length : 2.0 * m.cell;
  const double room = spec.length + 4.0 * m.cell;
  m.domain_min = VecD<D>::Constant(-room);
  m.domain_max = VecD<D>::Constant(room);
  m.materials = {spec.material};
  m.damping = spec.damping;
  m.plane = spec.plane;
  m.gravity = spec.gravity.template head<D>();
  // Clamp: the nodes at x ≤ 0 that the clamped material's stencils reach (1.5 cells around its cross-section), like
  // the jaws of a real clamp; a beam that curls back past x = 0 passes them freely.
  VecD<D> cmin = m.domain_min, cmax = m.domain_max;
  cmax[0] = 0.0;
  cmin[1] = -0.5 * spec.thickness - 1.5 * m.cell;
  cmax[1] = 0.5 * spec.thickness + 1.5 * m.cell;
  if constexpr (D == 3) {
    cmin[2] = -0.5 * spec.width - 1.5 * m.cell;
    cmax[2] = 0.5 * spec.width + 1.5 * m.cell;
  }
  m.clamps.push_back({cmin, cmax, VecD<D>::Zero()});

  LatticeOptions lattice;
  lattice.spacing = m.cell / spec.particles_per_cell;
  const Vec3 lo(-clamp, -0.5 * spec.thickness, D == 3 ? -0.5 * spec.width : 0.0);
  const Vec3 hi(spec.length, 0.5 * spec.thickness, D == 3 ? 0.5 * spec.width : 0.0);
  const std::vector<Vec3> points = sample_box(lo, hi, lattice, D);
  const double v0 = std::pow(lattice.spacing, D);
  std::vector<VecD<D>> x;
  x.reserve(points.size());
  for (const Vec3& p : points) {
    x.push_back(p.template head<D>());
    m.volume.push_back(v0);
    m.mass.push_back(spec.material.density * v0);
    m.remanence.push_back(p.x() > 0.0 ? VecD<D>(spec.remanence.template head<D>()) : VecD<D>::Zero());
    m.material.push_back(0);
    m.section.push_back(p.x() > 0.0 ? 1 : 0);
    if (p.x() > spec.length - lattice.spacing) c.tip.push_back(static_cast<std::uint32_t>(x.size() - 1));
  }
  c.state = rest_state<D>(x);
  return c;
}

template <int D>
VecD<D> mean_position(const MpmState<D>& state, const std::vector<std::uint32_t>& ids) {
  VecD<D> s = VecD<D>::Zero();
  for (std::uint32_t i : ids) s += state.x[i];
  return ids.empty() ? s : VecD<D>(s / static_cast<double>(ids.size()));
}

bool RestWatch::add(const std::vector<Vec3>& probes) {
  m_history.push_back(probes);
  if (m_history.size() > 11) m_history.pop_front();
  if (m_history.size() < 11) return false;
  double spread = 0.0;
  for (const std::vector<Vec3>& h : m_history) {
    for (std::size_t q = 0; q < probes.size(); ++q) spread = std::max(spread, (h[q] - probes[q]).norm());
  }
  return spread < m_tolerance;
}

template <int D>
SettleResult settle(const MpmModel<D>& model, MpmState<D>& state, MpmWorkspace<D>& ws,
                    const std::function<AppliedField(double)>& field, const std::vector<std::uint32_t>& probe,
                    const SettleOptions& o) {
  SettleResult r;
  const double bound = model.stable_step(o.courant);
  r.time_step = o.time_step > 0.0 ? o.time_step : bound;
  // The probe's path sampled every window/10.
  RestWatch watch(o.tolerance);
  double next_sample = state.time;
  const double start = state.time;
  TlGrid<D> grid;
  TlWorkspace<D> tl_ws;
  if (o.total_lagrangian) grid = make_tl_grid<D>(model, state);
  // Implicit steps: a failed one is taken again at half the length (ImplicitStepper).
  ImplicitStepper<D> implicit(o.total_lagrangian ? &grid : nullptr, r.time_step);
  while (state.time - start < o.max_time) {
    if (o.implicit) {
      ImplicitStats counted;
      r.status = implicit.step(model, field(state.time), state, ws, tl_ws, std::numeric_limits<double>::infinity(),
                               o.newton, &counted);
      r.cg += counted.cg;
      r.newton += counted.newton;
      r.factorizations += counted.factorizations;
      r.retries = implicit.retries();
    } else if (o.total_lagrangian) {
      r.status = tl_step<D>(model, grid, field(state.time), state, tl_ws, r.time_step);
    } else {
      r.status = step(model, field(state.time), state, ws, r.time_step);
    }
    ++r.steps;
    if (!r.status.ok) break;
    if (state.time >= next_sample) {
      next_sample += o.window / 10.0;
      Vec3 probe_at = Vec3::Zero();
      probe_at.head<D>() = mean_position(state, probe);
      if (watch.add({probe_at}) && state.time - start >= o.min_time) {
        r.settled = true;
        break;
      }
    }
  }
  r.time = state.time - start;
  return r;
}

template Cantilever<2> make_cantilever<2>(const CantileverSpec&);
template Cantilever<3> make_cantilever<3>(const CantileverSpec&);
template VecD<2> mean_position<2>(const MpmState<2>&, const std::vector<std::uint32_t>&);
template VecD<3> mean_position<3>(const MpmState<3>&, const std::vector<std::uint32_t>&);
template SettleResult settle<2>(const MpmModel<2>&, MpmState<2>&, MpmWorkspace<2>&,
                                const std::function<AppliedField(double)>&, const std::vector<std::uint32_t>&,
                                const SettleOptions&);
template SettleResult settle<3>(const MpmModel<3>&, MpmState<3>&, MpmWorkspace<3>&,
                                const std::function<AppliedField(double)>&, const std::vector<std::uint32_t>&,
                                const SettleOptions&);

}  // namespace magvine::mpm
