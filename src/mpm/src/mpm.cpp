#include "magvine/mpm/mpm.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>

#include "magvine/core/units.hpp"

namespace magvine::mpm {
namespace {

constexpr int kSlabCells = 4;           // a particle writes 3 nodes along an axis: slabs 4 cells apart never share one
constexpr double kMaxJ = 100.0;         // |det F| beyond this is an explosion, not a deformation
constexpr double kMaxCellsPerStep = 1;  // a particle moving a whole cell in one step has broken the CFL bound
constexpr std::int64_t kParallelMin = 4096;  // below this many items a loop runs on one thread (fork cost)

template <int D>
using Index = Eigen::Matrix<std::int64_t, D, 1>;

/// Quadratic B-spline weights and the base node of a particle (eq 3.2).
template <int D>
struct Stencil {
  Index<D> base;
  VecD<D> fx;                      // x/δx − base, in [0.5, 1.5)
  std::array<std::array<double, 3>, D> w;

  Stencil(const VecD<D>& x, double inv_dx) {
    for (int a = 0; a < D; ++a) {
      const double s = x[a] * inv_dx;
      base[a] = static_cast<std::int64_t>(std::floor(s - 0.5));
      fx[a] = s - static_cast<double>(base[a]);
      w[a][0] = 0.5 * (1.5 - fx[a]) * (1.5 - fx[a]);
      w[a][1] = 0.75 - (fx[a] - 1.0) * (fx[a] - 1.0);
      w[a][2] = 0.5 * (fx[a] - 0.5) * (fx[a] - 0.5);
    }
  }
};

/// Strides of a box's linear index (the last axis fastest).
template <int D>
Index<D> strides(const Index<D>& n) {
  Index<D> s;
  s[D - 1] = 1;
  for (int a = D - 2; a >= 0; --a) s[a] = s[a + 1] * n[a + 1];
  return s;
}

/// Visits the 3^D stencil nodes as (linear index, weight, offset per axis 0..2) for a box with strides `st` whose
/// first node is the stencil's base at linear index `first`; the last axis fastest.
template <int D, typename Fn>
void for_nodes(const Stencil<D>& s, std::int64_t first, const Index<D>& st, Fn&& fn) {
  if constexpr (D == 2) {
    for (int i = 0; i < 3; ++i) {
      const std::int64_t ki = first + i * st[0];
      for (int j = 0; j < 3; ++j) fn(ki + j, s.w[0][i] * s.w[1][j], i, j, 0);
    }
  } else {
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        const std::int64_t kij = first + i * st[0] + j * st[1];
        const double wij = s.w[0][i] * s.w[1][j];
        for (int k = 0; k < 3; ++k) fn(kij + k, wij * s.w[2][k], i, j, k);
      }
  }
}

template <int D>
std::int64_t linear(const Index<D>& i, const Index<D>& lo, const Index<D>& n) {
  std::int64_t k = 0;
  for (int a = 0; a < D; ++a) k = k * n[a] + (i[a] - lo[a]);
  return k;
}

template <int D>
Vec3 to3(const VecD<D>& x) {
  if constexpr (D == 2) return Vec3(x[0], x[1], 0.0);
  else return x;
}

template <int D>
VecD<D> from3(const Vec3& x) {
  if constexpr (D == 2) return VecD<D>(x[0], x[1]);
  else return x;
}

/// Applies a wall/obstacle condition to v for an outward normal n (pointing away from the solid, into the body).
template <int D>
void apply_boundary(VecD<D>& v, const VecD<D>& n, Boundary kind, double mu) {
  const double vn = v.dot(n);
  if (vn >= 0.0) return;  // separating: free (eq 3.21)
  if (kind == Boundary::kSticky) {
    v.setZero();
    return;
  }
  VecD<D> vt = v - vn * n;
  if (kind == Boundary::kFriction) {
    const double t = vt.norm();
    const double keep = t > 0.0 ? std::max(0.0, 1.0 - mu * (-vn) / t) : 0.0;
    vt *= keep;
  }
  v = vt;
}

/// Ensures the field box covers the grid box and matches the field's version; evaluates new nodes in parallel.
template <int D>
void refresh_field(const AppliedField& field, double dx, MpmWorkspace<D>& ws) {
  bool covers = ws.field_valid && ws.field_version == field.version;
  for (int a = 0; covers && a < D; ++a) {
    covers = ws.lo[a] >= ws.field_lo[a] && ws.lo[a] + ws.n[a] <= ws.field_lo[a] + ws.field_n[a];
  }
  if (covers) return;
  constexpr std::int64_t kMargin = 8;  // cells of slack so a moving body does not re-evaluate every step
  ws.field_lo = ws.lo.array() - kMargin;
  ws.field_n = ws.n.array() + 2 * kMargin;
  const std::int64_t total = ws.field_n.prod();
  ws.field_b.resize(static_cast<std::size_t>(total));
  ws.field_g.resize(static_cast<std::size_t>(total));
#pragma omp parallel for schedule(static) if (total > kParallelMin)
  for (std::int64_t k = 0; k < total; ++k) {
    Index<D> i;
    std::int64_t r = k;
    for (int a = D - 1; a >= 0; --a) {
      i[a] = ws.field_lo[a] + r % ws.field_n[a];
      r /= ws.field_n[a];
    }
    const VecD<D> x = i.template cast<double>() * dx;
    const magnetics::FieldSample s = field.sample(to3<D>(x));
    ws.field_b[static_cast<std::size_t>(k)] = from3<D>(s.b);
    ws.field_g[static_cast<std::size_t>(k)] = s.g.template topLeftCorner<D, D>();
  }
  ws.field_version = field.version;
  ws.field_valid = true;
}

}  // namespace

