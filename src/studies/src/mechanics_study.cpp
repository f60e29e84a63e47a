#include "magvine/studies/mechanics_study.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "magvine/core/atomic_file.hpp"
#include "magvine/core/stopwatch.hpp"
#include "magvine/core/text.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/magnetics/magnetisation.hpp"
#include "magvine/robot/elastica.hpp"
#include "magvine/robot/inflated_beam.hpp"
#include "magvine/robot/rod.hpp"
#include "magvine/robot/vine.hpp"

namespace magvine::studies {
namespace {

using robot::RodField;
using robot::RodModel;
using robot::RodState;

constexpr double kEpmRadius = 50.8e-3;   // Ø101.6 × 101.6 mm N52 (thesis 4.6.3, 5.8.1)
constexpr double kEpmLength = 101.6e-3;
constexpr double kEpmPolarisation = 1.48;  // J [T]: |m| = J V/μ0 = 970 A·m², the thesis's 970.1 A·m²

/// Mean wall time of one equilibrium from the straight rod (repeated for at least 0.2 s), and the solved state.
double time_solve(const RodModel& m, const RodField& field, RodState& out, robot::RodSolveReport& report) {
  int runs = 0;
  const Stopwatch clock;
  do {
    out = robot::straight_rod(m);
    report = robot::solve_rod_statics(m, field, out);
    ++runs;
  } while (clock.seconds() < 0.2 && runs < 1000);
  return clock.seconds() / runs;
}

magnetics::FieldModel epm(const Vec3& position, const Vec3& moment_direction) {
  magnetics::FieldModel model;
  model.add(magnetics::CylinderMagnet(kEpmRadius, kEpmLength, Vec3(0.0, 0.0, kEpmPolarisation)),
            magnetics::Pose::from_axis(position, moment_direction), "EPM");
  return model;
}

/// A uniform field through the magnetics module's own source (no gradient is evaluated for it).
RodField uniform(const Vec3& b) {
  magnetics::FieldModel model;
  model.add(magnetics::UniformSource{b}, magnetics::Pose{}, "uniform");
  return magnetics::field_function(model, model.rest_poses);
}

/// The skin MVR of thesis 4.6 (robot::thesis_skin_mvr), 80 mm, at pressure p.
robot::VineParameters skin_mvr(double pressure, int edges) {
  robot::VineParameters v = robot::thesis_skin_mvr(80e-3, edges);
  v.pressure = pressure;
  return v;
}

/// Chord angle of the tip from the base direction +z towards +x [deg] (the thesis's θ = asin(y(l)/l)).
double chord_angle(const Vec3& tip) { return std::atan2(tip.x(), tip.z()) / kDegToRad; }

}  // namespace

void run_rod_convergence_study(const std::filesystem::path& dir) {
  struct Case {
    const char* name;
    RodField field;
  };
  const double length = 60e-3;
  const double side = 3e-3;
  std::vector<Case> cases;
  cases.push_back({"uniform 10 mT perpendicular", uniform(Vec3(0.0, 10e-3, 0.0))});
  cases.push_back({"uniform 20 mT at 135 deg", uniform(20e-3 * Vec3(std::cos(0.75 * kPi), std::sin(0.75 * kPi), 0.0))});
  const magnetics::FieldModel magnet = epm(Vec3(0.5 * length, -0.15, 0.0), Vec3::UnitY());
  cases.push_back({"EPM at 150 mm", magnetics::field_function(magnet, magnet.rest_poses)});
  std::ostringstream csv;
  csv.precision(9);
  csv << "case,nodes,spacing_m,tip_error_rel_L,seconds,iterations\n";
  for (const Case& c : cases) {
    robot::ElasticaProblem p;
    p.length = length;
    p.bending_stiffness = 3.0 * 120e3 * side * side * side * side / 12.0;
    p.area = side * side;
    p.density = 1882.0;
    p.gravity = Eigen::Vector2d(0.0, -9.81);
    p.remanence = 0.125;
    p.field = c.field;
    const robot::ElasticaSolution ref = robot::solve_elastica(p, {.intervals = 4000});
    for (const int edges : {4, 8, 16, 32, 64, 128, 256}) {
      RodModel m = robot::rectangular_rod(length, side, side, 120e3, 1882.0, 0.125, Vec3::UnitX(), edges);
      m.gravity = Vec3(0.0, -9.81, 0.0);
      RodState s;
      robot::RodSolveReport report;
      const double seconds = time_solve(m, c.field, s, report);
      const double error = ref.converged && report.converged ? (s.tip().head<2>() - ref.tip()).norm() / length : NAN;
      csv << csv_quoted(c.name) << ',' << edges + 1 << ',' << length / edges << ',' << error << ',' << seconds << ','
          << report.iterations << '\n';
      std::cerr << "  rod " << c.name << ", " << edges + 1 << " nodes: error " << error << " L, " << seconds * 1e3
                << " ms\n";
    }
  }
  write_file_atomically(dir / "rod_convergence.csv", csv.str());
}

VineDeflectionPoint vine_deflection_point(bool torque, double pressure, double distance, int edges) {
  constexpr double kOffset = 65e-3;  // h: EPM centre above the base (thesis 4.7.1)
  const robot::VineParameters v = skin_mvr(pressure, edges);
  RodModel m = robot::vine_rod(v);
  m.base_frame.col(0) = Vec3::UnitZ();
  m.base_frame.col(1) = torque ? Vec3::UnitX() : Vec3::UnitY();  // the skin's m̂ (body y) in or across the plane
  m.base_frame.col(2) = m.base_frame.col(0).cross(m.base_frame.col(1));
  m.gravity = Vec3(0.0, 0.0, -9.81);
  const double moment = m.moment_per_length.front().norm();
  // Torque: EPM axis vertical, field at the body ≈ −z across the skin's +x; gradient: EPM moment along −y, so the
  // field at the body is along the skin's +y and pulls it towards the magnet.
  const magnetics::FieldModel magnet =
      epm(Vec3(distance, 0.0, kOffset), torque ? Vec3::UnitZ() : Vec3(-Vec3::UnitY()));
  const RodField field = magnetics::field_function(magnet, magnet.rest_poses);
  RodState s = robot::straight_rod(m);
  const robot::RodSolveReport report = robot::solve_rod_statics(m, field, s);
  VineDeflectionPoint out;
  out.converged = report.converged;
  out.iterations = report.iterations;
  out.angle_deg = chord_angle(s.tip() - m.base_position);
  out.creased = robot::vine_bend_state(m, s).creased;
  // The two-stage reference: loads of the straight body (the same field), stage 2 with the body turned.
  const Vec3 m_hat = torque ? Vec3::UnitX() : Vec3::UnitY();
  robot::TwoStageLoads loads;
  const auto straight_wrench = [&](double u) {
    return magnetics::magnetic_wrench(moment * m_hat, field(Vec3(0.0, 0.0, u)));
  };
  loads.force = [&](double u) { return straight_wrench(u).force.x(); };
  loads.torque = [&](double u) { return straight_wrench(u).torque.y(); };
  loads.creased_base_moment = [&](double theta) {
    const Vec3 axis(std::sin(theta), 0.0, std::cos(theta));
    const Vec3 mh = torque ? Vec3(std::cos(theta), 0.0, -std::sin(theta)) : Vec3::UnitY();
    double total = 0.0;
    const int n = 200;
    for (int i = 0; i <= n; ++i) {
      const double u = v.length * i / n;
      const Vec3 p = u * axis;
      const magnetics::Wrench w = magnetics::magnetic_wrench(moment * mh, field(p));  // per length
      const Vec3 force = w.force + m.mass_per_length * m.gravity;
      const double per_length = p.cross(force).y() + w.torque.y();
      total += (i == 0 || i == n ? 0.5 : 1.0) * per_length * v.length / n;
    }
    return total;
  };
  const robot::TwoStageResult ref = robot::solve_two_stage(
      {.radius = m.inflated->radius, .pressure = v.pressure, .bending_stiffness = m.bending_stiffness_3,
       .length = v.length},
      loads, 400);
  out.two_stage_angle_deg = ref.angle / kDegToRad;
  out.two_stage_stage = ref.stage;
  return out;
}

void run_vine_deflection_study(const std::filesystem::path& dir) {
  std::ostringstream csv;
  csv.precision(9);
  csv << "setup,pressure_kPa,d_mm,angle_deg,creased,two_stage_angle_deg,two_stage_stage,iterations,converged\n";
  for (const std::string setup : {"torque", "gradient"}) {
    for (const double kpa : {1.0, 6.0, 12.0}) {
      // d > L + R_EPM: the body cannot reach the magnet (no contact in free space).
      for (double d_mm = 300.0; d_mm >= 132.0; d_mm -= 4.0) {
        const VineDeflectionPoint p = vine_deflection_point(setup == "torque", kpa * kKpaToPa, d_mm * kMmToM);
        csv << setup << ',' << kpa << ',' << d_mm << ',' << p.angle_deg << ',' << (p.creased ? 1 : 0) << ','
            << p.two_stage_angle_deg << ',' << p.two_stage_stage << ',' << p.iterations << ','
            << (p.converged ? 1 : 0) << '\n';
      }
      std::cerr << "  vine " << setup << " " << kpa << " kPa done\n";
    }
  }
  write_file_atomically(dir / "vine_deflection.csv", csv.str());
}

void run_fluid_vine_study(const std::filesystem::path& dir) {
  constexpr double kLength = 50e-3;
  constexpr int kEdges = 25;
  std::ostringstream csv;
  std::ostringstream summary;
  csv.precision(9);
  summary.precision(6);
  csv << "law,diameter_mm,pressure_kPa,d_mm,angle_deg,iterations,converged\n";
  summary << "law,diameter_mm,pressure_kPa,critical_d_mm,snap_deg,max_angle_deg,B_mT_at_critical,dB_dd_mT_per_m_at_critical,"
             "thesis_critical_d_mm,thesis_max_angle_deg\n";
  const double thesis_angle[] = {52.0, 59.0, 51.0};
  for (const robot::FluidLaw law : {robot::FluidLaw::kBounded, robot::FluidLaw::kThesis}) {
    const char* law_name = law == robot::FluidLaw::kBounded ? "bounded" : "thesis";
    for (int k = 0; k < 3; ++k) {
      const double diameter = std::array<double, 3>{4e-3, 5e-3, 7e-3}[static_cast<std::size_t>(k)];
      // Growing pressure: 35 kPa at Ø4 mm (thesis 5.6.1), scaled with 1/d² (thesis 5.8.2) for the others.
      const double growing = 35e3 * std::pow(4e-3 / diameter, 2);
      for (const double pressure : {growing, 0.5 * growing}) {
        robot::VineParameters v = robot::thesis_fluid_vine(kLength, kEdges);
        v.radius = 0.5 * diameter;
        v.pressure = pressure;
        v.law = law;
        RodModel m = robot::vine_rod(v);
        m.base_frame.col(0) = Vec3::UnitZ();
        m.base_frame.col(1) = Vec3::UnitX();
        m.base_frame.col(2) = Vec3::UnitZ().cross(Vec3::UnitX());
        m.gravity = Vec3(0.0, 0.0, -9.81);
        std::vector<std::pair<double, double>> curve;
        const double far = law == robot::FluidLaw::kThesis ? 600.0 : 300.0;
        for (double d_mm = far; d_mm >= 104.0; d_mm -= 4.0) {  // d > L + R_EPM: the body cannot reach the magnet
          // EPM at the tip's height, its axis pointing at the vine (thesis 5.6.1).
          const magnetics::FieldModel magnet = epm(Vec3(d_mm * kMmToM, 0.0, kLength), Vec3(-Vec3::UnitX()));
          const RodField field = magnetics::field_function(magnet, magnet.rest_poses);
          RodState s = robot::straight_rod(m);
          const robot::RodSolveReport report = robot::solve_rod_statics(m, field, s);
          const double angle = chord_angle(s.tip());
          curve.emplace_back(d_mm, angle);
          csv << law_name << ',' << diameter * 1e3 << ',' << pressure / kKpaToPa << ',' << d_mm << ',' << angle << ','
              << report.iterations << ',' << (report.converged ? 1 : 0) << '\n';
        }
        // Critical distance: the farthest distance (approaching from afar) at which the bend reaches 20°, where the
        // thesis saw it "deflect sharply"; the snap is the largest angle increase between neighbouring distances.
        double snap = 0.0;
        double critical = NAN;
        double largest = 0.0;
        for (std::size_t i = 0; i < curve.size(); ++i) {
          largest = std::max(largest, curve[i].second);
          if (std::isnan(critical) && curve[i].second >= 20.0) critical = curve[i].first;
          if (i > 0) snap = std::max(snap, curve[i].second - curve[i - 1].second);
        }
        summary << law_name << ',' << diameter * 1e3 << ',' << pressure / kKpaToPa << ',';
        if (std::isnan(critical)) {
          summary << ',' << snap << ',' << largest << ",,,";  // never reaches 20° on the grid: no critical distance
        } else {
          const magnetics::FieldModel magnet = epm(Vec3(critical * kMmToM, 0.0, kLength), Vec3(-Vec3::UnitX()));
          const magnetics::FieldSample at_tip =
              magnetics::field_gradient(magnet, magnet.rest_poses, Vec3(0, 0, kLength));
          summary << critical << ',' << snap << ',' << largest << ',' << at_tip.b.norm() * 1e3 << ','
                  << std::abs(at_tip.b.normalized().dot(at_tip.g * Vec3::UnitX())) * 1e3 << ',';
        }
        summary << "160," << thesis_angle[k] << '\n';
        std::cerr << "  fluid vine " << law_name << " Ø" << diameter * 1e3 << " mm at " << pressure / kKpaToPa
                  << " kPa: 20° reached at " << critical << " mm (largest jump " << snap << "°), largest angle " << largest
                  << "°\n";
      }
    }
  }
  write_file_atomically(dir / "fluid_vine.csv", csv.str());
  write_file_atomically(dir / "fluid_vine_summary.csv", summary.str());
}

}  // namespace magvine::studies
