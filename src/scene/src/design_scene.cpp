#include "magvine/scene/design_scene.hpp"

#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>

#include "anatomy_entry.hpp"
#include "free_space_internal.hpp"
#include "magvine/anatomy/airway_graph.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/text.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/field_function.hpp"
#include "magvine/scene/navigator.hpp"
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

/// The insertion path along an airway graph (design.insertion.path: {anatomy, branch, points, speed}): the planned
/// centreline to the branch's end from the point nearest the rod's base, sampled at `points` equally spaced points over
/// the rod's length. The base must sit on it: on the centreline, along its direction (20°).
std::vector<Vec3> airway_path(const YamlMap& path, const FileUnits& units, const robot::RodModel& model,
                              const std::filesystem::path& directory, AnatomyCache* cache,
                              DesignScene::AirwayPath& out) {
  path.allow_only({"anatomy", "branch", "points", "speed"});
  if (path.map("anatomy").has("breathing")) {
    path.map("anatomy").fail("breathing", "a design follows the airway as imaged; breathing belongs to experiments");
  }
  const std::shared_ptr<const SceneAnatomy> anatomy =
      detail::parse_anatomy_entry(path.map("anatomy"), units, directory, cache);
  if (!anatomy->graph) {
    path.fail("anatomy", "has no airway graph to follow: a generated phantom's, or graph: (extract | FILE.json)");
  }
  const anatomy::AirwayGraph& graph = *anatomy->graph;
  out.branch = path.text("branch");
  const std::optional<int> branch = anatomy::find_branch(graph, out.branch);
  if (!branch) path.fail("branch", "'" + out.branch + "' is not a branch of the anatomy's airway graph");
  const int count = path.has("points") ? static_cast<int>(path.whole("points", 2, 10000)) : 17;
  if (path.has("speed")) {
    out.insertion_speed = path.quantity("speed", Unit{units.len.si, units.len.name + "/s"}, range::kPositiveSpeed);
  }
  const std::vector<Vec3> line = planned_path(graph, *branch);
  double total = 0.0;
  for (std::size_t i = 1; i < line.size(); ++i) total += (line[i] - line[i - 1]).norm();
  const auto point_at = [&](double s) { return point_at_arc_length(line, s); };
  const double start = arc_length_of_nearest(line, model.base_position);
  const Vec3 on = point_at(start);
  const Vec3 tangent = (point_at(std::min(total, start + 1e-3)) - on).normalized();
  const auto mm = [&](const Vec3& v) {
    return printf_string("[%.4g, %.4g, %.4g]", v.x() / units.len.si, v.y() / units.len.si, v.z() / units.len.si);
  };
  // On the centreline to 1 % of the target spacing: the first target is the base, the next ones on the centreline.
  if ((model.base_position - on).norm() > 0.01 * model.length / (count - 1.0) ||
      tangent.dot(model.base_frame.col(0)) < std::cos(20.0 * kDegToRad)) {
    path.fail("branch", "the rod's base must sit on the path to " + out.branch +
                            " (on its centreline, along it within "
                            "20°): e.g. robot.base.position " +
                            mm(on) + ", direction " +
                            printf_string("[%.4g, %.4g, %.4g]", tangent.x(), tangent.y(), tangent.z()));
  }
  if (start + model.length > total * (1.0 + 1e-9)) {
    path.fail("branch", printf_string("the path from the base to the end of %s is %.4g %s, shorter than the rod "
                                      "(%.4g %s)",
                                      out.branch.c_str(), (total - start) / units.len.si, units.len.name.c_str(),
                                      model.length / units.len.si, units.len.name.c_str()));
  }
  std::vector<Vec3> targets;
  for (int k = 0; k < count; ++k) targets.push_back(point_at(start + model.length * k / (count - 1.0)));
  targets.front() = model.base_position;  // the first target is the clamped base itself
  out.end_radius = anatomy::nearest_centreline_point(graph, targets.back()).radius;
  // experiment.yaml is written elsewhere: its mesh and graph files by absolute paths.
  YAML::Node entry = YAML::Clone(path.node("anatomy"));
  for (const char* key : {"mesh", "graph"}) {
    if (!entry[key] || !entry[key].IsScalar() || entry[key].as<std::string>() == "extract") continue;
    const std::filesystem::path file = entry[key].as<std::string>();
    if (file.is_relative()) entry[key] = std::filesystem::absolute(directory / file).lexically_normal().string();
  }
  YAML::Emitter emitter;
  emitter << YAML::Flow << entry;
  out.anatomy_yaml = emitter.c_str();
  return targets;
}

}  // namespace