double wave_speed(const Material& m) {
  return std::sqrt((m.bulk_modulus + 4.0 / 3.0 * m.shear_modulus) / m.density);
}

double Obstacle::distance(const Vec3& x, Vec3* normal) const {
  switch (shape) {
    case Shape::kHalfSpace: {
      *normal = b;
      return (x - a).dot(b);
    }
    case Shape::kSphere: {
      const Vec3 d = x - a;
      const double r = d.norm();
      *normal = r > 0.0 ? Vec3(d / r) : Vec3::UnitZ();
      return r - radius;
    }
    case Shape::kCylinder: {
      const Vec3 axis = (b - a).normalized();
      const Vec3 d = x - a;
      const Vec3 radial = d - d.dot(axis) * axis;
      const double r = radial.norm();
      const double along = d.dot(axis);
      const double len = (b - a).norm();
      const double dr = r - radius;
      const double da = std::max(-along, along - len);
      if (dr > 0.0 || da > 0.0) {  // outside: distance to the solid, normal along the nearest offset
        const Vec3 off = (dr > 0.0 ? Vec3(radial / r * dr) : Vec3::Zero()) +
                         (da > 0.0 ? Vec3((along < 0.0 ? -1.0 : 1.0) * da * axis) : Vec3::Zero());
        *normal = off.normalized();
        return off.norm();
      }
      if (dr > da) {
        *normal = r > 0.0 ? Vec3(radial / r) : Vec3::UnitX();
        return dr;
      }
      *normal = (along < 0.5 * len ? -1.0 : 1.0) * axis;
      return da;
    }
    case Shape::kBox:
    default: {
      const Vec3 c = 0.5 * (a + b);
      const Vec3 h = 0.5 * (b - a);
      const Vec3 q = (x - c).cwiseAbs() - h;
      const Vec3 sign = (x - c).cwiseSign();
      if ((q.array() > 0.0).any()) {
        const Vec3 out = q.cwiseMax(0.0).cwiseProduct(sign);
        *normal = out.normalized();
        return out.norm();
      }
      int axis = 0;
      q.maxCoeff(&axis);
      *normal = Vec3::Zero();
      (*normal)[axis] = sign[axis] == 0.0 ? 1.0 : sign[axis];
      return q[axis];
    }
  }
}

template <int D>
double MpmModel<D>::stable_step(double courant) const {
  double c = 0.0;
  for (const Material& m : materials) c = std::max(c, wave_speed(m));
  return c > 0.0 ? courant * cell / c : std::numeric_limits<double>::infinity();
}

