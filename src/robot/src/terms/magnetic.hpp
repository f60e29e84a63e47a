#pragma once
// The magnetic energy of each edge (rod.hpp, PHYSICS.md §2), energy, gradient and Hessian together, with the field
// sampled once per edge midpoint c: a hard moment m_j = R_j m̂_j h (m̂_j the moment per length, body frame) has
// U = −m·B(c); a soft-magnetic fill U = V e(R_jᵀB(c)) (magnetics::InducedMagnetisation, V = A_fill·h). Their
// gradient is the wrench of the effective moment m = m_hard + V R M (magnetics::magnetic_wrench): −τ on the frame's
// rotation, −½F on each end node.

#include "../rod_system.hpp"
#include "magvine/magnetics/magnetisation.hpp"

namespace magvine::robot::detail {

struct Magnetic {
  static bool active(const TermContext& c) {
    const RodModel& m = c.model;
    return c.field && (!m.moment_per_length.empty() || fill_volume(c) > 0.0);
  }
  /// The hard moment λ h_j R_j m̂_j of edge j (world) [A·m²].
  static Vec3 hard_moment(const TermContext& c, std::size_t j) {
    return c.load * c.h(static_cast<int>(j)) * (c.state.frames[j] * c.model.moment_per_length[j]);
  }
  /// V = λ A_fill h of the fill of an edge of length h [m³].
  static double fill_volume(const TermContext& c) {
    return c.model.induced ? c.load * c.model.induced->volume_per_length * c.edge_length : 0.0;
  }
  static double fill_volume(const TermContext& c, int j) {
    return c.model.induced ? c.load * c.model.induced->volume_per_length * c.h(j) : 0.0;
  }

  /// The effective moment m = −dU/dB (world) of an edge of hard moment `hard`, fill volume `volume` and frame r in
  /// the field sample f; adds the edge's energy U to `energy`.
  static Vec3 effective_moment(const TermContext& c, const Vec3& hard, double volume, const Mat3& r,
                               const magnetics::FieldSample& f, double& energy) {
    energy -= hard.dot(f.b);
    Vec3 moment = hard;
    if (volume > 0.0) {
      Vec3 de_db;
      energy += volume * c.model.induced->law.energy_density(r.transpose() * f.b, de_db);
      moment -= volume * (r * de_db);
    }
    return moment;
  }

  static void add_energy(const TermContext& c, double& energy, System* sys) {
    if (!active(c)) return;
    const RodModel& m = c.model;
    const bool hard = !m.moment_per_length.empty();
    for (int j = 0; j < c.edges(); ++j) {
      const auto ju = static_cast<std::size_t>(j);
      const double volume = fill_volume(c, j);
      const Mat3& r = c.state.frames[ju];
      const Vec3 mj = hard ? hard_moment(c, ju) : Vec3::Zero();
      if (mj.isZero() && volume == 0.0) continue;
      const magnetics::FieldSample f =
          c.samples != nullptr ? c.samples->at(c.field, c.state, ju) : c.field(edge_midpoint(c.state, ju));
      const Vec3 moment = effective_moment(c, mj, volume, r, f, energy);
      if (sys == nullptr) continue;
      const magnetics::Wrench wrench = magnetics::magnetic_wrench(moment, f);
      const Vec3 half_gradient = -0.5 * wrench.force;
      sys->add_gradient(position_slot(j), half_gradient);
      sys->add_gradient(position_slot(j + 1), half_gradient);
      sys->add_gradient(rotation_slot(j), -wrench.torque);
    }
  }

  /// The derivative of the gradient (the unknowns of rod_gradient) with respect to each edge's hard moment per length
  /// m̂_j (body frame), into the 6N × 3N matrix `out` (columns 3j..3j+2): the wrench is linear in the moment, so column
  /// k of edge j is the gradient of the moment h_j R_j e_k, −½F on each end node and −τ on the frame (design
  /// sensitivities, rod.hpp). A fill's induced moment does not depend on m̂.
  static void add_moment_sensitivity(const TermContext& c, MatX& out) {
    if (!c.field) return;
    for (int j = 0; j < c.edges(); ++j) {
      const auto ju = static_cast<std::size_t>(j);
      const magnetics::FieldSample f = c.field(edge_midpoint(c.state, ju));
      for (int k = 0; k < 3; ++k) {
        const Vec3 unit = c.load * c.h(j) * c.state.frames[ju].col(k);  // h R e_k
        const magnetics::Wrench w = magnetics::magnetic_wrench(unit, f);
        add_column(out, position_slot(j), 3 * j + k, -0.5 * w.force);
        add_column(out, position_slot(j + 1), 3 * j + k, -0.5 * w.force);
        add_column(out, rotation_slot(j), 3 * j + k, -w.torque);
      }
    }
  }

  /// The derivative of the gradient with respect to a uniform field B added to the field, into the 6N × 3 matrix
  /// `out`: −τ = −m × B is linear in B (the wrench of the effective moment in the sample {e_k, G = 0}); a uniform field
  /// adds no force. Hard moments only (a fill's induced moment depends on B itself: InputError from the caller).
  static void add_uniform_field_sensitivity(const TermContext& c, MatX& out) {
    if (c.model.moment_per_length.empty()) return;
    for (int j = 0; j < c.edges(); ++j) {
      const auto ju = static_cast<std::size_t>(j);
      const Vec3 m = hard_moment(c, ju);
      for (int k = 0; k < 3; ++k) {
        const magnetics::Wrench w = magnetics::magnetic_wrench(m, magnetics::FieldSample{Vec3::Unit(k), Mat3::Zero()});
        add_column(out, rotation_slot(j), k, -w.torque);
      }
    }
  }

