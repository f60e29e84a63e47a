#include "magvine/scene/calibrate_scene.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "experiment_internal.hpp"
#include "free_space_internal.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/text.hpp"
#include "magvine/core/units.hpp"
#include "ranges.hpp"
#include "robot_entries.hpp"
#include "yaml_reader.hpp"

namespace magvine::scene {
namespace {

/// What a parameter key sets on the vine and in which file unit.
enum class UnitKind { length, stress, density, tesla, plain };
struct ParameterKey {
  std::string_view key;
  UnitKind unit;
  Range range;                                     ///< what the scene accepts for it, SI: the bounds must lie within
  double robot::VineParameters::*field = nullptr;  ///< a top-level member, or
  robot::WallLayer robot::VineParameters::*layer = nullptr;
  double robot::WallLayer::*layer_field = nullptr;  ///< a member of a layer
  double scale = 1.0;                               ///< shear moduli: E = 3G
};

const std::vector<ParameterKey>& parameter_keys() {
  using V = robot::VineParameters;
  using W = robot::WallLayer;
  const Range fraction{0.0, 0.74, true, true};  // as robot_entries' fill.volume_fraction
  static const std::vector<ParameterKey> keys = {
      {"pressure", UnitKind::stress, range::kPressure, &V::pressure},
      {"wall.thickness", UnitKind::length, range::kLayerThickness, nullptr, &V::wall, &W::thickness},
      {"wall.youngs_modulus", UnitKind::stress, range::kModulus, nullptr, &V::wall, &W::modulus},
      {"wall.shear_modulus", UnitKind::stress, range::kModulus, nullptr, &V::wall, &W::modulus, 3.0},
      {"wall.density", UnitKind::density, range::kDensity, nullptr, &V::wall, &W::density},
      {"skin.thickness", UnitKind::length, range::kLayerThickness, nullptr, &V::skin, &W::thickness},
      {"skin.youngs_modulus", UnitKind::stress, range::kModulus, nullptr, &V::skin, &W::modulus},
      {"skin.shear_modulus", UnitKind::stress, range::kModulus, nullptr, &V::skin, &W::modulus, 3.0},
      {"skin.density", UnitKind::density, range::kDensity, nullptr, &V::skin, &W::density},
      {"skin.remanence", UnitKind::tesla, range::kRemanence, &V::skin_remanence},
      {"fill.volume_fraction", UnitKind::plain, fraction, &V::volume_fraction},
      {"fill.density", UnitKind::density, range::kDensity, &V::fill_density},
  };
  return keys;
}

void set_parameter(robot::VineParameters& v, const ParameterKey& k, double si) {
  if (k.field != nullptr) {
    v.*k.field = si;
  } else {
    v.*k.layer.*k.layer_field = k.scale * si;
  }
}

/// The observables by their names in the measurements file.
std::optional<design::Observable> observable_of(const std::string& name) {
  using design::Observable;
  for (const Observable o : {Observable::chord_angle, Observable::bend_angle, Observable::tip_x, Observable::tip_y,
                             Observable::tip_z, Observable::critical_distance}) {
    if (name == design::observable_name(o)) return o;
  }
  return std::nullopt;
}
bool is_angle(design::Observable o) {
  return o == design::Observable::chord_angle || o == design::Observable::bend_angle;
}

std::vector<std::string> split_csv_line(const std::string& line) {
  std::vector<std::string> out;
  std::string cell;
  std::istringstream in(line);
  while (std::getline(in, cell, ',')) {
    const auto first = cell.find_first_not_of(" \t\r");
    const auto last = cell.find_last_not_of(" \t\r");
    out.push_back(first == std::string::npos ? std::string() : cell.substr(first, last - first + 1));
  }
  if (!line.empty() && line.back() == ',') out.emplace_back();
  return out;
}

/// One row of the measurements file, in file units.
struct Row {
  int line = 0;
  std::optional<double> diameter;
  std::optional<double> pressure;
  design::Observable observable = design::Observable::chord_angle;
  double distance = NAN;
  double value = 0.0;
  double sigma = 0.0;
  bool holdout = false;
};

/// Reads the measurements CSV: a header naming observable, distance, value, sigma and use (and optionally diameter and
/// pressure), then one measurement per line; '#' lines and blank lines skipped.
std::vector<Row> read_measurements(const std::filesystem::path& file, const std::string& scene_file) {
  const std::string label = file.string();
  std::istringstream in(read_text_file(label, "measurements file"));
  std::string line;
  int number = 0;
  std::map<std::string, std::size_t> column;
  std::vector<Row> rows;
  const auto fail = [&](const std::string& what) {
    throw InputError(label, number, "", what + " (the measurements of " + scene_file + ")");
  };
  while (std::getline(in, line)) {
    ++number;
    if (line.find_first_not_of(" \t\r") == std::string::npos || line[line.find_first_not_of(" \t")] == '#') continue;
    const std::vector<std::string> cells = split_csv_line(line);
    if (column.empty()) {
      for (std::size_t i = 0; i < cells.size(); ++i) {
        static const std::vector<std::string> known = {"diameter", "pressure", "observable", "distance",
                                                       "value",    "sigma",    "use"};
        if (std::ranges::find(known, cells[i]) == known.end()) {
          fail("unknown column '" + cells[i] +
               "' (columns: diameter, pressure, observable, distance, value, sigma, use)");
        }
        column[cells[i]] = i;
      }
      for (const char* required : {"observable", "value", "sigma", "use"}) {
        if (!column.contains(required)) fail(std::string("the header has no '") + required + "' column");
      }
      continue;
    }
    if (cells.size() != column.size()) {
      fail("has " + std::to_string(cells.size()) + " cells, the header " + std::to_string(column.size()));
    }
    const auto cell = [&](const char* name) -> std::optional<std::string> {
      if (!column.contains(name) || cells[column.at(name)].empty()) return std::nullopt;
      return cells[column.at(name)];
    };
    const auto number_of = [&](const char* name) -> std::optional<double> {
      const std::optional<std::string> text = cell(name);
      if (!text) return std::nullopt;
      std::size_t used = 0;
      double v = NAN;
      try {
        v = std::stod(*text, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != text->size() || !std::isfinite(v))
        fail(std::string(name) + ": '" + *text + "' is not a finite number");
      return v;
    };
    Row r;
    r.line = number;
    r.diameter = number_of("diameter");
    r.pressure = number_of("pressure");
    const std::string observable = cell("observable").value_or("");
    const std::optional<design::Observable> o = observable_of(observable);
    if (!o) {
      fail("observable: '" + observable + "' is not chord_angle, bend_angle, tip_x, tip_y, tip_z or critical_distance");
    }
    r.observable = *o;
    const std::optional<double> distance = number_of("distance");
    if (r.observable != design::Observable::critical_distance) {
      if (!distance) fail("distance: a " + observable + " needs the magnet's distance");
      r.distance = *distance;
    }
    if (!number_of("value")) fail("value: missing");
    r.value = *number_of("value");
    if (!number_of("sigma") || !(*number_of("sigma") > 0.0)) fail("sigma: must be a positive number");
    r.sigma = *number_of("sigma");
    const std::string use = cell("use").value_or("");
    if (use != "fit" && use != "holdout") fail("use: must be fit or holdout (got '" + use + "')");
    r.holdout = use == "holdout";
    if ((r.diameter && !(*r.diameter > 0.0)) || (r.pressure && !(*r.pressure >= 0.0))) {
      fail("diameter and pressure must be positive");
    }
    rows.push_back(r);
  }
  if (rows.empty()) fail("no measurements");
  return rows;
}

}  // namespace

bool is_calibrate_scene(const std::filesystem::path& file) {
  return has_top_level_key(file, "calibrate");
}

CalibrateScene load_calibrate_scene(const std::filesystem::path& file) {
  return parse_calibrate_scene(read_text_file(file.string(), "calibration file"), file.string(), file.parent_path());
}

CalibrateScene parse_calibrate_scene(const std::string& text, const std::string& file_label,
                                     const std::filesystem::path& directory) {
  CalibrateScene out;
  out.file = file_label;
  out.text = text;
  const YAML::Node root = parse_yaml(out.text, out.file);
  out.scene = detail::parse_free_space_root(root, out.file, "calibrate", nullptr);
  const YamlMap top(root, out.file, "");
  const FileUnits units = file_units(top);
  out.length_unit = units.len.si;
  out.pressure_unit = units.stress.si;
  const YamlMap robot_map = top.map("robot");
  if (!out.scene.vine) robot_map.fail("kind", "calibrate fits a vine's parameters (kind: vine)");
  if (!out.scene.magnets || out.scene.magnets->size() != 1 || !out.scene.magnets->has_gradient()) {
    top.fail("magnets", "calibrate needs exactly one magnet (a cylinder or dipole): the one that approaches");
  }
  if (!top.has("calibrate")) top.fail("calibrate", "missing required key");
  const YamlMap c = top.map("calibrate");
  c.allow_only({"parameters", "measurements", "approach", "iterations"});
  if (c.has("iterations")) out.max_iterations = static_cast<int>(c.whole("iterations", 1, 10000));

  // Parameters: keys under robot, each present in the file (its value the start; scene.yaml replaces it).
  const YamlMap params = c.map("parameters");
  const YAML::Node pnode = c.node("parameters");
  if (pnode.size() == 0) c.fail("parameters", "names no parameter");
  std::vector<const ParameterKey*> chosen;
  for (const auto& item : pnode) {
    const std::string key = item.first.as<std::string>();
    const auto found = std::ranges::find_if(parameter_keys(), [&](const ParameterKey& k) { return k.key == key; });
    if (found == parameter_keys().end()) {
      std::string names;
      for (const ParameterKey& k : parameter_keys()) names += (names.empty() ? "" : ", ") + std::string(k.key);
      params.fail(key, "is not a parameter calibrate fits (" + names + ")");
    }
    const auto dot = key.find('.');
    const bool present = dot == std::string::npos ? robot_map.has(key)
                                                  : robot_map.has(key.substr(0, dot)) &&
                                                        robot_map.map(key.substr(0, dot)).has(key.substr(dot + 1));
    if (!present) params.fail(key, "robot." + key + " is not in the scene: name it there (its value is the start)");
    const Unit unit = found->unit == UnitKind::length    ? units.len
                      : found->unit == UnitKind::stress  ? units.stress
                      : found->unit == UnitKind::tesla   ? kTesla
                      : found->unit == UnitKind::density ? kKgPerM3
                                                         : kPlain;
    const YamlMap bounds = params.map(key);
    bounds.allow_only({"min", "max"});
    design::CalibrationParameter q;
    q.name = key;
    q.lower = bounds.quantity("min", unit, found->range);
    q.upper = bounds.quantity("max", unit, found->range);
    const double file_value = dot == std::string::npos ? robot_map.number(key)
                                                       : robot_map.map(key.substr(0, dot)).number(key.substr(dot + 1));
    q.start = file_value * unit.si;
    if (!(q.lower < q.upper)) bounds.fail("max", "must be above min");
    if (!(q.start >= q.lower && q.start <= q.upper)) {
      bounds.fail("min", printf_string("the scene's value (%g) lies outside [min, max]", file_value));
    }
    out.problem.parameters.push_back(q);
    out.keys.emplace_back(key, unit.si);
    out.unit_names.push_back(unit.name);
    chosen.push_back(&*found);
  }

  // The approach: the magnet moves by (d − d0) u from where the scene puts it.
  const robot::RodModel& model = out.scene.model;
  const magnetics::Pose rest = out.scene.magnets->rest_poses.front();
  const Vec3 to_magnet = rest.position - model.base_position;
  const Vec3 axis = model.base_frame.col(0);
  Vec3 u = to_magnet - to_magnet.dot(axis) * axis;
  double step = 4e-3;
  double closest = NAN;
  double critical = 20.0;
  if (c.has("approach")) {
    const YamlMap a = c.map("approach");
    a.allow_only({"direction", "step", "closest", "critical_angle"});
    if (a.has("direction")) u = a.direction("direction");
    if (a.has("step")) step = a.quantity("step", units.len, range::kDistance);
    if (a.has("closest")) closest = a.quantity("closest", units.len, range::kDistance);
    if (a.has("critical_angle")) critical = a.quantity("critical_angle", kPlain, Range{0.0, 180.0, true, true});
  }
  // The magnet's entry: where the approach starts.
  const YamlMap magnet(top.node("magnets")[0], out.file, "magnets[0]");
  if (!(u.norm() > 1e-9 * std::max(1.0, to_magnet.norm()))) {
    magnet.fail("position",
                "the magnet sits on the base's axis, so the approach has no direction: give "
                "calibrate.approach.direction");
  }
  u.normalize();
  const double start = to_magnet.dot(u);
  if (!(start > 0.0)) {
    magnet.fail("position", "the approach must start on the far side along calibrate.approach.direction (d0 > 0)");
  }
  if (std::isnan(closest)) closest = 0.5 * start;

  // Measurements, grouped into cases by (diameter, pressure).
  const std::string mfile = c.text("measurements");
  const std::filesystem::path mpath = directory / mfile;
  out.measurements_file = mpath.string();
  const std::vector<Row> rows = read_measurements(mpath, out.file);
  const robot::VineParameters base = *out.scene.vine;
  for (const Row& r : rows) {
    const double diameter = r.diameter ? *r.diameter * units.len.si : 2.0 * base.radius;
    const double pressure = r.pressure ? *r.pressure * units.stress.si : base.pressure;
    std::size_t index = 0;
    while (index < out.case_settings.size() && out.case_settings[index] != std::pair{diameter, pressure}) ++index;
    if (index == out.case_settings.size()) {
      out.case_settings.emplace_back(diameter, pressure);
      design::CalibrationCase k;
      k.label = printf_string("Ø%g mm at %g kPa", diameter * 1e3, pressure * 1e-3);
      k.model = [base, chosen, diameter, pressure, model](const VecX& theta) {
        robot::VineParameters v = base;
        v.radius = 0.5 * diameter;
        v.pressure = pressure;
        for (std::size_t i = 0; i < chosen.size(); ++i)
          set_parameter(v, *chosen[i], theta[static_cast<Eigen::Index>(i)]);
        robot::RodModel m = robot::vine_rod(v);
        m.base_position = model.base_position;
        m.base_frame = model.base_frame;
        m.gravity = model.gravity;
        return m;
      };
      k.magnet = *out.scene.magnets;
      k.approach = u;
      k.start_distance = start;
      k.step = step;
      k.closest = closest;
      k.critical_angle = critical * kDegToRad;
      k.solver = out.scene.solver;
      out.problem.cases.push_back(std::move(k));
    }
    design::Measurement m;
    m.case_index = index;
    m.observable = r.observable;
    m.distance = r.distance * units.len.si;
    m.value = is_angle(r.observable) ? r.value * kDegToRad : r.value * units.len.si;
    m.sigma = is_angle(r.observable) ? r.sigma * kDegToRad : r.sigma * units.len.si;
    m.holdout = r.holdout;
    if (r.observable != design::Observable::critical_distance && !(m.distance > 0.0)) {
      throw InputError(out.measurements_file, r.line, "distance",
                       "must be positive (the measurements of " + out.file + ")");
    }
    if (r.observable != design::Observable::critical_distance && !(m.distance <= start * (1 + 1e-12))) {
      magnet.fail("position", printf_string("the approach starts at d0 = %g %s, closer than the measurement at %g %s "
                                            "(%s:%d)",
                                            start / units.len.si, units.len.name.c_str(), r.distance,
                                            units.len.name.c_str(), out.measurements_file.c_str(), r.line));
    }
    out.problem.measurements.push_back(m);
  }
  // At its closest the magnet must stay out of the body's reach: the field inside a magnet is no load on a body, and
  // the body would meet it.
  double nearest = start;
  for (const design::Measurement& m : out.problem.measurements) {
    nearest = std::min(nearest, m.observable == design::Observable::critical_distance ? closest : m.distance);
  }
  const Vec3 centre = rest.position + (nearest - start) * u;
  double gap = (centre - model.base_position).norm();
  if (const std::optional<detail::MagnetBody> body = detail::magnet_body(*out.scene.magnets, 0)) {
    const Vec3 local = rest.rotation.transpose() * (model.base_position - centre);
    const double radial = std::max(0.0, local.head<2>().norm() - body->radius);
    const double axial = std::max(0.0, std::abs(local.z()) - body->half_length);
    gap = std::hypot(radial, axial);
  }
  if (!(gap > model.length)) {
    magnet.fail("position", printf_string("at the approach's closest, d = %g %s, the magnet comes within %g %s of the "
                                          "base, inside the %g %s body's reach: start it farther, turn it, or raise "
                                          "calibrate.approach.closest and the measurements' distances",
                                          nearest / units.len.si, units.len.name.c_str(), gap / units.len.si,
                                          units.len.name.c_str(), model.length / units.len.si, units.len.name.c_str()));
  }
  // Each case's body must be one the vine law accepts (the diameter and pressure of the rows included).
  for (std::size_t i = 0; i < out.problem.cases.size(); ++i) {
    VecX start_theta(static_cast<Eigen::Index>(out.problem.parameters.size()));
    for (std::size_t k = 0; k < out.problem.parameters.size(); ++k) {
      start_theta[static_cast<Eigen::Index>(k)] = out.problem.parameters[k].start;
    }
    try {
      (void)out.problem.cases[i].model(start_theta);
    } catch (const InputError& e) {
      throw InputError(out.measurements_file, 0, out.problem.cases[i].label,
                       std::string(e.what()) + " (the measurements of " + out.file + ")");
    }
  }
  design::check_calibration_problem(out.problem, out.file);
  return out;
}

std::string calibrated_scene_yaml(const CalibrateScene& scene, const design::CalibrationResult& result) {
  YAML::Node root = YAML::Clone(parse_yaml(scene.text, scene.file));
  root.remove("calibrate");
  for (std::size_t i = 0; i < scene.keys.size(); ++i) {
    const std::string& key = scene.keys[i].first;
    const double value = result.theta[static_cast<Eigen::Index>(i)] / scene.keys[i].second;
    const auto dot = key.find('.');
    if (dot == std::string::npos) {
      root["robot"][key] = value;
    } else {
      root["robot"][key.substr(0, dot)][key.substr(dot + 1)] = value;
    }
  }
  YAML::Emitter emitter;
  emitter << root;
  return "# The scene calibrated by `magvine calibrate " + scene.file + "` (run it with `magvine run`).\n" +
         std::string(emitter.c_str()) + "\n";
}

void write_calibration_outputs(const CalibrateScene& scene, const design::CalibrationResult& r,
                               const std::filesystem::path& dir) {
  const std::size_t p = scene.keys.size();
  nlohmann::json j;
  j["parameters"] = nlohmann::json::array();
  for (std::size_t i = 0; i < p; ++i) {
    const auto k = static_cast<Eigen::Index>(i);
    const double unit = scene.keys[i].second;
    const design::CalibrationParameter& q = scene.problem.parameters[i];
    j["parameters"].push_back(
        {{"key", "robot." + q.name},
         {"unit", scene.unit_names[i]},
         {"value", r.theta[k] / unit},
         {"sigma", std::isfinite(r.sigma[k]) ? nlohmann::json(r.sigma[k] / unit) : nlohmann::json()},
         {"start", q.start / unit},
         {"min", q.lower / unit},
         {"max", q.upper / unit}});
  }
  nlohmann::json cov = nlohmann::json::array();
  nlohmann::json corr = nlohmann::json::array();
  for (Eigen::Index a = 0; a < r.covariance.rows(); ++a) {
    nlohmann::json crow = nlohmann::json::array();
    nlohmann::json rrow = nlohmann::json::array();
    for (Eigen::Index b = 0; b < r.covariance.cols(); ++b) {
      crow.push_back(r.covariance(a, b));
      const double s = r.sigma[a] * r.sigma[b];
      rrow.push_back(std::isfinite(s) && s > 0.0 ? nlohmann::json(r.covariance(a, b) / s) : nlohmann::json());
    }
    cov.push_back(crow);
    corr.push_back(rrow);
  }
  j["covariance_si"] = cov;
  j["correlation"] = corr;
  j["chi2"] = r.chi2;
  j["fitted"] = r.fitted;
  j["held_out"] = static_cast<int>(scene.problem.measurements.size()) - r.fitted;
  j["iterations"] = r.iterations;
  j["evaluations"] = r.evaluations;
  j["equilibria"] = r.equilibria;
  j["runtime_s"] = r.runtime_s;
  j["converged"] = r.converged;
  j["message"] = r.message;
  j["history_chi"] = r.history;
  j["measurements_file"] = scene.measurements_file;

  std::ostringstream csv;
  csv.precision(9);
  csv << "diameter,pressure,observable,distance,measured,sigma,predicted,predicted_sigma,use,z,reached\n";
  for (std::size_t i = 0; i < scene.problem.measurements.size(); ++i) {
    const design::Measurement& m = scene.problem.measurements[i];
    const auto k = static_cast<Eigen::Index>(i);
    const double unit = is_angle(m.observable) ? kDegToRad : scene.length_unit;
    const auto& [diameter, pressure] = scene.case_settings[m.case_index];
    const double z = (r.predictions.values[k] - m.value) /
                     std::sqrt(m.sigma * m.sigma + r.prediction_sigma[k] * r.prediction_sigma[k]);
    csv << diameter / scene.length_unit << ',' << pressure / scene.pressure_unit << ','
        << design::observable_name(m.observable) << ',';
    if (m.observable != design::Observable::critical_distance) csv << m.distance / scene.length_unit;
    csv << ',' << m.value / unit << ',' << m.sigma / unit << ',' << r.predictions.values[k] / unit << ','
        << r.prediction_sigma[k] / unit << ',' << (m.holdout ? "holdout" : "fit") << ',' << z << ','
        << (r.predictions.reached[i] ? 1 : 0) << '\n';
  }
  std::filesystem::create_directories(dir);
  write_file_atomically(dir / "calibration.json", j.dump(2) + "\n");
  write_file_atomically(dir / "predictions.csv", csv.str());
  write_file_atomically(dir / "scene.yaml", calibrated_scene_yaml(scene, r));
}

}  // namespace magvine::scene