template <int D>
MpmState<D> rest_state(const std::vector<VecD<D>>& positions) {
  MpmState<D> s;
  s.x = positions;
  s.v.assign(positions.size(), VecD<D>::Zero());
  s.c.assign(positions.size(), MatD<D>::Zero());
  s.f.assign(positions.size(), MatD<D>::Identity());
  return s;
}

template <int D>
MatD<D> elastic_stress(const Material& m, const MatD<D>& f) {
  const double j = f.determinant();
  const MatD<D> f_inv_t = f.inverse().transpose();
  const double i1 = f.squaredNorm() + (D == 2 ? 1.0 : 0.0);  // plane strain: F33 = 1
  const double j23 = 1.0 / std::cbrt(j * j);                   // J^(−2/3)
  return m.shear_modulus * j23 * (f - (i1 / 3.0) * f_inv_t) + m.bulk_modulus * j * (j - 1.0) * f_inv_t;
}

template <int D>
double strain_energy_density(const Material& m, const MatD<D>& f) {
  const double j = f.determinant();
  const double i1 = f.squaredNorm() + (D == 2 ? 1.0 : 0.0);
  return 0.5 * m.shear_modulus * (i1 / std::cbrt(j * j) - 3.0) + 0.5 * m.bulk_modulus * (j - 1.0) * (j - 1.0);
}

template <int D>
double kinetic_energy(const MpmModel<D>& model, const MpmState<D>& state) {
  double e = 0.0;
  for (std::size_t p = 0; p < model.size(); ++p) e += 0.5 * model.mass[p] * state.v[p].squaredNorm();
  return e;
}

