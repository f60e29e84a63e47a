#include "magvine/studies/field_study.hpp"

#include <array>
#include <chrono>
#include <cstdio>
#include <functional>
#include <iostream>
#include <string>
#include <vector>

#include "magvine/core/atomic_file.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/dipole.hpp"
#include "magvine/magnetics/reference.hpp"
#include "magvine/core/text.hpp"

namespace magvine::studies {

namespace {

using magnetics::CylinderMagnet;
using magnetics::QuadratureResolution;

// Reference: 4× the finest studied resolution in φ and z; the studied sequence has converged to ~3e-12 by
// 256 × 128, so the reference is at least that good at these distances.
constexpr QuadratureResolution kReference{1024, 32, 16};

// Mean wall time per call of `eval` over all points, repeated until at least 50 ms have passed.
double ns_per_eval(const std::vector<Vec3>& pts, const std::function<Vec3(const Vec3&)>& eval) {
  using Clock = std::chrono::steady_clock;
  double sink = 0.0;
  std::size_t calls = 0;
  const auto start = Clock::now();
  auto elapsed = Clock::duration::zero();
  while (elapsed < std::chrono::milliseconds(50)) {
    for (const auto& p : pts) sink += eval(p).x();
    calls += pts.size();
    elapsed = Clock::now() - start;
  }
  volatile double keep = sink;
  (void)keep;
  return std::chrono::duration<double, std::nano>(elapsed).count() / static_cast<double>(calls);
}

double max_rel_error(const std::vector<Vec3>& pts, const std::vector<Vec3>& ref,
                     const std::function<Vec3(const Vec3&)>& eval) {
  double worst = 0.0;
  for (std::size_t i = 0; i < pts.size(); ++i) worst = std::max(worst, (eval(pts[i]) - ref[i]).norm() / ref[i].norm());
  return worst;
}

}  // namespace

void run_field_model_study(const CylinderMagnet& magnet, const FieldStudySpec& spec, const std::filesystem::path& dir) {
  constexpr int kAngles = 19;
  std::vector<Vec3> pts;
  std::vector<std::size_t> distance_of;
  for (std::size_t k = 0; k < spec.distances.size(); ++k) {
    for (int i = 0; i < kAngles; ++i) {
      const double th = 0.5 * kPi * i / (kAngles - 1);
      for (double phi : {0.0, 0.5 * kPi}) {
        pts.emplace_back(spec.distances[k] * std::sin(th) * std::cos(phi), spec.distances[k] * std::sin(th) * std::sin(phi),
                         spec.distances[k] * std::cos(th));
        distance_of.push_back(k);
      }
    }
  }
  std::cerr << "study field-models: reference quadrature at " << pts.size() << " points ...\n";
  std::vector<Vec3> ref(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) ref[i] = magnetics::cylinder_field_quadrature(magnet, pts[i], kReference);

  const Vec3 m = magnet.dipole_moment();
  const auto exact = [&](const Vec3& p) { return magnet.field(p); };
  const auto dipole = [&](const Vec3& p) { return magnetics::dipole_field(m, p); };

  std::string models = "model,resolution,max_rel_err_B,ns_per_eval\n";
  auto add_row = [&](const std::string& name, const std::string& res, double err, double ns) {
    models += name + "," + res + ",";
    append_csv_row(models, std::array{err, ns});
    std::fprintf(stderr, "  %-10s %-12s max error %.3e  %.1f ns/eval\n", name.c_str(), res.c_str(), err, ns);
  };
  add_row("exact", "closed-form", max_rel_error(pts, ref, exact), ns_per_eval(pts, exact));
  add_row("dipole", "-", max_rel_error(pts, ref, dipole), ns_per_eval(pts, dipole));
  for (const QuadratureResolution res : {QuadratureResolution{8, 1, 2}, QuadratureResolution{16, 2, 4},
                                         QuadratureResolution{32, 4, 4}, QuadratureResolution{64, 4, 8},
                                         QuadratureResolution{128, 8, 8}, QuadratureResolution{256, 16, 8}}) {
    const auto quad = [&](const Vec3& p) { return magnetics::cylinder_field_quadrature(magnet, p, res); };
    const std::string label = std::to_string(res.n_phi) + "x" + std::to_string(res.z_panels * res.gauss_order);
    add_row("quadrature", label, max_rel_error(pts, ref, quad), ns_per_eval(pts, quad));
  }

  // Worst errors per distance: dipole in B, dipole in G (against the analytic exact gradient), exact in B.
  std::vector<std::array<double, 3>> worst(spec.distances.size(), {0.0, 0.0, 0.0});
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const magnetics::FieldSample ex = magnet.field_gradient(pts[i]);
    const magnetics::FieldSample dp = magnetics::dipole_field_gradient(m, pts[i]);
    auto& w = worst[distance_of[i]];
    w[0] = std::max(w[0], (dp.b - ref[i]).norm() / ref[i].norm());
    w[1] = std::max(w[1], (dp.g - ex.g).norm() / ex.g.norm());
    w[2] = std::max(w[2], (ex.b - ref[i]).norm() / ref[i].norm());
  }
  std::string by_distance = "distance_m,dipole_err_B,dipole_err_G,exact_err_B\n";
  for (std::size_t k = 0; k < spec.distances.size(); ++k) {
    append_csv_row(by_distance, std::array{spec.distances[k], worst[k][0], worst[k][1], worst[k][2]});
  }
  write_file_atomically(dir / "field_models.csv", models);
  write_file_atomically(dir / "field_model_distance.csv", by_distance);
}

}  // namespace magvine::studies
