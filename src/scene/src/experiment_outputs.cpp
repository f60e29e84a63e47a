#include <algorithm>
#include <array>
#include <cmath>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <system_error>

#include "experiment_internal.hpp"
#include "failed_run.hpp"
#include "magvine/anatomy/airway_graph.hpp"
#include "magvine/config.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/text.hpp"
#include "magvine/core/usage.hpp"
#include "magvine/scene/experiment.hpp"
#include "magvine/scene/navigator.hpp"
#include "magvine/scene/video_plugin.hpp"

namespace magvine::scene {

std::optional<double> film_overload(const ExperimentScene& scene, const ExperimentResult& result) {
  if (scene.growth.rod || scene.growth.catheter) return std::nullopt;
  std::optional<double> overload;
  for (const ExperimentSample& s : result.samples) {
    if (s.pressure > 0.0) overload = std::max(overload.value_or(0.0), s.max_pressure / s.pressure);
  }
  return overload;
}

namespace detail {

RunFigures figures_of(const ExperimentScene& scene, const ExperimentResult& result) {
  RunFigures f;
  const Vec3 tip = result.final_state.tip();
  f.everted_length = result.samples.empty() ? scene.vine.length : result.samples.back().length;
  f.film_overload = film_overload(scene, result);
  if (scene.target) f.final_error = (tip - *scene.target).norm();
  Vec3 last = result.samples.empty() ? tip : result.samples.front().tip;
  int last_branch = -1;
  for (const ExperimentSample& s : result.samples) {
    f.path += (s.tip - last).norm();
    last = s.tip;
    f.max_normal = std::max(f.max_normal, s.max_normal);
    f.max_line_load = std::max(f.max_line_load, s.max_line_load);
    f.max_shear = std::max(f.max_shear, s.total_shear);
    f.max_pressure = std::max(f.max_pressure, s.max_pressure);
    f.mean_normal += s.total_normal / static_cast<double>(result.samples.size());
    if (scene.anatomy->graph && s.branch >= 0 && s.branch != last_branch) {
      f.branches.push_back(scene.anatomy->graph->branches[static_cast<std::size_t>(s.branch)].name);
      f.generation =
          std::max(f.generation, scene.anatomy->graph->branches[static_cast<std::size_t>(s.branch)].generation);
      last_branch = s.branch;
    }
  }
  if (scene.anatomy->graph) {
    f.centreline = anatomy::nearest_centreline_point(*scene.anatomy->graph, tip).distance;
    double sum = 0.0;
    for (const ExperimentSample& s : result.samples) sum += s.centreline;
    f.mean_centreline = result.samples.empty() ? *f.centreline : sum / static_cast<double>(result.samples.size());
  }
  if (scene.navigator && scene.target) {
    // Arc length along the planned path of the tip's and the target's nearest points on it.
    f.progress = path_progress(target_path(scene), *scene.target, tip);
  }
  return f;
}

std::string failure_reason(const ExperimentResult& result, const RunFigures& figures) {
  std::ostringstream why;
  why.precision(3);
  // The last event that stopped the tip since the navigator last backed it out of a wrong turn (which dealt with
  // the stops before it).
  const RunEvent* last = nullptr;
  for (const RunEvent& e : result.events) {
    if (e.kind == EventKind::kRecover) {
      last = nullptr;
    } else if (e.kind != EventKind::kResume && e.kind != EventKind::kRetract) {
      last = &e;
    }
  }
  const std::string branch = figures.branches.empty() ? std::string() : ", last in branch " + figures.branches.back();
  if (!result.converged) {
    why << "the run failed: " << result.failure;
  } else if (last != nullptr) {
    why << event_name(last->kind) << " at " << last->time << " s, " << 1e3 * last->length
        << " mm everted: " << last->detail;
  } else {
    why << "the time ran out";
  }
  why << branch;
  if (figures.final_error) why << ", " << 1e3 * *figures.final_error << " mm from the target";
  if (result.recoveries > 0) {
    why << ", after " << result.recoveries << (result.recoveries == 1 ? " retraction" : " retractions")
        << " by the navigator";
  }
  return why.str();
}

}  // namespace detail

namespace {

/// Every file and folder a run of an experiment may write besides metrics.json (docs/cli.md, magvine run).
constexpr std::array<const char*, 18> kRunOutputs = {"tip_trajectory.csv", "shape.csv",       "shapes.csv",
                                                     "events.json",        "puncture.csv",    "guidance.csv",
                                                     "guidance",           "graph.json",      "magnet_trajectory.csv",
                                                     "arms.csv",           "tip.mp4",         "tip.avi",
                                                     "overview.mp4",       "overview.avi",    "tip_frames",
                                                     "tip_depth",          "overview_frames", "overview_depth"};

}  // namespace

void write_experiment_outputs(const ExperimentScene& scene, const ExperimentResult& result,
                              const std::filesystem::path& dir) {
  const auto vec = [](const Vec3& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); };
  nlohmann::json j;
  const Vec3 tip = result.final_state.tip();
  std::string puncture_csv;  // a biopsy's puncture.csv
  j["scene"] = scene.file;
  j["anatomy"] = scene.anatomy->label;
  j["seed"] = scene.seed;
  j["success"] = result.success;
  j["time_to_target_s"] = result.time_to_target >= 0.0 ? nlohmann::json(result.time_to_target) : nlohmann::json();
  const detail::RunFigures f = detail::figures_of(scene, result);
  j["final_tip_error_m"] = f.final_error ? nlohmann::json(*f.final_error) : nlohmann::json();
  j["tip_position_m"] = vec(tip);
  j["everted_length_m"] = f.everted_length;
  j["tip_path_length_m"] = f.path;
  j["branches_reached"] = f.branches;
  const auto optional = [](const std::optional<double>& v) { return v ? nlohmann::json(*v) : nlohmann::json(); };
  j["generation_reached"] = f.generation >= 0 ? nlohmann::json(f.generation) : nlohmann::json();
  j["tip_to_centreline_m"] = optional(f.centreline);
  j["mean_tip_to_centreline_m"] = optional(f.mean_centreline);
  j["path_progress"] = optional(f.progress);
  j["max_wall_normal_N"] = f.max_normal;
  j["max_wall_line_load_N_per_mm"] = 1e-3 * f.max_line_load;
  j["mean_wall_normal_N"] = f.mean_normal;
  j["max_wall_shear_N"] = f.max_shear;
  j["max_contact_pressure_Pa"] = f.max_pressure;
  j["max_contact_pressure_over_inflation"] = optional(f.film_overload);
  double imbalance = 0.0;
  for (const ExperimentSample& s : result.samples) imbalance = std::max(imbalance, s.imbalance);
  j["max_force_imbalance"] = imbalance;
  if (scene.biopsy) {
    const Vec3& nodule = scene.biopsy->nodule;
    const anatomy::BiopsyPlan& plan = scene.biopsy->plan;
    j["biopsy"] = {
        {"nodule_m", vec(nodule)},
        {"nodule_radius_m", scene.biopsy->radius},
        {"stop_m", vec(plan.start)},
        {"stop_branch", scene.anatomy->graph->branches[static_cast<std::size_t>(plan.branch)].name},
        {"wall_m", vec(plan.wall)},
        {"needle_direction", vec(plan.direction)},
        {"needle_m", plan.needle},
        {"needle_angle_deg", plan.angle / kDegToRad},
        {"stop_lumen_diameter_m", 2.0 * plan.lumen_radius},
        {"straight_miss_m", plan.straight_miss},
        {"best_straight_miss_m", plan.best_straight_miss},
        {"best_straight_branch",
         plan.best_straight_branch < 0
             ? nlohmann::json()
             : nlohmann::json(
                   scene.anatomy->graph->branches[static_cast<std::size_t>(plan.best_straight_branch)].name)},
        {"tip_to_stop_m", (tip - plan.start).norm()}};
    if (scene.biopsy->given_stop) {  // a given stop: how far its node lies from it, and whether the needle crosses
      j["biopsy"]["given_stop_m"] = vec(*scene.biopsy->given_stop);
      j["biopsy"]["given_stop_distance_m"] = plan.given_distance;
      j["biopsy"]["needle_crosses_airway"] = plan.crosses_airway;
    }
    // The puncture (robot/needle.hpp): null fields when the vine did not reach its stop.
    nlohmann::json& b = j["biopsy"];
    const std::optional<robot::PunctureReport>& p = result.puncture;
    b["needle_pushed"] = p.has_value();
    b["punctured"] = p && p->punctured;
    b["success"] = p && p->success;
    b["why"] = p                ? nlohmann::json(p->why)
               : result.success ? nlohmann::json("the run failed before the puncture: " + result.failure)
                                : nlohmann::json("the vine did not reach its stop");
    b["aim_angle_deg"] = p ? nlohmann::json(result.aim_angle / kDegToRad) : nlohmann::json();
    b["held"] = p ? nlohmann::json(p->held) : nlohmann::json();
    b["slide_back_m"] = p ? nlohmann::json(p->slide) : nlohmann::json();
    b["wall_distance_m"] = p && p->wall_distance >= 0.0 ? nlohmann::json(p->wall_distance) : nlohmann::json();
    b["needle_tip_m"] = p ? vec(p->needle_tip) : nlohmann::json();
    b["needle_to_nodule_m"] = p ? nlohmann::json(p->to_nodule) : nlohmann::json();
    b["max_reaction_N"] = p ? nlohmann::json(p->max_force) : nlohmann::json();
    b["held_reaction_N"] = p ? nlohmann::json(p->held_force) : nlohmann::json();
    b["wall_share"] = p ? nlohmann::json(p->wall_share) : nlohmann::json();
    b["max_unsupported"] = p ? nlohmann::json(p->max_unsupported) : nlohmann::json();
    b["max_wall_normal_N"] = p ? nlohmann::json(p->max_normal) : nlohmann::json();
    b["max_moment_over_collapse"] = p ? nlohmann::json(p->max_moment) : nlohmann::json();
    if (p) {
      std::ostringstream rows;
      rows.precision(9);
      rows << "time_s,protrusion_mm,depth_mm,force_N,tip_x_mm,tip_y_mm,tip_z_mm,needle_x_mm,needle_y_mm,"
              "needle_z_mm,slide_mm,wall_x_N,wall_y_N,wall_z_N,clamp_x_N,clamp_y_N,clamp_z_N,max_normal_N,"
              "total_normal_N,imbalance,unsupported,moment_over_collapse\n";
      for (const robot::PunctureStep& st : p->steps) {
        rows << st.time << ',' << 1e3 * st.protrusion << ',' << 1e3 * st.depth << ',' << st.force;
        for (const Vec3* v : {&st.tip, &st.needle_tip}) {
          for (int c = 0; c < 3; ++c) rows << ',' << 1e3 * (*v)[c];
        }
        rows << ',' << 1e3 * st.slide;
        for (const Vec3* v : {&st.wall, &st.clamp}) {
          for (int c = 0; c < 3; ++c) rows << ',' << (*v)[c];
        }
        rows << ',' << st.max_normal << ',' << st.total_normal << ',' << st.imbalance << ',' << st.unsupported << ','
             << st.moment << '\n';
      }
      puncture_csv = rows.str();
    }
  }
  int stalls = 0;
  int workspace = 0;
  int blocked = 0;
  nlohmann::json events = nlohmann::json::array();
  for (const RunEvent& e : result.events) {
    stalls += e.kind == EventKind::kStall || e.kind == EventKind::kSqueeze;
    blocked += e.kind == EventKind::kBlocked;
    workspace += e.kind == EventKind::kWorkspace;
    events.push_back(
        {{"time_s", e.time}, {"length_m", e.length}, {"kind", std::string(event_name(e.kind))}, {"detail", e.detail}});
  }
  j["stalls"] = stalls;
  j["blocked"] = blocked;
  j["retractions"] = result.recoveries;  // the navigator's, out of wrong turns (control.navigator.recover)
  std::string guidance_csv;              // a camera-guided navigator's guidance.csv
  if (scene.navigator && scene.navigator->camera) {
    // Camera guidance: what the navigator saw and chose at each placement, with the truth beside it.
    int blind = 0;
    int several = 0;
    double error = 0.0;
    double max_error = 0.0;
    double drift = 0.0;
    std::ostringstream rows;
    rows.precision(10);
    rows << "t_s,everted_length_m,estimated_arc_m,true_arc_m,lumens,chosen,junction,line_x,line_y,line_z,"
            "line_error_deg\n";
    for (const GuidanceSample& g : result.guidance) {
      blind += g.lumens == 0;
      several += g.lumens > 1;
      error += g.line_error;
      max_error = std::max(max_error, g.line_error);
      drift = std::max(drift, std::abs(g.arc - g.true_arc));
      rows << g.time << ',' << g.length << ',' << g.arc << ',' << g.true_arc << ',' << g.lumens << ',' << g.chosen
           << ',' << g.junction << ',' << g.line.x() << ',' << g.line.y() << ',' << g.line.z() << ','
           << g.line_error / kDegToRad << '\n';
    }
    const double n = std::max<double>(1.0, static_cast<double>(result.guidance.size()));
    j["guidance"] = {{"mode", "camera"},
                     {"placements", result.guidance.size()},
                     {"placements_without_lumen", blind},
                     {"placements_with_several_lumens", several},
                     {"mean_line_error_deg", error / n / kDegToRad},
                     {"max_line_error_deg", max_error / kDegToRad},
                     {"max_arc_estimate_error_m", drift}};
    guidance_csv = rows.str();
  }
  j["events"] = static_cast<int>(result.events.size());
  double travel = 0.0;
  std::vector<std::optional<Vec3>> previous(scene.magnets ? scene.magnets->size() : 0);
  for (const MagnetSample& m : result.magnet_samples) {
    auto& p = previous[static_cast<std::size_t>(m.magnet)];
    if (p) travel += (m.position - *p).norm();
    p = m.position;
  }
  j["magnet_travel_m"] = travel;
  if (result.platform) {
    // The arms (docs/platform.md): the least magnet–skin gap, steps with a collision or a limit exceeded, the
    // largest holding torque as a fraction of its joint's limit, the joints' travel and the arms' lag.
    const platform::PlatformFigures& arms = *result.platform;
    j["manipulators"] = scene.platform->arms.size();
    j["min_magnet_skin_clearance_m"] =
        std::isfinite(arms.min_skin_clearance) ? nlohmann::json(arms.min_skin_clearance) : nlohmann::json();
    j["arm_collisions"] = arms.collisions;
    j["joint_limit_violations"] = arms.limit_violations;
    j["max_joint_torque_fraction"] = arms.max_torque_fraction;
    j["arm_path_length_rad"] = arms.path_length;
    j["max_arm_tracking_error_m"] = arms.max_tracking_error;
    j["workspace_events"] = workspace;
    j["platform_runtime_s"] = arms.compute_s;
  }
  const double simulated = result.samples.empty() ? 0.0 : result.samples.back().time;
  j["simulated_s"] = simulated;
  j["runtime_s"] = result.runtime_s;
  j["real_time_factor"] = result.runtime_s > 0.0 ? nlohmann::json(simulated / result.runtime_s) : nlohmann::json();
  j["converged"] = result.converged;
  j["failed_steps"] = result.failed_steps;
  j["failure"] = result.failure;
  j["failed"] = !result.converged;

