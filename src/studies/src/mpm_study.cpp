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
#include "magvine/core/text.hpp"
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

std::vector<double> zhao_experiment_fields() { return {5e-3, 7e-3, 10e-3, 15e-3, 25e-3, 40e-3}; }

const char* zhao_model_name(ZhaoModel model) {
  switch (model) {
    case ZhaoModel::kPlaneStrain:
      return "plane-strain";
    case ZhaoModel::kPlaneStress:
      return "plane-stress";
    case ZhaoModel::k3D:
      return "3d";
  }
  return "?";
}

double zhao_reference_modulus(ZhaoModel model, const mpm::Material& m) {
  if (model == ZhaoModel::kPlaneStrain) return plane_strain_modulus(m);
  return 9.0 * m.bulk_modulus * m.shear_modulus / (3.0 * m.bulk_modulus + m.shear_modulus);
}

namespace {

template <int D>
ZhaoPoint settle_zhao_beam(const mpm::CantileverSpec& spec, double field, ZhaoPoint p) {
  mpm::Cantilever<D> beam = mpm::make_cantilever<D>(spec);
  p.particles = beam.model.size();
  mpm::SettleOptions o;
  o.min_time = 0.05;
  o.max_time = 1.5;
  o.window = 0.02;
  o.tolerance = kRestTolerance * kLength;
  o.total_lagrangian = p.total_lagrangian;
  if (p.step_ratio > 0.0) {  // at most a quarter of the kick, so that it lasts as the protocol says
    o.implicit = true;
    const double bound = beam.model.stable_step(o.courant);
    o.time_step = std::min(p.step_ratio * bound, 0.25 * kKickTime);
    p.step_ratio = o.time_step / bound;
  }
  mpm::MpmWorkspace<D> ws;
  const Stopwatch clock;
  const mpm::SettleResult r = mpm::settle<D>(
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
  p.failure = r.status.cause;
  p.settled = r.settled;
  p.steps = r.steps;
  p.newton = r.newton;
  p.cg = r.cg;
  p.retries = r.retries;
  p.deflection = std::abs(mpm::mean_position(beam.state, beam.tip).y()) / kLength;
  return p;
}

}  // namespace

ZhaoPoint run_zhao_beam(int cells, int ppc, double field, ZhaoModel model, bool total_lagrangian, double step_ratio) {
  mpm::CantileverSpec spec;
  spec.length = kLength;
  spec.thickness = kThickness;
  spec.width = kZhaoWidth;
  spec.cells_through_thickness = cells;
  spec.particles_per_cell = ppc;
  spec.material = {kShear, 20.0 * kShear, kDensity};
  spec.remanence = Vec3(kRemanence, 0.0, 0.0);
  spec.damping = kDamping;
  spec.plane = model == ZhaoModel::kPlaneStress ? mpm::Plane::kStress : mpm::Plane::kStrain;
  ZhaoPoint p;
  p.model = model;
  p.total_lagrangian = total_lagrangian;
  p.step_ratio = step_ratio;
  p.cells = cells;
  p.particles_per_cell = ppc;
  p.field = field;
  p.bbar = 12.0 * (kLength / kThickness) * (kLength / kThickness) * kRemanence * field /
           (kMu0 * zhao_reference_modulus(model, spec.material));
  p.reference = antiparallel_elastica_deflection(p.bbar);
  return model == ZhaoModel::k3D ? settle_zhao_beam<3>(spec, field, p) : settle_zhao_beam<2>(spec, field, p);
}

void run_mpm_beam_study(const std::filesystem::path& dir, int jobs, const MpmBeamStudyOptions& options,
                        const std::function<void(const ZhaoPoint&)>& progress) {
  create_output_directory(dir);
  struct Job {
    int cells, ppc;
    double field;
  };
  std::vector<Job> todo;
  for (const auto& [cells, ppc] : options.resolutions) {
    for (double b : options.fields) todo.push_back({cells, ppc, b});
  }
  std::vector<ZhaoPoint> points(todo.size());
  std::atomic<std::size_t> next{0};
  std::mutex report;
  const int threads = std::max(1, jobs);
  auto worker = [&] {
    mpm::share_step_threads(threads);  // each beam its share of the cores
    for (std::size_t i = next++; i < todo.size(); i = next++) {
      points[i] = run_zhao_beam(todo[i].cells, todo[i].ppc, todo[i].field, options.model, options.total_lagrangian,
                                options.step_ratio);
      if (progress) {
        const std::lock_guard lock(report);
        progress(points[i]);
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) pool.emplace_back(worker);
  for (std::thread& t : pool) t.join();

  std::ostringstream csv, summary;
  csv.precision(8);
  summary.precision(8);
  csv << "model,frame,cells,particles_per_cell,particles,field_mT,bbar,reference,deflection,abs_error_pct,experiment,settled,"
         "ok,steps,seconds,step_ratio,newton,cg,failure,retries\n";
  summary << "model,frame,cells,particles_per_cell,particles,mape_pct,seconds,all_settled,step_ratio\n";
  for (const auto& [cells, ppc] : options.resolutions) {
    double sum = 0.0, seconds = 0.0;
    int n = 0, buckled = 0;
    bool settled = true;
    std::size_t particles = 0;
    for (const ZhaoPoint& p : points) {
      if (p.cells != cells || p.particles_per_cell != ppc) continue;
      const bool has_reference = p.reference > 0.0;  // below the buckling field the elastica is straight
      const double err = has_reference ? 100.0 * std::abs(p.deflection - p.reference) / p.reference : 0.0;
      const bool at_5mt = std::abs(p.field - 5e-3) < 1e-9;
      csv << zhao_model_name(p.model) << ',' << (p.total_lagrangian ? "total" : "updated") << ',' << p.cells << ',' << p.particles_per_cell << ',' << p.particles << ','
          << p.field * 1e3 << ',' << p.bbar << ',' << p.reference << ',' << p.deflection << ',';
      if (has_reference) csv << err;
      csv << ',';
      if (at_5mt) csv << kZhaoExperiment5mT;
      csv << ',' << p.settled << ',' << p.ok << ',' << p.steps << ',' << p.seconds << ',' << p.step_ratio << ','
          << p.newton << ',' << p.cg << ',' << csv_quoted(p.failure) << ',' << p.retries << '\n';
      if (has_reference) {
        sum += err;
        ++buckled;
      }
      seconds += p.seconds;
      settled = settled && p.settled && p.ok;
      particles = p.particles;
      ++n;
    }
    summary << zhao_model_name(options.model) << ',' << (options.total_lagrangian ? "total" : "updated") << ','
            << cells << ',' << ppc << ',' << particles << ','
            << (buckled > 0 ? sum / buckled : 0.0) << ',' << seconds << ',' << settled << ',' << options.step_ratio
            << '\n';
  }
  write_file_atomically(dir / "mpm_beam_study.csv", csv.str());
  write_file_atomically(dir / "mpm_beam_summary.csv", summary.str());
}

}  // namespace magvine::studies
