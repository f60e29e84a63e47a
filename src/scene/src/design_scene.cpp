#include "magvine/scene/design_scene.hpp"

#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>

#include "free_space_internal.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/field_function.hpp"
#include "ranges.hpp"
#include "robot_entries.hpp"
#include "yaml_reader.hpp"

namespace magvine::scene {
namespace {

constexpr int kMaxIterations = 100000;

/// The target points: a list of [x, y, z] in file length units, as SI.
std::vector<Vec3> target_points(const YamlMap& target, const Unit& length, const std::string& key) {
  if (key == "points") target.allow_only({"points"});
  const YAML::Node list = target.node(key);
  if (!list.IsSequence()) target.fail(key, "must be a list of [x, y, z] points");
  std::vector<Vec3> out;
  for (std::size_t k = 0; k < list.size(); ++k) {
    const std::string path = target.key_path(key + "[" + std::to_string(k) + "]");
    const YAML::Node p = list[k];
    if (!p.IsSequence() || p.size() != 3) target.fail_at(p, path, "must be a point [x, y, z]");
    Vec3 v;
    for (int i = 0; i < 3; ++i) {
      const double x = checked_number(p[static_cast<std::size_t>(i)], target.file(), path);
      v[i] = checked_quantity(x, length, range::kCoordinate, target.file(), p, path);
    }
    out.push_back(v);
  }
  return out;
}

}  // namespace

DesignScene parse_design_scene(const std::string& text, const std::string& file_label) {
  const YAML::Node root = parse_yaml(text, file_label);
  DesignScene out;
  double area = 0.0;
  out.scene = detail::parse_free_space_root(root, file_label, "design", &area);
  out.file = file_label;
  out.text = text;
  const YamlMap top(root, file_label, "");
  const FileUnits units = file_units(top);
  out.length_unit = units.len.si;
  out.seed = seed_of(top, 1);
  if (out.scene.vine) top.map("robot").fail("kind", "a design needs a rod (kind: rod): vines are not designed");
  out.circular_section = top.map("robot").map("section").text("shape") == "circle";  // (checked by parse_rod)
  if (!top.has("design")) top.fail("design", "missing required key (the design file's design: section)");
  const YamlMap d = top.map("design");
  d.allow_only({"sections", "remanence", "target", "field", "iterations", "method", "starts", "insertion", "magnet"});
  design::DesignProblem& p = out.problem;
  p.model = out.scene.model;
  p.area = area;
  p.solver = out.scene.solver;
  p.spec.sections = static_cast<int>(d.whole("sections", 1, 1000));
  if (d.has("remanence")) {
    if (d.node("remanence").IsMap()) {
      const YamlMap r = d.map("remanence");
      r.allow_only({"min", "max"});
      const double lo = r.quantity("min", kTesla, range::kRemanenceBound);
      const double hi = r.quantity("max", kTesla, range::kRemanenceBound);
      if (lo > hi) r.fail("min", "exceeds max: the bounds exclude every design");
      if (!(hi > 0.0)) r.fail("max", "must be > 0");
      p.spec.remanence_bounds = std::make_pair(lo, hi);
    } else {
      p.spec.remanence = d.quantity("remanence", kTesla, range::kRemanenceMagnitude);
    }
  }
  // The target: a shape (target.points), or the path of a follow-the-leader insertion (insertion.path).
  if (d.has("insertion")) {
    const YamlMap ins = d.map("insertion");
    ins.allow_only({"steps", "path"});
    if (d.has("target")) d.fail("target", "give either target or insertion.path (the insertion's target), not both");
    p.insertion_steps = static_cast<int>(ins.whole("steps", 1, 1000));
    p.spec.target = target_points(ins, units.len, "path");
    if (!d.has("field")) ins.fail("steps", "a follow-the-leader insertion needs design.field.free (a field per step)");
  } else {
    p.spec.target = target_points(d.map("target"), units.len, "points");
  }
  if (d.has("field")) {
    const YamlMap f = d.map("field");
    f.allow_only({"free"});
    const YamlMap free = f.map("free");
    free.allow_only({"max"});
    p.spec.field_max = free.quantity("max", kTesla, range::kUniformFieldBound);
  }
  if (d.has("iterations")) out.max_iterations = static_cast<int>(d.whole("iterations", 1, kMaxIterations));
  if (d.has("starts")) out.starts = static_cast<int>(d.whole("starts", 1, 1000));
  if (d.has("method")) {
    const std::string method = d.text("method");
    if (method == "least-squares") {
      out.method = DesignMethod::least_squares;
    } else if (method == "lbfgsb") {
      out.method = DesignMethod::lbfgsb;
    } else if (method == "bayesian") {
      out.method = DesignMethod::bayesian;
    } else {
      d.fail("method", "must be least-squares, lbfgsb or bayesian (got '" + method + "')");
    }
  }
  // The field: the scene's magnets, fixed; or, free, a uniform field that starts at the scene's uniform one.
  if (out.scene.magnets) {
    const magnetics::FieldModel& magnets = *out.scene.magnets;
    if (p.spec.field_max) {
      for (std::size_t i = 0; i < magnets.size(); ++i) {
        if (!std::holds_alternative<magnetics::UniformSource>(magnets.sources[i])) {
          d.fail("field", "a free field is uniform: the scene's magnets may hold uniform fields only (its start)");
        }
      }
      p.start_field = magnetics::field(magnets, magnets.rest_poses, Vec3::Zero());
      if (p.start_field.norm() > *p.spec.field_max) p.start_field *= *p.spec.field_max / p.start_field.norm();
    } else {
      p.field = magnetics::field_function(magnets, magnets.rest_poses);
    }
    if (d.has("magnet")) {  // where the EPM goes joins the unknowns
      const YamlMap mg = d.map("magnet");
      mg.allow_only({"index", "min", "max"});
      design::DesignProblem::MagnetPosition position;
      position.magnets = magnets;
      position.index = static_cast<std::size_t>(mg.has("index") ? mg.whole("index", 0, 65535) : 0);
      position.min = mg.vec3_quantity("min", units.len, range::kCoordinate);
      position.max = mg.vec3_quantity("max", units.len, range::kCoordinate);
      p.magnet = position;
    }
  } else if (d.has("magnet")) {
    d.fail("magnet", "the scene has no magnets to place");
  }
  // The design's own checks, at the line of the key they name (a target point's: the list's, which holds them all).
  if (const std::optional<design::DesignProblemIssue> issue = design::design_problem_issue(p)) {
    const std::string& key = issue->key;
    const std::string path = d.key_path(key);
    if (key.rfind("target.points", 0) == 0) {
      // A target point's (the list's line, which holds them all), or the insertion path's.
      const YamlMap holder = d.has("insertion") ? d.map("insertion") : d.map("target");
      const std::string list = d.has("insertion") ? "path" : "points";
      holder.fail_at(holder.node(list), holder.key_path(list + key.substr(std::string("target.points").size())),
                     issue->what);
    }
    const std::string top_key = key.substr(0, key.find_first_of(".["));
    if (d.has(top_key)) d.fail_at(d.node(top_key), path, issue->what);
    d.fail(top_key, issue->what);
  }
  return out;
}

bool is_design_scene(const std::filesystem::path& file) {
  try {
    const YAML::Node root = YAML::LoadFile(file.string());
    return root.IsMap() && root["design"];
  } catch (const YAML::Exception&) {
    return false;
  }
}

DesignScene load_design_scene(const std::filesystem::path& file) {
  return parse_design_scene(read_text_file(file.string(), "design file"), file.string());
}

const char* method_name(DesignMethod m) {
  switch (m) {
    case DesignMethod::least_squares:
      return "least-squares";
    case DesignMethod::lbfgsb:
      return "lbfgsb";
    case DesignMethod::bayesian:
      return "bayesian";
  }
  return "?";
}

design::DesignResult run_design(const DesignScene& scene, const std::function<void(int, double)>& progress) {
  design::DesignOptions options;
  options.max_iterations = scene.max_iterations;
  options.starts = scene.starts;
  options.seed = scene.seed;
  options.progress = progress;
  return design::multi_start_design(scene.problem, scene.method, options);
}

std::string designed_scene_yaml(const DesignScene& scene, const design::Design& design) {
  YAML::Node root = YAML::Clone(parse_yaml(scene.text, scene.file));
  root.remove("design");
  const int sections = scene.problem.spec.sections;
  const std::vector<std::pair<double, double>> spans = design::DesignObjective(scene.problem).section_spans();
  YAML::Node list(YAML::NodeType::Sequence);
  for (int s = 0; s < sections; ++s) {
    YAML::Node entry(YAML::NodeType::Map);
    entry["from"] = spans[static_cast<std::size_t>(s)].first / scene.length_unit;  // file units
    entry["to"] = spans[static_cast<std::size_t>(s)].second / scene.length_unit;
    entry["remanence"] = design.remanences[static_cast<std::size_t>(s)];
    YAML::Node dir(YAML::NodeType::Sequence);
    for (int i = 0; i < 3; ++i) dir.push_back(design.directions[static_cast<std::size_t>(s)][i]);
    dir.SetStyle(YAML::EmitterStyle::Flow);
    entry["direction"] = dir;
    entry.SetStyle(YAML::EmitterStyle::Flow);
    list.push_back(entry);
  }
  root["robot"]["magnetisation"] = list;
  if (!design.fields.empty()) {
    YAML::Node magnets(YAML::NodeType::Sequence);
    YAML::Node uniform(YAML::NodeType::Map);
    uniform["kind"] = "uniform";
    YAML::Node b(YAML::NodeType::Sequence);
    for (int i = 0; i < 3; ++i) b.push_back(design.fields.back()[i]);
    b.SetStyle(YAML::EmitterStyle::Flow);
    uniform["field"] = b;
    uniform.SetStyle(YAML::EmitterStyle::Flow);
    magnets.push_back(uniform);
    root["magnets"] = magnets;
  }
  if (design.magnet_position && scene.problem.magnet) {
    YAML::Node at(YAML::NodeType::Sequence);
    for (int i = 0; i < 3; ++i) at.push_back((*design.magnet_position)[i] / scene.length_unit);
    at.SetStyle(YAML::EmitterStyle::Flow);
    root["magnets"][scene.problem.magnet->index]["position"] = at;
  }
  YAML::Emitter emitter;
  emitter << root;
  return "# The rod designed by `magvine design " + scene.file + "` (run it with `magvine run`).\n" +
         std::string(emitter.c_str()) + "\n";
}

void write_design_outputs(const DesignScene& scene, const design::DesignResult& result,
                          const std::filesystem::path& dir) {
  const auto vec = [](const Vec3& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); };
  const design::DesignProblem& p = scene.problem;
  nlohmann::json j;
  j["method"] = method_name(scene.method);
  j["rms_m"] = result.rms;
  j["max_error_m"] = result.max_error;
  j["iterations"] = result.iterations;
  j["evaluations"] = result.evaluations;
  j["runtime_s"] = result.runtime_s;
  j["converged"] = result.converged;
  j["message"] = result.message;
  j["seed"] = scene.seed;
  const design::DesignObjective objective(p);
  nlohmann::json sections = nlohmann::json::array();
  const int count = p.spec.sections;
  const std::vector<std::pair<double, double>> spans = objective.section_spans();
  for (int s = 0; s < count; ++s) {
    const auto su = static_cast<std::size_t>(s);
    sections.push_back({{"from_m", spans[su].first},
                        {"to_m", spans[su].second},
                        {"direction", vec(result.design.directions[su])},
                        {"remanence_T", result.design.remanences[su]}});
  }
  j["sections"] = sections;
  if (p.insertion_steps > 0) {
    // Follow-the-leader: every step's field and how far its inserted part lies from the path.
    nlohmann::json fields = nlohmann::json::array();
    nlohmann::json rms = nlohmann::json::array();
    nlohmann::json worst = nlohmann::json::array();
    for (std::size_t c = 0; c < objective.configurations() && c < result.states.size(); ++c) {
      const std::vector<Vec3> on = objective.points_on(c, result.states[c]);
      const std::vector<std::size_t> targets = objective.targets_of(c);
      double sum = 0.0;
      double most = 0.0;
      for (std::size_t k = 0; k < on.size(); ++k) {
        const double e = (on[k] - p.spec.target[targets[k]]).norm();
        sum += e * e;
        most = std::max(most, e);
      }
      fields.push_back(vec(result.design.fields[c]));
      rms.push_back(std::sqrt(sum / static_cast<double>(on.size())));
      worst.push_back(most);
    }
    j["insertion"] = {
        {"steps", p.insertion_steps}, {"fields_T", fields}, {"step_rms_m", rms}, {"step_max_error_m", worst}};
  } else if (result.design.fields.size() == 1) {
    j["field_T"] = vec(result.design.fields.front());
  }
  if (result.design.magnet_position) j["magnet_position_m"] = vec(*result.design.magnet_position);
  nlohmann::json history = nlohmann::json::array();
  for (const design::DesignResult::Step& s : result.history) {
    history.push_back({{"iteration", s.iteration},
                       {"evaluation", s.evaluation},
                       {"rms_m", std::isfinite(s.rms) ? nlohmann::json(s.rms) : nlohmann::json(nullptr)},
                       {"best_rms_m", std::isfinite(s.best_rms) ? nlohmann::json(s.best_rms) : nlohmann::json(nullptr)},
                       {"time_s", s.time_s}});
  }
  j["history"] = history;
  create_output_directory(dir);
  std::ostringstream shape;
  shape.precision(12);
  shape << "s_m,x,y,z\n";
  const double h = p.model.length / p.model.edges;
  for (std::size_t i = 0; i < result.state.x.size(); ++i) {
    const Vec3& x = result.state.x[i];
    shape << static_cast<double>(i) * h << ',' << x.x() << ',' << x.y() << ',' << x.z() << '\n';
  }
  std::ostringstream target;
  target.precision(12);
  target << "s_m,target_x,target_y,target_z,x,y,z,error_m\n";
  const std::vector<Vec3> on = result.state.x.empty() ? std::vector<Vec3>() : objective.points_on(result.state);
  std::ostringstream insertion;
  insertion.precision(12);
  insertion << "step,inserted_m,s_m,x,y,z\n";
  for (std::size_t c = 0; c < result.states.size() && p.insertion_steps > 0; ++c) {
    const robot::RodState& st = result.states[c];
    const double inserted = p.model.length * static_cast<double>(c + 1) / p.insertion_steps;
    const double step_h = inserted / static_cast<double>(st.x.size() - 1);
    for (std::size_t i = 0; i < st.x.size(); ++i) {
      insertion << c + 1 << ',' << inserted << ',' << static_cast<double>(i) * step_h << ',' << st.x[i].x() << ','
                << st.x[i].y() << ',' << st.x[i].z() << '\n';
    }
  }
  for (std::size_t k = 0; k < on.size(); ++k) {
    const Vec3& t = p.spec.target[k];
    target << p.model.length * static_cast<double>(k) / static_cast<double>(on.size() - 1) << ',' << t.x() << ','
           << t.y() << ',' << t.z() << ',' << on[k].x() << ',' << on[k].y() << ',' << on[k].z() << ','
           << (on[k] - t).norm() << '\n';
  }
  write_file_atomically(dir / "shape.csv", shape.str());
  write_file_atomically(dir / "target.csv", target.str());
  if (p.insertion_steps > 0) write_file_atomically(dir / "insertion.csv", insertion.str());
  write_file_atomically(dir / "scene.yaml", designed_scene_yaml(scene, result.design));
  write_file_atomically(dir / "design.json", j.dump(2) + "\n");
}

}  // namespace magvine::scene