  if (!result.converged) {
    // A failed run (its last step has no equilibrium) leaves its metrics.json only (docs/cli.md: failed runs).
    if (!scene.videos.empty()) j["videos"] = nlohmann::json::array();
    detail::write_failed_run(dir, j, kRunOutputs);
    return;
  }
  std::ostringstream tips;
  tips.precision(10);
  // With breathing, a last column: the fraction of inspiration (1: the rest shape).
  tips << "t_s,x_m,y_m,z_m,length_m,pressure_Pa,max_normal_N,max_line_load_N_per_mm,mean_normal_N,"
          "total_normal_N,total_shear_N,branch"
       << (scene.breathing ? ",inspiration\n" : "\n");
  for (const ExperimentSample& s : result.samples) {
    tips << s.time << ',' << s.tip.x() << ',' << s.tip.y() << ',' << s.tip.z() << ',' << s.length << ',' << s.pressure
         << ',' << s.max_normal << ',' << 1e-3 * s.max_line_load << ',' << s.mean_normal << ',' << s.total_normal
         << ',' << s.total_shear << ','
         << (s.branch >= 0 ? scene.anatomy->graph->branches[static_cast<std::size_t>(s.branch)].name : std::string());
    if (scene.breathing) tips << ',' << s.inspiration;
    tips << '\n';
  }
  std::ostringstream shape;
  shape.precision(10);
  // Per node: the position and the wall's forces on the tissue there (0 where a run's forces have fewer nodes).
  const auto node_row = [](std::ostream& o, const Vec3& x, const std::vector<double>& normal,
                           const std::vector<double>& shear, const std::vector<Vec3>& normal_vector,
                           const std::vector<Vec3>& shear_vector, const std::vector<double>& pressure, std::size_t i) {
    const Vec3 n = i < normal_vector.size() ? normal_vector[i] : Vec3::Zero();
    const Vec3 s = i < shear_vector.size() ? shear_vector[i] : Vec3::Zero();
    o << x.x() << ',' << x.y() << ',' << x.z() << ',' << (i < normal.size() ? normal[i] : 0.0) << ','
      << (i < shear.size() ? shear[i] : 0.0) << ',' << n.x() << ',' << n.y() << ',' << n.z() << ',' << s.x() << ','
      << s.y() << ',' << s.z() << ',' << (i < pressure.size() ? pressure[i] : 0.0) << '\n';
  };
  const char* node_columns =
      "x_m,y_m,z_m,normal_N,shear_N,normal_x_N,normal_y_N,normal_z_N,shear_x_N,shear_y_N,shear_z_N,pressure_Pa\n";
  shape << node_columns;
  for (std::size_t i = 0; i < result.final_state.x.size(); ++i) {
    node_row(shape, result.final_state.x[i], result.final_forces.normal, result.final_forces.shear,
             result.final_forces.normal_vector, result.final_forces.shear_vector, result.final_forces.pressure, i);
  }