  static void add_column(MatX& out, const Slot& s, int column, const Vec3& v) {
    if (s.block >= 0) out.block<3, 1>(6 * s.block + s.offset, column) += v;
  }

  /// The Hessian blocks of every edge (edge_blocks).
  static void add_hessian(const TermContext& c, System& sys) {
    if (!active(c)) return;
    const auto n = static_cast<std::size_t>(c.edges());
    FieldSamples local;
    FieldSamples& samples = c.samples != nullptr ? *c.samples : local;
    if (c.samples == nullptr) local.reset(n);
    const bool uniform = uniform_at_edges(c, samples);
    for (std::size_t ju = 0; ju < n; ++ju) {
      EdgeBlocks b;
      if (!edge_blocks(c, ju, samples.value[ju], uniform, b)) continue;
      add_edge_element(sys, static_cast<int>(ju), EdgeVector::midpoint, b.cc, b.phic.transpose(), b.phiphi);
    }
  }

  /// The derivative of the gradient with respect to a translation p of every field source (the field becomes
  /// B(x − p)), into the 6N × 3 matrix `out`: the edge's energy depends on c − p, so the rotation rows take −H_φc and
  /// each end node −½ H_cc (the Hessian's own blocks, edge_blocks; design sensitivities, rod.hpp).
  static void add_field_translation_sensitivity(const TermContext& c, MatX& out) {
    if (!active(c)) return;
    const auto n = static_cast<std::size_t>(c.edges());
    FieldSamples samples;
    samples.reset(n);
    const bool uniform = uniform_at_edges(c, samples);
    for (std::size_t ju = 0; ju < n; ++ju) {
      EdgeBlocks b;
      if (!edge_blocks(c, ju, samples.value[ju], uniform, b)) continue;
      const int j = static_cast<int>(ju);
      for (int k = 0; k < 3; ++k) {
        add_column(out, rotation_slot(j), k, -b.phic.col(k));
        add_column(out, position_slot(j), k, -0.5 * b.cc.col(k));
        add_column(out, position_slot(j + 1), k, -0.5 * b.cc.col(k));
      }
    }
  }

 private:
  /// The second derivatives of one edge's energy in its frame rotation φ and its midpoint c.
  struct EdgeBlocks {
    Mat3 cc = Mat3::Zero();
    Mat3 phic = Mat3::Zero();  ///< rows φ, columns c
    Mat3 phiphi = Mat3::Zero();
  };

  /// Samples the field at every edge midpoint; true when it has no gradient at any (uniform: no curvature terms).
  static bool uniform_at_edges(const TermContext& c, FieldSamples& samples) {
    bool uniform = true;
    for (std::size_t j = 0; j < static_cast<std::size_t>(c.edges()); ++j) {
      const bool flat =
          samples.at(c.field, c.state, j).g.isZero(0.0);  // sampled at every edge, even past the first gradient
      uniform = uniform && flat;
    }
    return uniform;
  }

  /// With w = dU/dB (world) = −m + R p (p = V de/db, P = V d²e/db², body frame), c the midpoint and G = ∂B/∂c:
  ///   δφδφ: sym(w Bᵀ) − w·B I + [B]ᵀRPRᵀ[B];  δφδc: ([w] − [B]RPRᵀ)G;  δcδc: GᵀRPRᵀG + Σ_i w_i ∇²B_i,
  /// the last from the field's closed-form curvature where it has one (dipoles), else from forward differences of G
  /// (skipped when the field has no gradient at any midpoint: uniform). False for an edge without moment or fill.
  static bool edge_blocks(const TermContext& c, std::size_t ju, const magnetics::FieldSample& f, bool uniform,
                          EdgeBlocks& out) {
    const RodModel& m = c.model;
    const bool hard = !m.moment_per_length.empty();
    const int j = static_cast<int>(ju);
    const double volume = fill_volume(c, j);
    const Mat3& r = c.state.frames[ju];
    Vec3 w = hard ? Vec3(-hard_moment(c, ju)) : Vec3::Zero();  // dU/dB of the hard moment
    Mat3 p_world = Mat3::Zero();                               // R P Rᵀ
    if (volume > 0.0) {
      Vec3 de_db;
      Mat3 d2e;
      m.induced->law.energy_density(r.transpose() * f.b, de_db, &d2e);
      w += volume * (r * de_db);
      p_world = volume * r * d2e * r.transpose();
    }
    if (w.isZero(0.0) && volume == 0.0) return false;
    out.phiphi = cross_squared(w, f.b);
    out.phic = skew(w) * f.g;
    out.cc = Mat3::Zero();
    if (volume > 0.0) {  // the induced moment's terms (a hard moment has P = 0)
      const Mat3 bx = skew(f.b);
      out.phiphi += bx.transpose() * p_world * bx;
      out.phic -= bx * p_world * f.g;
      out.cc = f.g.transpose() * p_world * f.g;
    }
    if (!uniform) {
      // Without a closed-form curvature, forward differences of G: truncation ~step/d relative (d the distance to
      // the magnet, ≫ L/1e6 here) and round-off ~ε·d/step, both far below what Newton's convergence notices; half
      // the field samples of central ones. (For a dipole the closed form took a tenth off a cold 100-node solve.)
      const double step = 1e-6 * m.length;
      const Vec3 mid = edge_midpoint(c.state, ju);
      if (c.field.curvature()) {
        out.cc += c.field.curvature()(mid, w);
      } else {
        for (int k = 0; k < 3; ++k) {
          out.cc.col(k) += (c.field(mid + step * Vec3::Unit(k)).g - f.g).transpose() * w / step;
        }
        out.cc = 0.5 * (out.cc + out.cc.transpose()).eval();
      }
    }
    return true;
  }
};

}  // namespace magvine::robot::detail