template <int D>
StepStatus step(const MpmModel<D>& model, const AppliedField& field, MpmState<D>& state, MpmWorkspace<D>& ws,
                double dt) {
  const std::size_t np = model.size();
  const double dx = model.cell;
  const double inv_dx = 1.0 / dx;
  const double d_inv = 4.0 * inv_dx * inv_dx;  // D⁻¹ of the quadratic B-spline
  const bool general = field.kind == AppliedField::Kind::kGeneral;
  const bool uniform = field.kind == AppliedField::Kind::kUniform;
  const VecD<D> b_uniform = from3<D>(field.uniform);

  // The grid box: every node some particle's stencil touches (a parallel min/max, so order does not matter).
  Index<D> lo = Index<D>::Constant(std::numeric_limits<std::int64_t>::max());
  Index<D> hi = Index<D>::Constant(std::numeric_limits<std::int64_t>::min());
  std::atomic<std::int64_t> nonfinite{-1};
  const auto n_points = static_cast<std::int64_t>(np);
#pragma omp parallel if (n_points > kParallelMin)
  {
    Index<D> my_lo = lo, my_hi = hi;
#pragma omp for schedule(static) nowait
    for (std::int64_t pp = 0; pp < n_points; ++pp) {
      const VecD<D>& x = state.x[static_cast<std::size_t>(pp)];
      if (!x.allFinite()) {
        nonfinite = pp;
        continue;
      }
      for (int a = 0; a < D; ++a) {
        const auto b = static_cast<std::int64_t>(std::floor(x[a] * inv_dx - 0.5));
        my_lo[a] = std::min(my_lo[a], b);
        my_hi[a] = std::max(my_hi[a], b + 2);
      }
    }
#pragma omp critical(mpm_box)
    {
      lo = lo.cwiseMin(my_lo);
      hi = hi.cwiseMax(my_hi);
    }
  }
  if (nonfinite >= 0) return {false, "particle " + std::to_string(nonfinite.load()) + " has a non-finite position"};
  ws.lo = lo;
  ws.n = hi - lo + Index<D>::Ones();
  const auto nodes = static_cast<std::size_t>(ws.n.prod());
  ws.node.resize(nodes);
  const auto n_nodes = static_cast<std::int64_t>(nodes);
#pragma omp parallel for schedule(static) if (n_nodes > kParallelMin)
  for (std::int64_t k = 0; k < n_nodes; ++k) ws.node[static_cast<std::size_t>(k)].setZero();
  const Index<D> stride = strides<D>(ws.n);
  if (general) {
    ws.node_moment.assign(nodes, VecD<D>::Zero());
    refresh_field(field, dx, ws);
  }
  const Index<D> field_stride = general ? strides<D>(ws.field_n) : Index<D>::Zero();

  // Slabs along the longest axis, particles bucketed by slab (counting sort, stable: deterministic order).
  int axis = 0;
  ws.n.maxCoeff(&axis);
  const auto slabs = static_cast<std::size_t>((ws.n[axis] + kSlabCells - 1) / kSlabCells);
  ws.slab_count.assign(slabs + 1, 0);
  ws.slab_order.resize(np);
  ws.slab_key.resize(np);
#pragma omp parallel for schedule(static) if (n_points > kParallelMin)
  for (std::int64_t pp = 0; pp < n_points; ++pp) {
    const auto b = static_cast<std::int64_t>(std::floor(state.x[static_cast<std::size_t>(pp)][axis] * inv_dx - 0.5));
    ws.slab_key[static_cast<std::size_t>(pp)] = static_cast<std::uint32_t>((b - lo[axis]) / kSlabCells);
  }
  for (std::size_t p = 0; p < np; ++p) ++ws.slab_count[ws.slab_key[p] + 1];
  for (std::size_t s = 0; s < slabs; ++s) ws.slab_count[s + 1] += ws.slab_count[s];
  ws.slab_start.assign(ws.slab_count.begin(), ws.slab_count.end());
  for (std::size_t p = 0; p < np; ++p) ws.slab_order[ws.slab_start[ws.slab_key[p]]++] = static_cast<std::uint32_t>(p);

  // P2G.
  auto scatter = [&](std::size_t p) {
    const Stencil<D> st(state.x[p], inv_dx);
    const MatD<D>& f = state.f[p];
    MatD<D> stress = elastic_stress<D>(model.materials[model.material[p]], f);
    const VecD<D>& br = model.remanence[p];
    const bool magnetic = (uniform || general) && br.squaredNorm() > 0.0;
    if (magnetic) {
      VecD<D> b = b_uniform;
      if (general) {
        b.setZero();
        for_nodes<D>(st, linear<D>(st.base, ws.field_lo, ws.field_n), field_stride,
                     [&](std::int64_t k, double w, int, int, int) { b += w * ws.field_b[static_cast<std::size_t>(k)]; });
      }
      stress.noalias() -= (1.0 / kMu0) * b * br.transpose();  // eq 3.13
    }
    const double m = model.mass[p];
    const MatD<D> affine = -dt * model.volume[p] * d_inv * stress * f.transpose() + m * state.c[p];
    // The record added at a node: w · (m v + A (x_i − x_p), m), A (x_i − x_p) = Σ_a A.col(a) d_a.
    Eigen::Matrix<double, D + 1, 1> base_rec;
    base_rec.template head<D>() = m * state.v[p];
    base_rec[D] = m;
    std::array<std::array<Eigen::Matrix<double, D + 1, 1>, 3>, D> along;
    for (int a = 0; a < D; ++a)
      for (int o = 0; o < 3; ++o) {
        along[a][o].template head<D>() = affine.col(a) * ((o - st.fx[a]) * dx);
        along[a][o][D] = 0.0;
      }
    const VecD<D> moment = (general && magnetic) ? VecD<D>(model.volume[p] / kMu0 * (f * br)) : VecD<D>::Zero();
    const std::int64_t first = linear<D>(st.base, lo, ws.n);
    if constexpr (D == 3) {
      // Node (i, j, k) gets w_i w_j w_k (r_ij + a_k): r_ij = base + a_i + a_j is formed once per (i, j).
      std::array<Eigen::Matrix<double, 4, 1>, 3> wa2;
      for (int k = 0; k < 3; ++k) wa2[k] = st.w[2][k] * along[2][k];
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          const double wij = st.w[0][i] * st.w[1][j];
          const Eigen::Matrix<double, 4, 1> r = base_rec + along[0][i] + along[1][j];
          Eigen::Matrix<double, 4, 1>* node = &ws.node[static_cast<std::size_t>(first + i * stride[0] + j * stride[1])];
          for (int k = 0; k < 3; ++k) node[k] += wij * (st.w[2][k] * r + wa2[k]);
          if (general && magnetic) {
            VecD<D>* mo = &ws.node_moment[static_cast<std::size_t>(first + i * stride[0] + j * stride[1])];
            for (int k = 0; k < 3; ++k) mo[k] += (wij * st.w[2][k]) * moment;
          }
        }
    } else {
      for_nodes<D>(st, first, stride, [&](std::int64_t k, double w, int i, int j, int) {
        ws.node[static_cast<std::size_t>(k)] += w * (base_rec + along[0][i] + along[1][j]);
        if (general && magnetic) ws.node_moment[static_cast<std::size_t>(k)] += w * moment;
      });
    }
  };
  for (std::size_t colour = 0; colour < 2; ++colour) {
#pragma omp parallel for schedule(dynamic, 1) if (static_cast<std::int64_t>(np) > kParallelMin)
    for (std::size_t s = colour; s < slabs; s += 2) {
      for (std::uint32_t i = ws.slab_count[s]; i < ws.slab_count[s + 1]; ++i) scatter(ws.slab_order[i]);
    }
  }

  // Grid: velocities, forces, damping, boundaries.
  const double damp = 1.0 / (1.0 + model.damping * dt);
  const auto total = static_cast<std::int64_t>(nodes);