  create_output_directory(dir);
  // What an earlier run left in this folder goes: every file here is this run's.
  for (const char* name : kRunOutputs) {
    std::error_code ec;
    std::filesystem::remove_all(dir / name, ec);
  }
  write_file_atomically(dir / "tip_trajectory.csv", tips.str());
  write_file_atomically(dir / "shape.csv", shape.str());
  if (scene.shape_interval > 0.0) {
    std::ostringstream shapes;
    shapes.precision(10);
    shapes << "t_s,node," << node_columns;
    for (const ShapeSample& sample : result.shapes) {
      for (std::size_t i = 0; i < sample.nodes.size(); ++i) {
        shapes << sample.time << ',' << i << ',';
        node_row(shapes, sample.nodes[i], sample.normal, sample.shear, sample.normal_vector, sample.shear_vector,
                 sample.pressure, i);
      }
    }
    write_file_atomically(dir / "shapes.csv", shapes.str());
  }
  write_file_atomically(dir / "events.json", events.dump(2) + "\n");
  if (!puncture_csv.empty()) write_file_atomically(dir / "puncture.csv", puncture_csv);
  if (!guidance_csv.empty()) {
    write_file_atomically(dir / "guidance.csv", guidance_csv);
    // The frames it chose between lumens in (Camera::frames), named by their time in ms.
    bool any = false;
    for (const GuidanceSample& g : result.guidance) {
      if (g.picture.empty()) continue;
      if (!any) create_output_directory(dir / "guidance");
      any = true;
      write_file_atomically(dir / "guidance" / printf_string("%06ld.png", std::lround(1e3 * g.time)), g.picture);
    }
  }
  if (scene.anatomy->graph) anatomy::write_graph(dir / "graph.json", *scene.anatomy->graph);
  if (scene.magnets) {
    std::ostringstream mags;
    mags.precision(10);
    mags << "t_s,magnet,x_m,y_m,z_m,axis_x,axis_y,axis_z\n";
    for (const MagnetSample& m : result.magnet_samples) {
      mags << m.time << ',' << m.magnet << ',' << m.position.x() << ',' << m.position.y() << ',' << m.position.z()
           << ',' << m.axis.x() << ',' << m.axis.y() << ',' << m.axis.z() << '\n';
    }
    write_file_atomically(dir / "magnet_trajectory.csv", mags.str());
  }
  if (result.platform) {
    std::ostringstream rows;
    rows.precision(10);
    rows << "t_s,arm";
    for (int i = 1; i <= platform::kArmJoints; ++i) rows << ",q" << i << "_deg";
    for (int i = 1; i <= platform::kArmJoints; ++i) rows << ",tau" << i << "_Nm";
    rows << ",magnet_x_m,magnet_y_m,magnet_z_m\n";
    for (const platform::ArmSample& a : result.arm_samples) {
      rows << a.time << ',' << a.arm;
      for (int i = 0; i < platform::kArmJoints; ++i) rows << ',' << a.q[i] / kDegToRad;
      for (int i = 0; i < platform::kArmJoints; ++i) rows << ',' << a.tau[i];
      rows << ',' << a.magnet.x() << ',' << a.magnet.y() << ',' << a.magnet.z() << '\n';
    }
    write_file_atomically(dir / "arms.csv", rows.str());
  }
  if (!scene.videos.empty() && video_plugin_built()) {
    VideoInputs in;
    if (scene.navigator) {
      in.planned_path = planned_path(*scene.anatomy->graph, scene.navigator->target_branch);
    }
    for (std::size_t i = 0; scene.magnets && i < scene.magnets->size(); ++i) {
      const std::optional<detail::MagnetBody> body = detail::magnet_body(*scene.magnets, i);
      in.magnet_diameters.push_back(body ? 2.0 * body->radius : 0.0);
      in.magnet_lengths.push_back(body ? 2.0 * body->half_length : 0.0);
    }
    const nlohmann::json written =
        nlohmann::json::parse(video_plugin("outputs.video").experiment_videos(scene, result, in, dir));
    for (int k = 0; k < written.at("renderers").get<int>(); ++k) usage::note(usage::Component::kRenderer);
    j["videos"] = written.at("videos");
  } else if (!scene.videos.empty()) {
    j["videos"] = nlohmann::json::array();
    j["videos_skipped"] = "this magvine was built without the render module (cmake -DMAGVINE_WITH_RENDER=ON)";
  }
  write_file_atomically(dir / "metrics.json", j.dump(2) + "\n");
}

}  // namespace magvine::scene