DesignScene parse_design_scene(const std::string& text, const std::string& file_label, AnatomyCache* cache) {
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
  d.allow_only({"sections", "remanence", "target", "field", "iterations", "method", "starts", "insertion", "magnet",
                "continuation"});
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
    if (ins.node("path").IsMap()) {  // along an airway graph
      DesignScene::AirwayPath airway;
      p.spec.target =
          airway_path(ins.map("path"), units, p.model, std::filesystem::path(file_label).parent_path(), cache, airway);
      out.airway = airway;
    } else {
      p.spec.target = target_points(ins, units.len, "path");
    }
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
  if (d.has("continuation")) out.field_stages = static_cast<int>(d.whole("continuation", 1, 100));
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
      mg.allow_only({"index", "min", "max", "orientation"});
      design::DesignProblem::MagnetPosition position;
      position.magnets = magnets;
      position.index = static_cast<std::size_t>(mg.has("index") ? mg.whole("index", 0, 65535) : 0);
      position.min = mg.vec3_quantity("min", units.len, range::kCoordinate);
      position.max = mg.vec3_quantity("max", units.len, range::kCoordinate);
      position.orientation = mg.has("orientation") && mg.flag("orientation");
      if (position.orientation && position.index < magnets.size()) {
        const YAML::Node entry = top.node("magnets")[position.index];
        if (!entry["axis"]) {
          mg.fail("orientation",
                  "the designed magnet's axis is its `axis:` key: give the magnet as polarisation + axis "
                  "(not a dipole's moment)");
        }
      }
      p.magnet = position;
    }
  } else if (d.has("magnet")) {
    d.fail("magnet", "the scene has no magnets to place");
  }
  if (out.field_stages > 1 && p.magnet) d.fail("continuation", "scales a fixed or free field, not a designed magnet's");
  if (out.field_stages > 1 && out.method == DesignMethod::bayesian) {
    d.fail("continuation", "is for the gradient methods (least-squares, lbfgsb)");
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
  return has_top_level_key(file, "design");
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
  options.field_stages = scene.field_stages;
  options.progress = progress;
  return design::multi_start_design(scene.problem, scene.method, options);
}

namespace {

/// [x, y, z] / unit, in flow style.
YAML::Node flow_vector(const Vec3& v, double unit) {
  YAML::Node out(YAML::NodeType::Sequence);
  for (int i = 0; i < 3; ++i) out.push_back(v[i] / unit);
  out.SetStyle(YAML::EmitterStyle::Flow);
  return out;
}

/// robot.magnetisation of a design: its sections, in file units.
YAML::Node sections_node(const DesignScene& scene, const design::Design& design) {
  const int sections = scene.problem.spec.sections;
  const std::vector<std::pair<double, double>> spans = design::DesignObjective(scene.problem).section_spans();
  YAML::Node list(YAML::NodeType::Sequence);
  for (int s = 0; s < sections; ++s) {
    YAML::Node entry(YAML::NodeType::Map);
    entry["from"] = spans[static_cast<std::size_t>(s)].first / scene.length_unit;  // file units
    entry["to"] = spans[static_cast<std::size_t>(s)].second / scene.length_unit;
    entry["remanence"] = design.remanences[static_cast<std::size_t>(s)];
    entry["direction"] = flow_vector(design.directions[static_cast<std::size_t>(s)], 1.0);
    entry.SetStyle(YAML::EmitterStyle::Flow);
    list.push_back(entry);
  }
  return list;
}

}  // namespace