#pragma omp parallel for schedule(static) if (total > kParallelMin)
  for (std::int64_t kk = 0; kk < total; ++kk) {
    const auto k = static_cast<std::size_t>(kk);
    const double m = ws.node[k][D];
    if (m <= 0.0) continue;
    Index<D> i;
    std::int64_t r = kk;
    for (int a = D - 1; a >= 0; --a) {
      i[a] = lo[a] + r % ws.n[a];
      r /= ws.n[a];
    }
    const VecD<D> xi = i.template cast<double>() * dx;
    const bool clamped = std::any_of(model.clamps.begin(), model.clamps.end(), [&](const auto& box) {
      return (xi.array() >= box.first.array()).all() && (xi.array() <= box.second.array()).all();
    });
    if (clamped) {
      ws.node[k].template head<D>().setZero();
      continue;
    }
    VecD<D> v = ws.node[k].template head<D>() / m;
    if (general) {  // eq 3.16: f_i = ∇B_iᵀ m_i
      const auto fk = static_cast<std::size_t>(linear<D>(i, ws.field_lo, ws.field_n));
      v += dt / m * (ws.field_g[fk].transpose() * ws.node_moment[k]);
    }
    v += dt * model.gravity;
    v *= damp;
    for (int a = 0; a < D; ++a) {  // domain walls: the nodes within a cell of a wall
      if (xi[a] <= model.domain_min[a] + dx) apply_boundary<D>(v, VecD<D>::Unit(a), model.walls, model.wall_friction);
      if (xi[a] >= model.domain_max[a] - dx) apply_boundary<D>(v, -VecD<D>::Unit(a), model.walls, model.wall_friction);
    }
    for (const Obstacle& ob : model.obstacles) {
      Vec3 n3;
      if (ob.distance(to3<D>(xi), &n3) <= 0.0) apply_boundary<D>(v, from3<D>(n3), ob.boundary, ob.friction);
    }
    ws.node[k].template head<D>() = v;  // now the velocity
  }

  // G2P, with the failure checks.
  std::atomic<std::int64_t> bad{std::numeric_limits<std::int64_t>::max()};
  const auto n_particles = static_cast<std::int64_t>(np);
