#include "magvine/mpm/mpm.hpp"
#include "magvine/magnetics/magnetisation.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

#include "magvine/core/multiversion.hpp"
#include "magvine/core/units.hpp"
#include "grid.hpp"

namespace magvine::mpm {
using namespace detail;  // NOLINT(google-build-using-namespace): the module's own internals (grid.hpp)
namespace {

/// x^(−1/3) for normal x > 0 to a few ulp, without libm's cbrt (which took a tenth of a 3D step): a first guess
/// from the bit pattern (the exponent divided by −3; within 3.5 % over 1e−8..1e8), then four Newton steps
/// t ← t (4 − x t³)/3, each squaring the relative error (3.5e−2 → 2.4e−3 → 1.2e−5 → 3e−10 → 2e−19). Other x go to cbrt.
inline double inverse_cbrt(double x) {
  if (!(x >= std::numeric_limits<double>::min() && x <= std::numeric_limits<double>::max())) return 1.0 / std::cbrt(x);
  // 4/3 · 2^52 · (1023 − 0.05): the bias term of log2 read off the bits, tuned for the smallest worst-case guess.
  constexpr std::uint64_t kMagic = 0x553eeeeeeeeef000;
  double t = std::bit_cast<double>(kMagic - std::bit_cast<std::uint64_t>(x) / 3);
  for (int i = 0; i < 4; ++i) t *= (4.0 - x * t * t * t) * (1.0 / 3.0);
  return t;
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

/// Ensures each sampled obstacle's samples cover the grid box (with a margin, so that a moving body does not sample
/// every step); samples the new box in parallel. The obstacles are fixed: samples stay valid for the model's life.
template <int D>
void refresh_obstacles(const MpmModel<D>& model, double dx, MpmWorkspace<D>& ws) {
  ws.obstacle_samples.resize(model.obstacles.size());
  for (std::size_t o = 0; o < model.obstacles.size(); ++o) {
    const Obstacle& ob = model.obstacles[o];
    if (ob.shape != Obstacle::Shape::kSampled) continue;
    auto& cache = ws.obstacle_samples[o];
    if (cache.source != ob.sampled.get() || cache.cell != dx) cache.valid = false;
    bool covers = cache.valid;
    for (int a = 0; covers && a < D; ++a) {
      covers = ws.lo[a] >= cache.lo[a] && ws.lo[a] + ws.n[a] <= cache.lo[a] + cache.n[a];
    }
    if (covers) continue;
    // The new box: the grid box with a margin, joined with the old one when they are near (a body moving on keeps
    // what it sampled); only the nodes the old box lacks are sampled.
    constexpr std::int64_t kMargin = 8;
    Index<D> lo = ws.lo.array() - kMargin;
    Index<D> hi = (ws.lo + ws.n).array() + kMargin;
    if (cache.valid) {
      const Index<D> old_hi = cache.lo + cache.n;
      const Index<D> joined_lo = lo.cwiseMin(cache.lo), joined_hi = hi.cwiseMax(old_hi);
      if ((joined_hi - joined_lo).prod() <= 4 * (hi - lo).prod()) {
        lo = joined_lo;
        hi = joined_hi;
      }
    }
    const auto old = std::move(cache);
    cache.lo = lo;
    cache.n = hi - lo;
    const std::int64_t total = cache.n.prod();
    cache.distance.resize(static_cast<std::size_t>(total));
    cache.normal.resize(static_cast<std::size_t>(total));
#pragma omp parallel for schedule(dynamic, 256) if (total > kParallelMin)
    for (std::int64_t k = 0; k < total; ++k) {
      const Index<D> i = box_node<D>(k, cache.lo, cache.n);
      const bool kept =
          old.valid && (i.array() >= old.lo.array()).all() && (i.array() < (old.lo + old.n).array()).all();
      if (kept) {
        const auto from = static_cast<std::size_t>(linear<D>(i, old.lo, old.n));
        cache.distance[static_cast<std::size_t>(k)] = old.distance[from];
        cache.normal[static_cast<std::size_t>(k)] = old.normal[from];
        continue;
      }
      Vec3 n3 = Vec3::UnitZ();
      cache.distance[static_cast<std::size_t>(k)] =
          ob.sampled->at(to3<D>(VecD<D>(i.template cast<double>() * dx)), &n3);
      cache.normal[static_cast<std::size_t>(k)] = from3<D>(n3);
    }
    cache.valid = true;
    cache.source = ob.sampled.get();
    cache.cell = dx;
  }
}

}  // namespace

void share_step_threads(int ways) { omp_set_num_threads(std::max(1, omp_get_max_threads() / std::max(1, ways))); }

double wave_speed(const Material& m) {
  return std::sqrt((m.bulk_modulus + 4.0 / 3.0 * m.shear_modulus) / m.density);
}

double Obstacle::distance(const Vec3& x, Vec3* normal) const {
  switch (shape) {
    case Shape::kSampled:
      return sampled->at(x, normal);
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

double plane_stress_stretch(const Material& m, const MatD<2>& f2) {
  // τ33(λ) = G J^(−2/3) (λ² − I1/3) + K J (J − 1) with J = j λ, I1 = i + λ²: r(λ) = g (2λ² − i)/3 + K J (J − 1),
  // g = G J^(−2/3), dr/dλ = g (4λ/3 − 2(2λ² − i)/(9λ)) + K j (2J − 1). Newton from J = 1 (λ = 1/j), where the
  // volumetric term vanishes; r rises steeply with λ (K ≫ G), so a handful of steps reach round-off.
  const double j = f2.determinant();
  if (!(j > 0.0)) return std::numeric_limits<double>::quiet_NaN();  // inverted: the step's checks name it
  const double i = f2.squaredNorm();
  double lambda = 1.0 / j;
  for (int k = 0; k < 40; ++k) {
    const double jj = j * lambda;
    const double g = m.shear_modulus * inverse_cbrt(jj * jj);
    const double q = 2.0 * lambda * lambda - i;
    const double r = g * q / 3.0 + m.bulk_modulus * jj * (jj - 1.0);
    const double dr = g * (4.0 * lambda / 3.0 - 2.0 * q / (9.0 * lambda)) + m.bulk_modulus * j * (2.0 * jj - 1.0);
    // r rises with λ wherever J > 1/2; below, or where Newton would cross zero, step halfway towards it instead.
    double next = dr > 0.0 ? lambda - r / dr : (r > 0.0 ? 0.5 * lambda : 2.0 * lambda);
    if (!(next > 0.0)) next = 0.5 * lambda;
    if (std::abs(next - lambda) <= 1e-14 * lambda) return next;
    lambda = next;
  }
  return std::numeric_limits<double>::quiet_NaN();  // no root: the step's checks stop the run and name the particle
}

namespace {

/// The full 3D invariants of a 2D or 3D F: J = det F and I1 = tr FᵀF with F33 = 1 (plane strain) or λ (plane stress);
/// λ² in `out_of_plane_sq` (1 in plane strain and 3D: unused).
template <int D>
struct Invariants {
  double j;
  double i1;
  double out_of_plane_sq;
};

template <int D>
Invariants<D> invariants(const Material& m, const MatD<D>& f, Plane plane) {
  if constexpr (D == 2) {
    const double l = plane == Plane::kStress ? plane_stress_stretch(m, f) : 1.0;
    return {f.determinant() * l, f.squaredNorm() + l * l, l * l};
  } else {
    (void)m;
    (void)plane;
    return {f.determinant(), f.squaredNorm(), 1.0};
  }
}

}  // namespace

template <int D>
MatD<D> elastic_stress(const Material& m, const MatD<D>& f, Plane plane) {
  // P = G J^(−2/3) (F − (I1/3) F⁻ᵀ) + K J (J − 1) F⁻ᵀ (eq 3.10); in plane stress G J^(−2/3) (F − λ² F⁻ᵀ) (τ33 = 0).
  const Invariants<D> v = invariants<D>(m, f, plane);
  const MatD<D> f_inv_t = f.inverse().transpose();
  const double t = inverse_cbrt(v.j * v.j);  // J^(−2/3)
  if (D == 2 && plane == Plane::kStress) return m.shear_modulus * t * (f - v.out_of_plane_sq * f_inv_t);
  return m.shear_modulus * t * (f - (v.i1 / 3.0) * f_inv_t) + m.bulk_modulus * v.j * (v.j - 1.0) * f_inv_t;
}

template <int D>
MatD<D> elastic_stress_differential(const Material& m, const MatD<D>& f, const MatD<D>& df, Plane plane) {
  if (D == 2 && plane == Plane::kStress) {
    // λ(F) makes the closed form long; the stress is smooth, so a central difference at a step of 1e-6 relative to F
    // is exact to ~1e-10 relative, far below what the Newton solve asks of its Hessian.
    const double h = 1e-6 * std::max(1.0, f.norm()) / std::max(df.norm(), std::numeric_limits<double>::min());
    return (elastic_stress<D>(m, f + h * df, plane) - elastic_stress<D>(m, f - h * df, plane)) / (2.0 * h);
  }
  // dP of eq 3.10, with dJ = J F⁻ᵀ:dF, d(J^(−2/3)) = −(2/3) J^(−2/3) F⁻ᵀ:dF, dI1 = 2 F:dF, dF⁻ᵀ = −F⁻ᵀ dFᵀ F⁻ᵀ
  // (in plane strain the 2×2 blocks of the 3D forms, F33 = 1 fixed).
  const Invariants<D> v = invariants<D>(m, f, plane);
  const MatD<D> f_inv_t = f.inverse().transpose();
  const MatD<D> d_f_inv_t = -f_inv_t * df.transpose() * f_inv_t;
  const double a = inverse_cbrt(v.j * v.j);  // J^(−2/3)
  const double tr_inv = (f_inv_t.array() * df.array()).sum();
  const double tr_f = (f.array() * df.array()).sum();
  const MatD<D> dev = f - (v.i1 / 3.0) * f_inv_t;
  return m.shear_modulus * a *
             (-(2.0 / 3.0) * tr_inv * dev + df - (2.0 / 3.0) * tr_f * f_inv_t - (v.i1 / 3.0) * d_f_inv_t) +
         m.bulk_modulus * (v.j * (2.0 * v.j - 1.0) * tr_inv * f_inv_t + v.j * (v.j - 1.0) * d_f_inv_t);
}

template <int D>
MatD<D> kirchhoff_stress(const Material& m, const MatD<D>& f, Plane plane) {
  // τ = G J^(−2/3) (F Fᵀ − (I1/3) I) + K J (J − 1) I (eq 3.10 times Fᵀ). In plane stress τ33 = 0 gives
  // K J (J − 1) = −G J^(−2/3) (λ² − I1/3), so the in-plane part is G J^(−2/3) (F Fᵀ − λ² I).
  const Invariants<D> v = invariants<D>(m, f, plane);
  const double g = m.shear_modulus * inverse_cbrt(v.j * v.j);  // G J^(−2/3)
  MatD<D> tau = g * (f * f.transpose());
  if (D == 2 && plane == Plane::kStress) {
    tau.diagonal().array() -= g * v.out_of_plane_sq;
  } else {
    tau.diagonal().array() += m.bulk_modulus * v.j * (v.j - 1.0) - g * v.i1 / 3.0;
  }
  return tau;
}

template <int D>
double strain_energy_density(const Material& m, const MatD<D>& f, Plane plane) {
  const Invariants<D> v = invariants<D>(m, f, plane);
  return 0.5 * m.shear_modulus * (v.i1 / std::cbrt(v.j * v.j) - 3.0) + 0.5 * m.bulk_modulus * (v.j - 1.0) * (v.j - 1.0);
}

template <int D>
double kinetic_energy(const MpmModel<D>& model, const MpmState<D>& state) {
  double e = 0.0;
  for (std::size_t p = 0; p < model.size(); ++p) e += 0.5 * model.mass[p] * state.v[p].squaredNorm();
  return e;
}

namespace {

// The lane helpers return 32-byte vectors by value, which GCC flags in baseline code (-Wpsabi: the ABI differs with
// AVX). They are inlined into the kernels and never cross a call, so no ABI is involved.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"

/// Four doubles as one SIMD value (a GCC/Clang vector extension): one AVX register in the x86-64-v3 kernels, two SSE2
/// registers in the baseline ones.
using Lanes = double __attribute__((vector_size(32)));

inline Lanes load(const NodeRecord& r) {
  Lanes l;
  std::memcpy(&l, r.value, sizeof l);
  return l;
}

inline void store(NodeRecord& r, const Lanes& l) {
  std::memcpy(r.value, &l, sizeof l);
}

/// The first D lanes from a D-vector; the others zero.
template <int D>
inline Lanes lanes_of(const VecD<D>& v) {
  Lanes l = {0.0, 0.0, 0.0, 0.0};
  for (int a = 0; a < D; ++a) l[a] = v[a];
  return l;
}

template <int D>
inline VecD<D> vec_of(const Lanes& l) {
  VecD<D> v;
  for (int a = 0; a < D; ++a) v[a] = l[a];
  return v;
}

/// P2G of particle p: node mass, momentum with the MLS affine part, and (non-uniform fields) the node moment.
/// The stress enters as P Fᵀ, the Kirchhoff stress, so F is never inverted.
template <int D>
inline void scatter_particle(const StepContext<D>& c, std::size_t p) {
  const MpmModel<D>& model = c.model;
  const MpmState<D>& state = c.state;
  MpmWorkspace<D>& ws = c.ws;
  const double dx = c.dx;
  const Stencil<D> st(state.x[p], c.inv_dx);
  const MatD<D>& f = state.f[p];
  MatD<D> tau = c.stress ? kirchhoff_stress<D>(model.materials[model.material[p]], f, model.plane) : MatD<D>::Zero();
  const VecD<D>& br = model.remanence[p];
  const bool magnetic = (c.uniform || c.general) && br.squaredNorm() > 0.0;
  VecD<D> f_br = VecD<D>::Zero();
  if (magnetic) {
    const VecD<D> b = field_at<D>(c, st);
    f_br = f * br;
    if (c.stress) tau += magnetics::hard_magnetic_kirchhoff_stress<D>(b, f_br);  // eq 3.13 times Fᵀ: −B (F B̃r)ᵀ/μ0
  }
  const double m = model.mass[p];
  const MatD<D> affine = (-c.dt * model.volume[p] * c.d_inv) * tau + m * state.c[p];
  // The record added at a node: w · (m v + A (x_i − x_p), m), A (x_i − x_p) = Σ_a A.col(a) d_a.
  Lanes base_rec = lanes_of<D>(m * state.v[p]);
  base_rec[D] = m;
  std::array<std::array<Lanes, 3>, D> along;
  for (int a = 0; a < D; ++a) {
    const Lanes col = lanes_of<D>(affine.col(a));
    for (int o = 0; o < 3; ++o) along[a][o] = col * ((o - st.fx[a]) * dx);
  }
  const bool moments = c.general && magnetic;
  const VecD<D> moment =
      moments ? magnetics::hard_magnetic_moment<D>(f_br, model.volume[p]) : VecD<D>::Zero();  // eq 3.15
  const std::int64_t first = linear<D>(st.base, ws.lo, ws.n);
  if constexpr (D == 3) {
    // Node (i, j, k) gets w_i w_j w_k (r_ij + a_k): r_ij = base + a_i + a_j is formed once per (i, j).
    std::array<Lanes, 3> wa2;
    for (int k = 0; k < 3; ++k) wa2[k] = st.w[2][k] * along[2][k];
    for_rows(st, first, c.stride, [&](int i, int j, std::size_t row, double wij) {
      const Lanes r = base_rec + along[0][i] + along[1][j];
      NodeRecord* node = &ws.node[row];
      for (int k = 0; k < 3; ++k) store(node[k], load(node[k]) + wij * (st.w[2][k] * r + wa2[k]));
      if (moments) {
        VecD<D>* mo = &ws.node_moment[row];
        for (int k = 0; k < 3; ++k) mo[k] += (wij * st.w[2][k]) * moment;
      }
    });
  } else {
    for_nodes<D>(st, first, c.stride, [&](std::int64_t k, double w, int i, int j, int) {
      NodeRecord& node = ws.node[static_cast<std::size_t>(k)];
      store(node, load(node) + w * (base_rec + along[0][i] + along[1][j]));
      if (moments) ws.node_moment[static_cast<std::size_t>(k)] += w * moment;
    });
  }
}

/// G2P of particle p: velocity, affine field C, then F ← (I + Δt C) F and x ← x + Δt v. True when the particle
/// failed a check (non-finite, det F outside (0, kMaxJ), a cell per step, outside the domain).
template <int D>
inline bool gather_particle(const StepContext<D>& c, std::size_t p) {
  const MpmModel<D>& model = c.model;
  MpmState<D>& state = c.state;
  const MpmWorkspace<D>& ws = c.ws;
  const double dx = c.dx;
  const double dt = c.dt;
  const Stencil<D> st(state.x[p], c.inv_dx);
  std::array<std::array<double, 3>, D> d;  // x_i − x_p per axis
  for (int a = 0; a < D; ++a)
    for (int o = 0; o < 3; ++o) d[a][o] = (o - st.fx[a]) * dx;
  // v = Σ w v_i and the columns of Σ w v_i (x_i − x_p)ᵀ, in lanes (the last lane carries mass, unused).
  Lanes v = {0.0, 0.0, 0.0, 0.0};
  std::array<Lanes, D> b;
  b.fill(v);
  const std::int64_t first = linear<D>(st.base, ws.lo, ws.n);
  if constexpr (D == 3) {
    // Sum along k first: s = Σ_k w_k v, t = Σ_k w_k d_k v; then the (i, j) weights and offsets apply once.
    std::array<double, 3> wd2;
    for (int k = 0; k < 3; ++k) wd2[k] = st.w[2][k] * d[2][k];
    for_rows(st, first, c.stride, [&](int i, int j, std::size_t row, double wij) {
      const NodeRecord* node = &ws.node[row];
      const Lanes n0 = load(node[0]), n1 = load(node[1]), n2 = load(node[2]);
      const Lanes sum = st.w[2][0] * n0 + st.w[2][1] * n1 + st.w[2][2] * n2;
      const Lanes moment_k = wd2[0] * n0 + wd2[1] * n1 + wd2[2] * n2;
      v += wij * sum;
      b[0] += (wij * d[0][i]) * sum;
      b[1] += (wij * d[1][j]) * sum;
      b[2] += wij * moment_k;
    });
  } else {
    for_nodes<D>(st, first, c.stride, [&](std::int64_t k, double w, int i, int j, int) {
      const Lanes wv = w * load(ws.node[static_cast<std::size_t>(k)]);
      v += wv;
      b[0] += d[0][i] * wv;
      b[1] += d[1][j] * wv;
    });
  }
  const VecD<D> vp = vec_of<D>(v);
  MatD<D> cp;
  for (int a = 0; a < D; ++a)
    for (int r = 0; r < D; ++r) cp(r, a) = c.d_inv * b[a][r];
  state.v[p] = vp;
  state.c[p] = cp;
  state.f[p] = (MatD<D>::Identity() + dt * cp) * state.f[p];
  state.x[p] += dt * vp;
  const double j = state.f[p].determinant();
  return !(j > 0.0 && j < kMaxJ) || !state.x[p].allFinite() || !vp.allFinite() ||
         vp.norm() * dt > kMaxCellsPerStep * dx || (state.x[p].array() < model.domain_min.array()).any() ||
         (state.x[p].array() > model.domain_max.array()).any();
}

// The particle loops are compiled for baseline x86-64 and for x86-64-v3 (magvine/core/multiversion.hpp): with AVX2 a
// node's 4-double record is one register.
MAGVINE_HOT_KERNEL void scatter_2d(const StepContext<2>& c, const std::uint32_t* p, const std::uint32_t* end) {
  for (; p != end; ++p) scatter_particle<2>(c, *p);
}

MAGVINE_HOT_KERNEL void scatter_3d(const StepContext<3>& c, const std::uint32_t* p, const std::uint32_t* end) {
  for (; p != end; ++p) scatter_particle<3>(c, *p);
}

/// G2P over the listed particles; returns the smallest index among those that failed a check (kNoFailure if none).
/// Every particle is updated either way.
MAGVINE_HOT_KERNEL std::int64_t gather_2d(const StepContext<2>& c, const std::uint32_t* p, const std::uint32_t* end) {
  std::int64_t bad = kNoFailure;
  for (; p != end; ++p) {
    if (gather_particle<2>(c, *p)) bad = std::min<std::int64_t>(bad, *p);
  }
  return bad;
}

MAGVINE_HOT_KERNEL std::int64_t gather_3d(const StepContext<3>& c, const std::uint32_t* p, const std::uint32_t* end) {
  std::int64_t bad = kNoFailure;
  for (; p != end; ++p) {
    if (gather_particle<3>(c, *p)) bad = std::min<std::int64_t>(bad, *p);
  }
  return bad;
}

template <int D>
void scatter(const StepContext<D>& c, const std::uint32_t* p, const std::uint32_t* end) {
  if constexpr (D == 2)
    scatter_2d(c, p, end);
  else
    scatter_3d(c, p, end);
}

template <int D>
std::int64_t gather(const StepContext<D>& c, const std::uint32_t* p, const std::uint32_t* end) {
  if constexpr (D == 2)
    return gather_2d(c, p, end);
  else
    return gather_3d(c, p, end);
}

#pragma GCC diagnostic pop

/// Grid update of the nodes with first index i0 along axis 0 (a plane of the box): velocity from momentum, the
/// gradient force (eq 3.16: f_i = ∇B_iᵀ m_i), gravity, damping, then clamps, domain walls and obstacles.
template <int D>
void update_plane(const StepContext<D>& c, std::int64_t i0, double damp) {
  MpmWorkspace<D>& ws = c.ws;
  const std::int64_t per_plane = c.stride[0];
  for (std::int64_t r = 0; r < per_plane; ++r) {
    const auto k = static_cast<std::size_t>(i0 * per_plane + r);
    double* rec = ws.node[k].value;
    const double m = rec[D];
    if (m <= 0.0) continue;
    const Index<D> i = box_node<D>(i0 * per_plane + r, ws.lo, ws.n);
    const VecD<D> xi = i.template cast<double>() * c.dx;
    if (const VecD<D>* held = clamp_velocity<D>(c, xi)) {
      std::copy(held->data(), held->data() + D, rec);
      continue;
    }
    VecD<D> v = node_velocity<D>(c, k, i) * damp;
    apply_walls_and_obstacles<D>(c, i, xi, v);
    std::copy(v.data(), v.data() + D, rec);  // now the velocity
  }
}

}  // namespace

namespace detail {

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
    const Index<D> i = box_node<D>(k, ws.field_lo, ws.field_n);
    const VecD<D> x = i.template cast<double>() * dx;
    const magnetics::FieldSample s = field.sample(to3<D>(x));
    ws.field_b[static_cast<std::size_t>(k)] = from3<D>(s.b);
    ws.field_g[static_cast<std::size_t>(k)] = s.g.template topLeftCorner<D, D>();
  }
  ws.field_version = field.version;
  ws.field_valid = true;
}


template <int D>
VecD<D> node_velocity(const StepContext<D>& c, std::size_t k, const Index<D>& i) {
  const double* rec = c.ws.node[k].value;
  const double m = rec[D];
  VecD<D> v = Eigen::Map<const VecD<D>>(rec) / m;
  if (c.general) {
    const auto fk = static_cast<std::size_t>(linear<D>(i, c.ws.field_lo, c.ws.field_n));
    v += c.dt / m * magnetics::gradient_force<D>(c.ws.field_g[fk], c.ws.node_moment[k]);  // eq 3.16
  }
  return v + c.dt * c.model.gravity;
}

template <int D>
const VecD<D>* clamp_velocity(const StepContext<D>& c, const VecD<D>& xi) {
  for (const auto& box : c.ws.clamps) {
    if ((xi.array() >= box.min.array()).all() && (xi.array() <= box.max.array()).all()) return &box.velocity;
  }
  return nullptr;
}

template <int D>
void apply_walls_and_obstacles(const StepContext<D>& c, const Index<D>& i, const VecD<D>& xi, VecD<D>& v) {
  const MpmModel<D>& model = c.model;
  const double dx = c.dx;
  for (int a = 0; a < D; ++a) {  // domain walls: the nodes within a cell of a wall
    if (xi[a] <= model.domain_min[a] + dx) apply_boundary<D>(v, VecD<D>::Unit(a), model.walls, model.wall_friction);
    if (xi[a] >= model.domain_max[a] - dx) apply_boundary<D>(v, -VecD<D>::Unit(a), model.walls, model.wall_friction);
  }
  for (std::size_t o = 0; o < model.obstacles.size(); ++o) {
    const Obstacle& ob = model.obstacles[o];
    if (ob.shape == Obstacle::Shape::kSampled) {
      const auto& cache = c.ws.obstacle_samples[o];
      const auto s = static_cast<std::size_t>(linear<D>(i, cache.lo, cache.n));
      if (cache.distance[s] <= 0.0) apply_boundary<D>(v, cache.normal[s], ob.boundary, ob.friction);
      continue;
    }
    Vec3 n3;
    if (ob.distance(to3<D>(xi), &n3) <= 0.0) apply_boundary<D>(v, from3<D>(n3), ob.boundary, ob.friction);
  }
}

template <int D>
StepStatus prepare_grid(StepContext<D>& c, const AppliedField& field) {
  const MpmModel<D>& model = c.model;
  const MpmState<D>& state = c.state;
  MpmWorkspace<D>& ws = c.ws;
  const std::size_t np = model.size();
  c.dx = model.cell;
  c.inv_dx = 1.0 / model.cell;
  c.d_inv = 4.0 * c.inv_dx * c.inv_dx;
  c.general = field.kind == AppliedField::Kind::kGeneral;
  c.uniform = field.kind == AppliedField::Kind::kUniform;
  c.b_uniform = from3<D>(field.uniform);
  ws.clamps.assign(model.clamps.begin(), model.clamps.end());  // reuses the workspace's storage
  for (auto& box : ws.clamps) {  // a moving clamp's box at this step's start
    box.min += state.time * box.velocity;
    box.max += state.time * box.velocity;
  }
  const double inv_dx = c.inv_dx;

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
  for (std::int64_t k = 0; k < n_nodes; ++k) ws.node[static_cast<std::size_t>(k)] = NodeRecord{};
  c.stride = strides<D>(ws.n);
  refresh_obstacles(model, c.dx, ws);
  if (c.general) {
    ws.node_moment.assign(nodes, VecD<D>::Zero());
    refresh_field(field, c.dx, ws);
    c.field_stride = strides<D>(ws.field_n);
  }

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
  return {};
}

template <int D>
void scatter_all(const StepContext<D>& c) {
  for_slabs_coloured<D>(c.ws, c.model.size(),
                        [&](const std::uint32_t* p, const std::uint32_t* end) { scatter<D>(c, p, end); });
}

template <int D>
std::int64_t gather_all(const StepContext<D>& c) {
  const std::uint32_t* order = c.ws.slab_order.data();
  const auto slabs = static_cast<std::int64_t>(c.ws.slab_count.size() - 1);
  std::int64_t bad = kNoFailure;
#pragma omp parallel for schedule(dynamic, 1) reduction(min : bad) if (c.model.size() > static_cast<std::size_t>(kParallelMin))
  for (std::int64_t s = 0; s < slabs; ++s) {
    const auto u = static_cast<std::size_t>(s);
    bad = std::min(bad, gather<D>(c, order + c.ws.slab_count[u], order + c.ws.slab_count[u + 1]));
  }
  return bad;
}

template <int D>
StepStatus particle_failure(const MpmState<D>& state, std::int64_t bad, double dt, double dx) {
  if (bad == kNoFailure) return {};
  const auto p = static_cast<std::size_t>(bad);
  const double j = state.f[p].determinant();
  std::string what;
  if (!state.x[p].allFinite() || !state.v[p].allFinite())
    what = "non-finite position or velocity";
  else if (!(j > 0.0))
    what = "inverted (det F = " + std::to_string(j) + ")";
  else if (!(j < kMaxJ))
    what = "exploded (det F = " + std::to_string(j) + ")";
  else if (state.v[p].norm() * dt > kMaxCellsPerStep * dx) {
    what = "moves more than a cell per step (|v| = " + std::to_string(state.v[p].norm()) + " m/s)";
  } else {
    what = "left the domain";
  }
  return {false, "particle " + std::to_string(p) + " " + what + " at t = " + std::to_string(state.time) + " s"};
}

template <int D>
StepStatus failure_of(const StepContext<D>& c, std::int64_t bad) {
  return particle_failure<D>(c.state, bad, c.dt, c.dx);
}

template StepStatus prepare_grid<2>(StepContext<2>&, const AppliedField&);
template StepStatus prepare_grid<3>(StepContext<3>&, const AppliedField&);
template void scatter_all<2>(const StepContext<2>&);
template void scatter_all<3>(const StepContext<3>&);
template std::int64_t gather_all<2>(const StepContext<2>&);
template std::int64_t gather_all<3>(const StepContext<3>&);
template VecD<2> node_velocity<2>(const StepContext<2>&, std::size_t, const Index<2>&);
template VecD<3> node_velocity<3>(const StepContext<3>&, std::size_t, const Index<3>&);
template const VecD<2>* clamp_velocity<2>(const StepContext<2>&, const VecD<2>&);
template const VecD<3>* clamp_velocity<3>(const StepContext<3>&, const VecD<3>&);
template void apply_walls_and_obstacles<2>(const StepContext<2>&, const Index<2>&, const VecD<2>&, VecD<2>&);
template void apply_walls_and_obstacles<3>(const StepContext<3>&, const Index<3>&, const VecD<3>&, VecD<3>&);
template void refresh_field<2>(const AppliedField&, double, MpmWorkspace<2>&);
template void refresh_field<3>(const AppliedField&, double, MpmWorkspace<3>&);
template StepStatus particle_failure<2>(const MpmState<2>&, std::int64_t, double, double);
template StepStatus particle_failure<3>(const MpmState<3>&, std::int64_t, double, double);
template StepStatus failure_of<2>(const StepContext<2>&, std::int64_t);
template StepStatus failure_of<3>(const StepContext<3>&, std::int64_t);

}  // namespace detail

template <int D>
StepStatus step(const MpmModel<D>& model, const AppliedField& field, MpmState<D>& state, MpmWorkspace<D>& ws,
                double dt) {
  const std::size_t np = model.size();
  StepContext<D> c{model, state, ws};
  c.dt = dt;
  if (StepStatus ready = prepare_grid<D>(c, field); !ready.ok) return ready;
  const auto n_points = static_cast<std::int64_t>(np);

  // P2G, grid and G2P in one parallel region. Each thread owns a run of whole slabs holding about an equal share of
  // the particles, and treats the same particles in P2G and G2P, so their state stays in its core's cache. P2G does
  // the even slabs, then (after a barrier) the odd ones: slabs of one colour never share a node, and every node's
  // sum runs in the same order for any thread count.
  const std::size_t slabs = ws.slab_count.size() - 1;
  const double damp = 1.0 / (1.0 + model.damping * dt);
  const std::uint32_t* order = ws.slab_order.data();
  std::int64_t bad = kNoFailure;
#pragma omp parallel if (n_points > kParallelMin) reduction(min : bad)
  {
    const auto threads = static_cast<std::size_t>(omp_get_num_threads());
    const auto t = static_cast<std::size_t>(omp_get_thread_num());
    const auto owned = [&](std::size_t u) {  // the first slab of thread u's run
      const std::uint32_t share = static_cast<std::uint32_t>(np * u / threads);
      return static_cast<std::size_t>(std::lower_bound(ws.slab_count.begin(), ws.slab_count.end() - 1, share) -
                                      ws.slab_count.begin());
    };
    const std::size_t s_begin = t == 0 ? 0 : owned(t), s_end = t + 1 == threads ? slabs : owned(t + 1);
    for (std::size_t colour = 0; colour < 2; ++colour) {
      for (std::size_t s = s_begin; s < s_end; ++s) {
        if (s % 2 == colour) scatter<D>(c, order + ws.slab_count[s], order + ws.slab_count[s + 1]);
      }
#pragma omp barrier
    }
#pragma omp for schedule(static)
    for (std::int64_t i0 = 0; i0 < ws.n[0]; ++i0) update_plane<D>(c, i0, damp);
    for (std::size_t s = s_begin; s < s_end; ++s) {
      bad = std::min(bad, gather<D>(c, order + ws.slab_count[s], order + ws.slab_count[s + 1]));
    }
  }
  state.time += dt;
  return failure_of<D>(c, bad);
}

template struct MpmModel<2>;
template struct MpmModel<3>;
template MpmState<2> rest_state<2>(const std::vector<VecD<2>>&);
template MpmState<3> rest_state<3>(const std::vector<VecD<3>>&);
template MatD<2> elastic_stress<2>(const Material&, const MatD<2>&, Plane);
template MatD<3> elastic_stress<3>(const Material&, const MatD<3>&, Plane);
template MatD<2> elastic_stress_differential<2>(const Material&, const MatD<2>&, const MatD<2>&, Plane);
template MatD<3> elastic_stress_differential<3>(const Material&, const MatD<3>&, const MatD<3>&, Plane);
template MatD<2> kirchhoff_stress<2>(const Material&, const MatD<2>&, Plane);
template MatD<3> kirchhoff_stress<3>(const Material&, const MatD<3>&, Plane);
template double strain_energy_density<2>(const Material&, const MatD<2>&, Plane);
template double strain_energy_density<3>(const Material&, const MatD<3>&, Plane);
template double kinetic_energy<2>(const MpmModel<2>&, const MpmState<2>&);
template double kinetic_energy<3>(const MpmModel<3>&, const MpmState<3>&);
template StepStatus step<2>(const MpmModel<2>&, const AppliedField&, MpmState<2>&, MpmWorkspace<2>&, double);
template StepStatus step<3>(const MpmModel<3>&, const AppliedField&, MpmState<3>&, MpmWorkspace<3>&, double);

}  // namespace magvine::mpm