std::string designed_scene_yaml(const DesignScene& scene, const design::Design& design) {
  YAML::Node root = YAML::Clone(parse_yaml(scene.text, scene.file));
  root.remove("design");
  root["robot"]["magnetisation"] = sections_node(scene, design);
  if (!design.fields.empty()) {
    YAML::Node magnets(YAML::NodeType::Sequence);
    YAML::Node uniform(YAML::NodeType::Map);
    uniform["kind"] = "uniform";
    uniform["field"] = flow_vector(design.fields.back(), 1.0);
    uniform.SetStyle(YAML::EmitterStyle::Flow);
    magnets.push_back(uniform);
    root["magnets"] = magnets;
  }
  if (design.magnet_position && scene.problem.magnet) {
    root["magnets"][scene.problem.magnet->index]["position"] = flow_vector(*design.magnet_position, scene.length_unit);
    if (design.magnet_axis)
      root["magnets"][scene.problem.magnet->index]["axis"] = flow_vector(*design.magnet_axis, 1.0);
  }
  YAML::Emitter emitter;
  emitter << root;
  return "# The rod designed by `magvine design " + scene.file + "` (run it with `magvine run`).\n" +
         std::string(emitter.c_str()) + "\n";
}

std::string designed_experiment_yaml(const DesignScene& scene, const design::Design& design) {
  if (!scene.airway) throw InputError(scene.file, 0, "design.insertion.path", "no airway path to run the design along");
  const DesignScene::AirwayPath& airway = *scene.airway;
  const design::DesignProblem& p = scene.problem;
  const double unit = scene.length_unit;
  const double step = p.model.length / p.insertion_steps;
  const YAML::Node file = parse_yaml(scene.text, scene.file);
  YAML::Node root(YAML::NodeType::Map);
  root["units"] = YAML::Clone(file["units"]);
  root["seed"] = scene.seed;
  root["anatomy"] = YAML::Load(airway.anatomy_yaml);
  YAML::Node robot = YAML::Clone(file["robot"]);
  robot.remove("nodes");  // the experiment's edge length (growth.edge_length: the radius)
  robot.remove("node_spacing");
  robot["magnetisation"] = sections_node(scene, design);
  robot["inserted"] = step / unit;
  robot["insertion_speed"] = airway.insertion_speed / unit;
  root["robot"] = robot;
  // Step c's field from the time its length is in (step 1 at t = 0), linear between: the experiment's push follows
  // the design's steps.
  YAML::Node field(YAML::NodeType::Sequence);
  for (int c = 0; c < p.insertion_steps; ++c) {
    YAML::Node key(YAML::NodeType::Sequence);
    key.push_back(c * step / airway.insertion_speed);
    key.push_back(flow_vector(design.fields[static_cast<std::size_t>(c)], 1.0));
    key.SetStyle(YAML::EmitterStyle::Flow);
    field.push_back(key);
  }
  root["control"]["field"] = field;
  const double inserted_by = (p.model.length - step) / airway.insertion_speed;
  root["simulation"]["duration"] = inserted_by + 1.0;  // then a second to settle
  root["simulation"]["dt"] = 0.02;
  if (file["simulation"] && file["simulation"]["gravity"]) {
    root["simulation"]["gravity"] = YAML::Clone(file["simulation"]["gravity"]);
  }
  root["target"]["position"] = flow_vector(p.spec.target.back(), unit);
  root["target"]["tolerance"] = airway.end_radius / unit;
  root["target"].SetStyle(YAML::EmitterStyle::Flow);
  root["simulation"].SetStyle(YAML::EmitterStyle::Flow);
  YAML::Emitter emitter;
  emitter << root;
  return "# The catheter designed by `magvine design " + scene.file + "` pushed along " + airway.branch +
         "'s path with the design's fields (run it with `magvine run`).\n" + std::string(emitter.c_str()) + "\n";
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
  if (result.design.magnet_axis) j["magnet_axis"] = vec(*result.design.magnet_axis);
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
  if (scene.airway) write_file_atomically(dir / "experiment.yaml", designed_experiment_yaml(scene, result.design));
  write_file_atomically(dir / "design.json", j.dump(2) + "\n");
}

}  // namespace magvine::scene