#pragma omp parallel for schedule(static) if (n_particles > kParallelMin)
  for (std::int64_t pp = 0; pp < n_particles; ++pp) {
    const auto p = static_cast<std::size_t>(pp);
    const Stencil<D> st(state.x[p], inv_dx);
    std::array<std::array<double, 3>, D> d;  // x_i − x_p per axis
    for (int a = 0; a < D; ++a)
      for (int o = 0; o < 3; ++o) d[a][o] = (o - st.fx[a]) * dx;
    VecD<D> v = VecD<D>::Zero();
    MatD<D> b = MatD<D>::Zero();  // Σ w v_i (x_i − x_p)ᵀ
    const std::int64_t first = linear<D>(st.base, lo, ws.n);
    if constexpr (D == 3) {
      // Sum along k first: s = Σ_k w_k v, t = Σ_k w_k d_k v; then the (i, j) weights and offsets apply once.
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          const Eigen::Matrix<double, 4, 1>* node =
              &ws.node[static_cast<std::size_t>(first + i * stride[0] + j * stride[1])];
          Vec3 sum = Vec3::Zero(), moment_k = Vec3::Zero();
          for (int k = 0; k < 3; ++k) {
            const Vec3 wv = st.w[2][k] * node[k].template head<3>();
            sum += wv;
            moment_k += d[2][k] * wv;
          }
          const double wij = st.w[0][i] * st.w[1][j];
          v += wij * sum;
          b.col(0) += (wij * d[0][i]) * sum;
          b.col(1) += (wij * d[1][j]) * sum;
          b.col(2) += wij * moment_k;
        }
    } else {
      for_nodes<D>(st, first, stride, [&](std::int64_t k, double w, int i, int j, int) {
        const VecD<D> wv = w * ws.node[static_cast<std::size_t>(k)].template head<D>();
        v += wv;
        b.col(0) += wv * d[0][i];
        b.col(1) += wv * d[1][j];
      });
    }
    state.v[p] = v;
    state.c[p] = d_inv * b;
    state.f[p] = (MatD<D>::Identity() + dt * state.c[p]) * state.f[p];
    state.x[p] += dt * v;
    const double j = state.f[p].determinant();
    const bool broken = !(j > 0.0 && j < kMaxJ) || !state.x[p].allFinite() || !v.allFinite() ||
                        v.norm() * dt > kMaxCellsPerStep * dx ||
                        (state.x[p].array() < model.domain_min.array()).any() ||
                        (state.x[p].array() > model.domain_max.array()).any();
    if (broken) {
      std::int64_t cur = bad.load();
      while (pp < cur && !bad.compare_exchange_weak(cur, pp)) {
      }
    }
  }
  state.time += dt;
  if (bad.load() == std::numeric_limits<std::int64_t>::max()) return {};

  // Name the first failing particle's cause.
  const auto p = static_cast<std::size_t>(bad.load());
  const double j = state.f[p].determinant();
  std::string what;
  if (!state.x[p].allFinite() || !state.v[p].allFinite()) what = "non-finite position or velocity";
  else if (!(j > 0.0)) what = "inverted (det F = " + std::to_string(j) + ")";
  else if (!(j < kMaxJ)) what = "exploded (det F = " + std::to_string(j) + ")";
  else if (state.v[p].norm() * dt > kMaxCellsPerStep * dx) {
    what = "moves more than a cell per step (|v| = " + std::to_string(state.v[p].norm()) + " m/s)";
  } else {
    what = "left the domain";
  }
  return {false, "particle " + std::to_string(p) + " " + what + " at t = " + std::to_string(state.time) + " s"};
}

template struct MpmModel<2>;
template struct MpmModel<3>;
template MpmState<2> rest_state<2>(const std::vector<VecD<2>>&);
template MpmState<3> rest_state<3>(const std::vector<VecD<3>>&);
template MatD<2> elastic_stress<2>(const Material&, const MatD<2>&);
template MatD<3> elastic_stress<3>(const Material&, const MatD<3>&);
template double strain_energy_density<2>(const Material&, const MatD<2>&);
template double strain_energy_density<3>(const Material&, const MatD<3>&);
template double kinetic_energy<2>(const MpmModel<2>&, const MpmState<2>&);
template double kinetic_energy<3>(const MpmModel<3>&, const MpmState<3>&);
template StepStatus step<2>(const MpmModel<2>&, const AppliedField&, MpmState<2>&, MpmWorkspace<2>&, double);
template StepStatus step<3>(const MpmModel<3>&, const AppliedField&, MpmState<3>&, MpmWorkspace<3>&, double);

}  // namespace magvine::mpm
