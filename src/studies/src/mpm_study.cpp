#include "magvine/studies/mpm_study.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include <sstream>
#include <thread>

#include "magvine/core/atomic_file.hpp"
#include "magvine/core/elliptic.hpp"
#include "magvine/core/stopwatch.hpp"
#include "magvine/core/units.hpp"
#include "magvine/mpm/cantilever.hpp"

namespace magvine::studies {
namespace {

// The Zhao beam as in the public reference code's 2D script (notes §5): Br 0.143 T, G 303 kPa. The density only
// sets how fast it comes to rest, not where (2000 kg/m³ assumed, PDMS with NdFeB).
constexpr double kLength = 17.2e-3;
constexpr double kThickness = 0.84e-3;
constexpr double kShear = 303e3;
constexpr double kRemanence = 0.143;
constexpr double kDensity = 2000.0;
constexpr double kDamping = 140.0;     // ≈ 2ω₁ of the straight beam: close to critical for its first mode [1/s]
constexpr double kKick = 3e-3;         // transverse field for the first millisecond [T] (the reference protocol)
constexpr double kKickTime = 1e-3;
constexpr double kRestTolerance = 1e-4;  // of L over a 20 ms window

/// The study's resolutions: (cells through the thickness, particles per cell per axis).
constexpr std::pair<int, int> kResolutions[] = {{3, 2}, {3, 3}, {3, 4}, {4, 4}, {5, 4}};

}  // namespace

double plane_strain_modulus(const mpm::Material& m) {
  const double k = m.bulk_modulus, g = m.shear_modulus;
  const double e = 9.0 * k * g / (3.0 * k + g);
  const double nu = (3.0 * k - 2.0 * g) / (2.0 * (3.0 * k + g));
  return e / (1.0 - nu * nu);
}

double antiparallel_elastica_deflection(double bbar) {
  const double root = std::sqrt(bbar);
  if (root <= 0.5 * kPi) return 0.0;
  double lo = 0.0, hi = 1.0;  // K(k) increases from π/2 at k = 0 to ∞ at k = 1
  for (int i = 0; i < 200 && hi - lo > 1e-15; ++i) {
    const double k = 0.5 * (lo + hi);
    (ellip_k(k * k) < root ? lo : hi) = k;
  }
  const double k = 0.5 * (lo + hi);
  return 2.0 * k / ellip_k(k * k);
}

std::vector<double> zhao_study_fields() { return {7e-3, 10e-3, 12.5e-3, 15e-3, 20e-3, 25e-3}; }

ZhaoPoint run_zhao_beam(int cells, int ppc, double field) {
  mpm::CantileverSpec spec;
  spec.length = kLength;
  spec.thickness = kThickness;
  spec.cells_through_thickness = cells;
  spec.particles_per_cell = ppc;
  spec.material = {kShear, 20.0 * kShear, kDensity};
  spec.remanence = Vec3(kRemanence, 0.0, 0.0);
  spec.damping = kDamping;
  mpm::Cantilever<2> beam = mpm::make_cantilever<2>(spec);
  ZhaoPoint p;
  p.cells = cells;
  p.particles_per_cell = ppc;
  p.particles = beam.model.size();
  p.field = field;
  p.bbar = 12.0 * (kLength / kThickness) * (kLength / kThickness) * kRemanence * field /
           (kMu0 * plane_strain_modulus(spec.material));
  p.reference = antiparallel_elastica_deflection(p.bbar);
  mpm::SettleOptions o;
  o.min_time = 0.05;
  o.max_time = 1.5;
  o.window = 0.02;
  o.tolerance = kRestTolerance * kLength;
  mpm::MpmWorkspace<2> ws;
  const Stopwatch clock;
  const mpm::SettleResult r = mpm::settle<2>(
      beam.model, beam.state, ws,
      [field](double t) {
        mpm::AppliedField f;
        f.kind = mpm::AppliedField::Kind::kUniform;
        f.uniform = Vec3(-field, t < kKickTime ? kKick : 0.0, 0.0);
        return f;
      },
      beam.tip, o);
  p.seconds = clock.seconds();
  p.ok = r.status.ok;
  p.settled = r.settled;
  p.steps = r.steps;
  p.deflection = std::abs(mpm::mean_position(beam.state, beam.tip).y()) / kLength;
  return p;
}

void run_mpm_beam_study(const std::filesystem::path& dir, int jobs, const std::function<void(const ZhaoPoint&)>& progress) {
  create_output_directory(dir);
  struct Job {
    int cells, ppc;
    double field;
  };
  std::vector<Job> todo;
  for (const auto& [cells, ppc] : kResolutions) {
    for (double b : zhao_study_fields()) todo.push_back({cells, ppc, b});
  }
  std::vector<ZhaoPoint> points(todo.size());
  std::atomic<std::size_t> next{0};
  std::mutex report;
  auto worker = [&] {
    for (std::size_t i = next++; i < todo.size(); i = next++) {
      points[i] = run_zhao_beam(todo[i].cells, todo[i].ppc, todo[i].field);
      if (progress) {
        const std::lock_guard lock(report);
        progress(points[i]);
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 0; t < std::max(1, jobs); ++t) pool.emplace_back(worker);
  for (std::thread& t : pool) t.join();

  std::ostringstream csv, summary;
  csv << "cells,particles_per_cell,particles,field_mT,bbar,reference,deflection,abs_error_pct,settled,ok,steps,seconds\n";
  summary << "cells,particles_per_cell,particles,mape_pct,seconds,all_settled\n";
  for (const auto& [cells, ppc] : kResolutions) {
    double sum = 0.0, seconds = 0.0;
    int n = 0;
    bool settled = true;
    std::size_t particles = 0;
    for (const ZhaoPoint& p : points) {
      if (p.cells != cells || p.particles_per_cell != ppc) continue;
      const double err = 100.0 * std::abs(p.deflection - p.reference) / p.reference;
      csv << p.cells << ',' << p.particles_per_cell << ',' << p.particles << ',' << p.field * 1e3 << ',' << p.bbar
          << ',' << p.reference << ',' << p.deflection << ',' << err << ',' << p.settled << ',' << p.ok << ','
          << p.steps << ',' << p.seconds << '\n';
      sum += err;
      seconds += p.seconds;
      settled = settled && p.settled && p.ok;
      particles = p.particles;
      ++n;
    }
    summary << cells << ',' << ppc << ',' << particles << ',' << sum / n << ',' << seconds << ',' << settled << '\n';
  }
  write_file_atomically(dir / "mpm_beam_study.csv", csv.str());
  write_file_atomically(dir / "mpm_beam_summary.csv", summary.str());
}

}  // namespace magvine::studies
