// Growth experiments (scene/experiment.hpp): the bundled demo scene steers the fluid vine into the chosen daughter
// of the Y phantom and reaches its target, while the same run without the magnet does not; runs are deterministic;
// schedules interpolate; bad scenes name the file and key.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <numeric>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "magvine/anatomy/airway_graph.hpp"
#include "magvine/anatomy/breathing.hpp"
#include "magvine/anatomy/collision_world.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/phantom.hpp"
#include "magvine/config.hpp"
#include "magvine/core/error.hpp"
#include "magvine/magnetics/cylinder.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/scene/calibrate_scene.hpp"
#include "magvine/scene/design_scene.hpp"
#include "magvine/scene/experiment.hpp"
#include "magvine/scene/free_space.hpp"
#include "magvine/scene/navigator.hpp"
#include "magvine/scene/trials.hpp"
#include "support/text_file.hpp"

namespace magvine::scene {
namespace {

const std::filesystem::path kDemo =
    std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes/y_bifurcation_fluid_vine.yaml";

using test::text_of;

std::string demo_text() {
  return text_of(kDemo);
}

/// The InputError a scene text (as "bad.yaml") gives when it is loaded, or "no error"; with `run`, when it is run.
std::string error_of(const std::string& scene, bool run = false) {
  try {
    const ExperimentScene parsed = parse_experiment_scene(scene, "bad.yaml", MAGVINE_SOURCE_DIR);
    if (run) (void)run_experiment(parsed);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

// Experiment stepped by a driver (the Python API's Simulation; docs/python.md): a bad request changes nothing; the
// driver's pressure below the yield holds the vine (the growth law: the tip advances only while P > Y, 20 kPa here)
// and its magnet pose holds; above the film's burst pressure the vine bursts and its clock runs on; its own half
// steps run to the duration.
TEST(Experiment, ADriversRequestsDoWhatTheySayAndABadOneChangesNothing) {
  const ExperimentScene scene = load_experiment_scene(kDemo);
  Experiment e(scene);
  ASSERT_TRUE(e.step());
  const double t = e.time();
  const Vec3 tip = e.state().body.tip();
  StepRequest bad;
  bad.dt = -0.01;
  EXPECT_THROW(e.step(bad), InputError);
  bad = {};
  bad.magnets.push_back({3, Vec3::Zero(), Vec3::UnitZ()});
  EXPECT_THROW(e.step(bad), InputError);
  EXPECT_EQ(e.time(), t);
  EXPECT_EQ(e.state().body.tip(), tip);
  EXPECT_FALSE(e.ended());
  StepRequest hold;
  hold.pressure = 15e3;
  hold.magnets.push_back({0, Vec3(0.08, 0.12, 0.01), Vec3(0, -2, 0)});
  ASSERT_TRUE(e.step(hold));
  const double length = e.everted_length();
  for (int k = 0; k < 20; ++k) ASSERT_TRUE(e.step());
  EXPECT_NEAR(e.everted_length(), length, 1e-4);  // held below yield: within 0.1 mm over 0.4 s
  EXPECT_EQ(e.pressure(), 15e3);
  EXPECT_TRUE(e.magnet_poses()[0].position.isApprox(Vec3(0.08, 0.12, 0.01), 1e-15));
  EXPECT_TRUE(e.magnet_poses()[0].rotation.col(2).isApprox(Vec3(0, -1, 0), 1e-15));
  StepRequest burst;
  burst.pressure = 60e3;  // hoop stress P·R/t = 60 kPa · 2.5 mm / 38 µm = 3.9 MPa > the film's 2.9 MPa
  ASSERT_TRUE(e.step(burst));
  EXPECT_TRUE(e.state().burst);
  const double burst_at = e.time();
  for (int k = 0; k < 3; ++k) ASSERT_TRUE(e.step());
  EXPECT_NEAR(e.time(), burst_at + 3 * scene.dt, 1e-12);

  Experiment halves(scene);
  StepRequest half;
  half.dt = 0.5 * scene.dt;
  long steps = 0;
  while (!halves.done() && steps < 100) {
    ASSERT_TRUE(halves.step(half));
    ++steps;
  }
  EXPECT_EQ(steps, 100);  // 1 s of the 8 s in half steps: not done by the step count of `magvine run`
  EXPECT_FALSE(halves.done());
  const ExperimentResult r = halves.finish();
  EXPECT_TRUE(halves.ended());
  EXPECT_THROW(halves.step(), std::logic_error);
  EXPECT_NEAR(r.samples.back().time, 100 * half.dt.value(), 1e-12);
}

TEST(Experiment, DemoSceneSteersIntoTheDaughterAndReachesTheTargetButNotWithoutTheMagnet) {
  // The Y phantom's daughters leave the junction at ±35°; the fluid vine on the table grows along the parent's
  // axis. With the EPM swept in beside daughter 0-0 it turns into that daughter and reaches the target near its
  // end; with the magnet left 250 mm away (the same scene, no keyframes) it does not get there (barrier contact,
  // 2026-12-02: blocked on the carina's ridge, tip at (72.2, 0.1) mm, the wall carrying 0.407 N of the growth force
  // 0.408 N); with the sweep mirrored to the −y side (and the target) it turns into 0-1.
  const ExperimentScene scene = load_experiment_scene(kDemo);
  const ExperimentResult steered = run_experiment(scene);
  ASSERT_TRUE(steered.converged) << steered.failure;
  ExperimentScene far = scene;
  far.magnet_keyframes.assign(far.magnet_keyframes.size(), {});
  const ExperimentResult unsteered = run_experiment(far);
  ExperimentScene mirrored = scene;
  for (MagnetKeyframe& k : mirrored.magnet_keyframes[0]) {
    k.position.y() = -k.position.y();
    k.axis.y() = -k.axis.y();
  }
  mirrored.target->y() = -mirrored.target->y();
  const ExperimentResult other = run_experiment(mirrored);
  const auto describe = [](const char* what, const ExperimentResult& r) {
    const Eigen::Vector3d tip = 1e3 * r.final_state.tip();
    std::printf("  %s: tip (%.1f, %.1f, %.1f) mm, %.1f mm everted, target %s", what, tip.x(), tip.y(), tip.z(),
                1e3 * r.samples.back().length, r.success ? "reached" : "not reached");
    if (r.success) std::printf(" at %.2f s", r.time_to_target);
    for (const auto& e : r.events) std::printf("; %s: %s", std::string(event_name(e.kind)).c_str(), e.detail.c_str());
    std::printf("\n");
  };
  describe("EPM swept in beside 0-0", steered);
  describe("EPM left away", unsteered);
  describe("EPM swept in beside 0-1", other);
  EXPECT_TRUE(steered.success);
  EXPECT_EQ(steered.samples.back().branch, 1);  // branch 1 = "0-0", the +y daughter
  EXPECT_GT(steered.final_state.tip().y(), 20e-3);
  EXPECT_FALSE(unsteered.success);
  EXPECT_LT(unsteered.final_state.tip().y(), 10e-3);  // not in 0-0
  EXPECT_TRUE(other.success);
  EXPECT_EQ(other.samples.back().branch, 2);  // "0-1"
}

/// The result of the scene `file` with the navigator's target replaced.
ExperimentResult navigate_to(const std::filesystem::path& file, const std::string& from, const std::string& to) {
  std::ifstream in(file);
  const std::string text(std::istreambuf_iterator<char>(in), {});
  const ExperimentScene scene = parse_experiment_scene(replaced(text, from, to), file.string(), file.parent_path());
  const ExperimentResult r = run_experiment(scene);
  std::string branches;
  int last = -1;
  for (const ExperimentSample& s : r.samples) {
    if (s.branch == last) continue;
    last = s.branch;
    branches += (branches.empty() ? "" : " ") + scene.anatomy->graph->branches[static_cast<std::size_t>(s.branch)].name;
  }
  // The workspace: no vertex of the airway wall ever inside the EPM (the Ø101.6 × 101.6 mm cylinder about its axis).
  // Reported: the least clearance, the largest of the axial and radial gaps outside the cylinder, over the vertices.
  double clearance = std::numeric_limits<double>::infinity();
  for (const MagnetSample& m : r.magnet_samples) {
    for (const Vec3& v : scene.anatomy->mesh().vertices) {
      const Vec3 d = v - m.position;
      const double a = std::abs(d.dot(m.axis));
      const double rho = (d - d.dot(m.axis) * m.axis).norm();
      clearance = std::min(clearance, std::max(a - 50.8e-3, rho - 50.8e-3));
    }
  }
  std::printf("  navigator to %s: %s (%s), %.0f mm everted, %.2f s of computing, EPM at least %.1f mm clear\n",
              to.c_str(), r.success ? "reached" : "NOT reached", branches.c_str(), 1e3 * r.samples.back().length,
              r.runtime_s, 1e3 * clearance);
  EXPECT_GT(clearance, 0.0);
  return r;
}

// control.navigator.target: {nodule: ...}: a nodule 15 mm beyond the blind end of leaf 0-0-1-0 of the generated tree
// (straight ahead of its last centreline node, past the end cap). The planned stop is at the leaf's end, whose needle
// runs 15 mm through tissue (the cap lies a radius beyond the node: the needle from the node to the nodule leaves the
// lumen at the cap); the navigator's target is the stop. A nodule inside the lumen and a needle too short are refused
// with the key and the reason.
TEST(Experiment, TheBaseAtTheAirwayEntryAndANoduleFromAPlanningProblemFile) {
  // base: {entry: 12} against the bundled scene's hand-set base (12 mm down the generated tree's trachea, along −z);
  // a nodule from a file of three numbers in mm (Med-MPD's target.txt) against the same point inline.
  const std::filesystem::path file =
      std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes/bronchial_tree_navigator.yaml";
  const std::string text = text_of(file);
  const ExperimentScene plain = load_experiment_scene(file);
  // The scene's base lies on the trachea's axis, some way down from the root's first node.
  const anatomy::AirwayGraph& g = *plain.anatomy->graph;
  const Vec3 first = g.nodes[g.branches.front().nodes.front()].position;
  const double inset = 1e3 * (plain.base_position - first).dot(plain.base_frame.col(0));
  std::printf("  the root's first node at (%g, %g, %g) mm: entry %g mm\n", 1e3 * first.x(), 1e3 * first.y(),
              1e3 * first.z(), inset);
  std::ostringstream base;
  base.precision(17);
  base << "base: {entry: " << inset << "}";
  const std::string at_entry =
      replaced(text, "base: {position: [0, 0, -12], direction: [0, 0, -1], normal: [1, 0, 0]}", base.str());
  const ExperimentScene entry = parse_experiment_scene(at_entry, file.string(), file.parent_path());
  EXPECT_LT((entry.base_position - plain.base_position).norm(), 1e-9);
  EXPECT_LT((entry.base_frame.col(0) - plain.base_frame.col(0)).norm(), 1e-9);
  EXPECT_LT(std::abs(entry.base_frame.col(0).dot(entry.base_frame.col(1))), 1e-12);
  EXPECT_THROW((void)parse_experiment_scene(replaced(text,
                                                     "base: {position: [0, 0, -12], direction: [0, 0, -1], "
                                                     "normal: [1, 0, 0]}",
                                                     "base: {entry: 500}"),
                                            file.string(), file.parent_path()),
               InputError);

  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "magvine_test_nodule_file";
  std::filesystem::create_directories(dir);
  // 15 mm past the end of leaf 0-0-1-0, in the tissue.
  const anatomy::AirwayBranch& leaf = g.branches[static_cast<std::size_t>(*anatomy::find_branch(g, "0-0-1-0"))];
  const Vec3 end = g.nodes[leaf.nodes.back()].position;
  const Vec3 along = (end - g.nodes[leaf.nodes[leaf.nodes.size() - 2]].position).normalized();
  const Vec3 point = 1e3 * (end + (g.nodes[leaf.nodes.back()].radius + 0.015) * along);
  std::ostringstream numbers;
  numbers.precision(17);
  numbers << point.x() << "\n" << point.y() << "\n" << point.z() << "\n";
  {
    std::ofstream(dir / "target.txt") << numbers.str();
    std::ofstream(dir / "short.txt") << "20 -5\n";
  }
  const auto with_nodule = [&](const std::string& nodule) {
    return parse_experiment_scene(replaced(text, "target: \"0-0-1\"", "target: {nodule: " + nodule + "}"),
                                  (dir / "scene.yaml").string(), dir);
  };
  const ExperimentScene from_file = with_nodule("target.txt");
  std::ostringstream inline_text;
  inline_text.precision(17);
  inline_text << "[" << point.x() << ", " << point.y() << ", " << point.z() << "]";
  const ExperimentScene inline_point = with_nodule(inline_text.str());
  ASSERT_TRUE(from_file.biopsy && inline_point.biopsy);
  EXPECT_EQ(from_file.biopsy->nodule, inline_point.biopsy->nodule);
  try {
    (void)with_nodule("short.txt");
    ADD_FAILURE() << "a two-number nodule file was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("short.txt"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

TEST(Experiment, NavigatorTakesANoduleAndStopsWhereTheNeedleReachesIt) {
  const std::filesystem::path file =
      std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes/bronchial_tree_navigator.yaml";
  const std::string text = text_of(file);
  const ExperimentScene plain = load_experiment_scene(file);
  const anatomy::AirwayGraph& g = *plain.anatomy->graph;
  const auto leaf = anatomy::find_branch(g, "0-0-1-0");
  ASSERT_TRUE(leaf);
  const anatomy::AirwayBranch& b = g.branches[static_cast<std::size_t>(*leaf)];
  const Vec3 end = g.nodes[b.nodes.back()].position;
  const Vec3 along = (end - g.nodes[b.nodes[b.nodes.size() - 2]].position).normalized();
  const double r = g.nodes[b.nodes.back()].radius;
  const Vec3 nodule = end + (r + 0.015) * along;
  std::ostringstream target;
  target.precision(17);
  target << "target: {nodule: [" << 1e3 * nodule.x() << ", " << 1e3 * nodule.y() << ", " << 1e3 * nodule.z() << "]}";
  const std::string with = replaced(text, "target: \"0-0-1\"", target.str());
  const ExperimentScene sc = parse_experiment_scene(with, file.string(), file.parent_path());
  ASSERT_TRUE(sc.biopsy.has_value());
  const anatomy::BiopsyPlan& plan = sc.biopsy->plan;
  EXPECT_EQ(g.branches[static_cast<std::size_t>(plan.branch)].name, "0-0-1-0");
  // A node at the leaf's end: its needle within the planner's 1 mm of the shortest (15 mm from the last node; the
  // cap is meshed on a 0.4 mm-class grid), the straightest of those.
  EXPECT_NE(std::find(b.nodes.end() - 3, b.nodes.end(), plan.node), b.nodes.end());
  EXPECT_GE(plan.needle, 0.015 - 0.5e-3);
  EXPECT_LE(plan.needle, 0.015 + 1.5e-3);
  EXPECT_LT(plan.angle, 5.0 * kDegToRad);
  EXPECT_EQ(sc.navigator->target, "0-0-1-0");
  EXPECT_EQ(*sc.target, plan.start);

  // The run: the vine reaches the stop, the magnet aims the tip, the needle is pushed (robot/needle.hpp). Every
  // increment's reaction is the tissue law's force at its depth, and the body balances it with everything else to
  // 2 % of the reaction (the issue's statics bound; the solve's own tolerance is far below). The outcome is
  // reported, not asserted: in this tree the 180 mm body behind the Ø5.6 mm leaf lies in lumens up to Ø18 mm and
  // gives way (measured: slides back 7 mm under 0.43 N; docs/ct.md).
  const ExperimentResult run = run_experiment(sc);
  ASSERT_TRUE(run.success) << "the vine did not reach the stop";
  ASSERT_TRUE(run.puncture.has_value());
  const robot::PunctureReport& p = *run.puncture;
  std::printf(
      "  biopsy: tip aimed %.1f deg off the nodule, wall %.1f mm ahead, %s, slid back %.2f mm, reaction up to "
      "%.2f N (walls take %.0f %%), needle tip %.1f mm from the nodule: %s\n",
      run.aim_angle / kDegToRad, 1e3 * p.wall_distance, p.held ? "held" : "did not hold", 1e3 * p.slide, p.max_force,
      100.0 * p.wall_share, 1e3 * p.to_nodule, p.success ? "success" : p.why.c_str());
  ASSERT_FALSE(p.steps.empty());
  for (const robot::PunctureStep& st : p.steps) {
    EXPECT_DOUBLE_EQ(st.force, robot::needle_tissue_force(sc.biopsy->needle, st.depth));
    EXPECT_LE(st.imbalance, 0.02) << "at " << 1e3 * st.protrusion << " mm";
  }
  EXPECT_GT(p.max_force, 0.0) << "the needle never met the wall";
  // Lying on the walls of the generated tree, the film presses them at its own pressure (film_contact_pressure)
  // and no more anywhere on the way: no wedged node (a ratio far above 1, docs/growth-and-contact.md).
  const std::optional<double> overload = film_overload(sc, run);
  ASSERT_TRUE(overload.has_value());
  std::printf("  largest contact pressure over the inflation pressure: %.4f\n", *overload);
  EXPECT_NEAR(*overload, 1.0, 1e-9);
  EXPECT_EQ(p.held, p.slide <= sc.biopsy->needle.max_slide);
  EXPECT_EQ(p.success, p.held && p.to_nodule <= sc.biopsy->radius);
  // punctured: some increment's equilibrium put the needle's tip past d_p (a retried increment's last piece is its
  // recorded equilibrium; its earlier pieces push the needle less far).
  EXPECT_EQ(p.punctured, std::any_of(p.steps.begin(), p.steps.end(), [&](const robot::PunctureStep& st) {
              return st.depth >= sc.biopsy->needle.puncture_depth;
            }));

  const std::string inside = replaced(text, "target: \"0-0-1\"",
                                      "target: {nodule: [" + std::to_string(1e3 * end.x()) + ", " +
                                          std::to_string(1e3 * end.y()) + ", " + std::to_string(1e3 * end.z()) + "]}");
  EXPECT_NE(error_of(inside).find("control.navigator.target.nodule"), std::string::npos) << error_of(inside);
  EXPECT_NE(error_of(inside).find("inside the airway lumen"), std::string::npos);
  std::string limited = target.str();
  limited.replace(limited.size() - 1, 1, ", max_needle: 5}");
  const std::string shortn = replaced(text, "target: \"0-0-1\"", limited);
  EXPECT_NE(error_of(shortn).find("no stop reaches the nodule"), std::string::npos) << error_of(shortn);

  // A given stop from a planning problem's start pose file (Med-MPD's startN.txt: a 4×4 pose by rows, mm): the
  // stop is the node the tool fits to nearest the pose's position, here the leaf's second-last node itself.
  const Vec3 pose = g.nodes[b.nodes[b.nodes.size() - 2]].position;
  const std::filesystem::path pose_file = std::filesystem::temp_directory_path() / "magvine_start_pose.txt";
  struct Remove {  // the file goes whatever the assertions do
    std::filesystem::path path;
    ~Remove() { std::filesystem::remove(path); }
  } remove_pose{pose_file};
  {
    std::ofstream out(pose_file);
    out.precision(17);
    out << "1 0 0 " << 1e3 * pose.x() << "\n0 1 0 " << 1e3 * pose.y() << "\n0 0 1 " << 1e3 * pose.z() << "\n0 0 0 1\n";
  }
  std::string given = target.str();
  given.replace(given.size() - 1, 1, ", stop: " + pose_file.string() + "}");
  const ExperimentScene at =
      parse_experiment_scene(replaced(text, "target: \"0-0-1\"", given), file.string(), file.parent_path());
  ASSERT_TRUE(at.biopsy.has_value());
  EXPECT_EQ(at.biopsy->plan.node, b.nodes[b.nodes.size() - 2]);
  EXPECT_LT(at.biopsy->plan.given_distance, 1e-9);
  for (const char* limit : {", max_angle: 30}", ", max_needle: 80}"}) {
    std::string both = given;
    both.replace(both.size() - 1, 1, limit);
    EXPECT_NE(error_of(replaced(text, "target: \"0-0-1\"", both)).find("taken as given"), std::string::npos) << limit;
  }
  std::ofstream(pose_file) << "1 0 0 1\n0 1 0 2\n";  // 8 numbers
  EXPECT_NE(error_of(replaced(text, "target: \"0-0-1\"", given)).find("needs 16 finite numbers"), std::string::npos);
  std::ofstream(pose_file) << "1 0 0 1\n0 1 0 2\n0 0 1 3\n0 0 1 1\n";  // not a rigid pose's last row
  EXPECT_NE(error_of(replaced(text, "target: \"0-0-1\"", given)).find("last row"), std::string::npos);
}

TEST(Experiment, NavigatorSteersIntoEitherDaughterOfTheYAndToGenerationTwoOfTheTree) {
  // control.navigator: the path is planned on the phantom's graph and the EPM placed 110 mm from the tip on the line
  // through the aim point each 0.1 s. The Y's two daughters are mirror images (±35°), and so are the tree's 0-0-1
  // and 0-1-0: each pair reached both ways shows the steering, not a bias of the start, picks the branch.
  const std::filesystem::path dir = std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes";
  std::ifstream in(kDemo);
  std::string y(std::istreambuf_iterator<char>(in), {});
  y = replaced(y,
               "  magnets:\n    - {magnet: 0, keyframes: [{time: 0, position: [90, 250, 0], axis: [0, -1, 0]},\n"
               "                              {time: 1, position: [70, 110, 0], axis: [0, -1, 0]}]}",
               "  navigator: {target: \"0-1\", magnet: 0, distance: 110}");
  y = replaced(y, "target: {position: [100, 24, 0], tolerance: 6}\n", "");
  const std::filesystem::path y_file = std::filesystem::temp_directory_path() / "magvine_y_navigator.yaml";
  std::ofstream(y_file) << y;
  for (const char* daughter : {"0-0", "0-1"}) {
    const ExperimentResult r = navigate_to(y_file, "target: \"0-1\"", "target: \"" + std::string(daughter) + "\"");
    EXPECT_TRUE(r.success) << daughter;
  }
  std::filesystem::remove(y_file);
  for (const char* branch : {"0-0-1", "0-1-0"}) {
    const ExperimentResult r = navigate_to(dir / "bronchial_tree_navigator.yaml", "target: \"0-0-1\"",
                                           "target: \"" + std::string(branch) + "\"");
    EXPECT_TRUE(r.success) << branch;
    EXPECT_TRUE(r.converged) << r.failure;
  }
}

TEST(Experiment, TheNavigatorSteersAPushedMagneticRodIntoEitherDaughterOfTheY) {
  // robot.kind: rod, pushed from the base (y_bifurcation_magnetic_rod.yaml: a Ø3 mm soft rod, its distal 20 mm
  // magnetised along its axis). The navigator's field at the tip turns the magnetised tip towards the aim: the rod
  // reaches the end of daughter 0-0 (+y) and, aimed the other way, of its mirror image 0-1 (−y). Without a magnet
  // the rod meets the symmetric carina head-on, and where it goes turns on round-off (with the barrier contact,
  // issue 28, the baseline and the AVX2 builds of the same commit part there), so that run is printed, and only
  // its insertion asserted. The inserted part carries the rod's distal magnetisation (the tip's 20 mm, 13–14 of
  // its 1.5 mm edges, whatever the insertion) and the body has no pressure.
  const std::filesystem::path scene =
      std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes/y_bifurcation_magnetic_rod.yaml";
  for (const auto& [daughter, side] : {std::pair<const char*, double>{"0-0", 1.0}, {"0-1", -1.0}}) {
    const ExperimentResult r = navigate_to(scene, "target: \"0-0\"", "target: \"" + std::string(daughter) + "\"");
    EXPECT_TRUE(r.success) << daughter;
    EXPECT_TRUE(r.converged) << r.failure;
    EXPECT_GT(side * r.final_state.tip().y(), 15e-3) << daughter;  // in the daughter, ±35° from the parent
    EXPECT_EQ(r.samples.back().pressure, 0.0);
  }
  std::ifstream in(scene);
  std::string text(std::istreambuf_iterator<char>(in), {});
  text = replaced(text,
                  "magnets:\n  - {kind: cylinder, diameter: 101.6, length: 101.6, polarisation: 1.48, "
                  "position: [90, 250, 0], axis: [0, -1, 0]}\n",
                  "");
  text = replaced(text, "  navigator: {target: \"0-0\", magnet: 0, distance: 110}", "  tether: [[0, 5], [8, 125]]");
  text += "target: {position: [100, 24, 0], tolerance: 6}\n";
  const ExperimentScene plain = parse_experiment_scene(text, "rod.yaml", MAGVINE_SOURCE_DIR);
  ASSERT_TRUE(plain.growth.rod.has_value());
  const robot::RodModel& body = plain.growth.rod->body;
  EXPECT_NEAR(plain.growth.rod->radius, 1.5e-3, 1e-12);
  EXPECT_TRUE(body.moment_per_length.front().isZero());
  EXPECT_NEAR(body.moment_per_length.back().x(), 0.125 / kMu0 * kPi * 2.25e-6, 1e-9);  // M·A along the tangent
  const ExperimentResult unsteered = run_experiment(plain);
  std::printf("  without a magnet: tip (%.1f, %.1f) mm, 0-0's end %s\n", 1e3 * unsteered.final_state.tip().x(),
              1e3 * unsteered.final_state.tip().y(), unsteered.success ? "reached" : "not reached");
  EXPECT_GT(unsteered.samples.back().length, 0.09);  // it was inserted, just not steered
  // A rod has no pressure: a pressure schedule is refused.
  EXPECT_NE(error_of(replaced(text, "  tether: [[0, 5], [8, 125]]", "  pressure: [[0, 35]]")).find("control.pressure"),
            std::string::npos);
}

TEST(Experiment, AUniformFieldScheduleActsAsTheSameFieldFromAMagnetsEntry) {
  // control.field (a coil system's field schedule) against the same uniform field given as magnets: [{kind: uniform}]
  // (the magnetics module's own source): the pushed magnetic rod of y_bifurcation_magnetic_rod.yaml in 8 mT along +y
  // for 3 s, tethered, ends in the same place to 1e-12 m. Then the schedule turning the field from +y to −y over
  // 0.5 s at t = 1.5 s bends the inserted tip the other way: it ends on the −y side.
  const std::filesystem::path scene =
      std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes/y_bifurcation_magnetic_rod.yaml";
  std::ifstream in(scene);
  std::string text(std::istreambuf_iterator<char>(in), {});
  text = replaced(text, "  navigator: {target: \"0-0\", magnet: 0, distance: 110}", "  tether: [[0, 5], [3, 50]]");
  text = replaced(text, "duration: 8", "duration: 3");
  const std::string magnet_line =
      "  - {kind: cylinder, diameter: 101.6, length: 101.6, polarisation: 1.48, position: [90, 250, 0], axis: [0, -1, "
      "0]}";
  const std::string as_magnet = replaced(text, magnet_line, "  - {kind: uniform, field: [0, 0.008, 0]}");
  const std::string as_schedule = replaced(replaced(text, "magnets:\n" + magnet_line + "\n", ""), "control:\n",
                                           "control:\n  field: [[0, [0, 0.008, 0]]]\n");
  const ExperimentResult a = run_experiment(parse_experiment_scene(as_magnet, "a.yaml", MAGVINE_SOURCE_DIR));
  const ExperimentResult b = run_experiment(parse_experiment_scene(as_schedule, "b.yaml", MAGVINE_SOURCE_DIR));
  ASSERT_TRUE(a.converged && b.converged) << a.failure << b.failure;
  double worst = 0.0;
  for (std::size_t i = 0; i < a.final_state.x.size(); ++i) {
    worst = std::max(worst, (a.final_state.x[i] - b.final_state.x[i]).norm());
  }
  std::printf("  uniform 8 mT: tip y %.2f mm; schedule against magnets entry %.3g m\n", 1e3 * a.final_state.tip().y(),
              worst);
  EXPECT_EQ(a.final_state.x.size(), b.final_state.x.size());
  EXPECT_LT(worst, 1e-12);
  EXPECT_GT(a.final_state.tip().y(), 1e-3);
  const std::string turned = replaced(as_schedule, "field: [[0, [0, 0.008, 0]]]",
                                      "field: [[0, [0, 0.008, 0]], [1.5, [0, 0.008, 0]], [2, [0, -0.008, 0]]]");
  const ExperimentResult c = run_experiment(parse_experiment_scene(turned, "c.yaml", MAGVINE_SOURCE_DIR));
  ASSERT_TRUE(c.converged) << c.failure;
  std::printf("  turned to -y at 1.5-2 s: tip y %.2f mm\n", 1e3 * c.final_state.tip().y());
  EXPECT_LT(c.final_state.tip().y(), -1e-3);
  // A keyframe that is not [time, [bx, by, bz]] is refused, naming the key.
  EXPECT_NE(
      error_of(replaced(as_schedule, "field: [[0, [0, 0.008, 0]]]", "field: [[0, 0.008]]")).find("control.field[0]"),
      std::string::npos);
}

TEST(Experiment, TrialsPerturbEachRunAndGiveTheSameOutcomesOnOneThreadOrTwo) {
  // magvine trials: the Y navigator scene towards both daughters, 2 repeats each, on 1 and on 2 threads: the same
  // outcomes in the same order (each trial's perturbation is drawn from its own seed); every trial reaches its
  // daughter (the placement is off by ~2 mm, the pressure by ~0.5 kPa: far inside what the steering tolerates).
  std::string y = demo_text();
  y = replaced(y,
               "  magnets:\n    - {magnet: 0, keyframes: [{time: 0, position: [90, 250, 0], axis: [0, -1, 0]},\n"
               "                              {time: 1, position: [70, 110, 0], axis: [0, -1, 0]}]}",
               "  navigator: {target: \"0-1\", magnet: 0, distance: 110}");
  y = replaced(y, "target: {position: [100, 24, 0], tolerance: 6}\n", "");
  const ExperimentScene scene = parse_experiment_scene(y, "y.yaml", MAGVINE_SOURCE_DIR);
  const ExperimentScene a = perturbed(scene, 1);
  const ExperimentScene b = perturbed(scene, 2);
  EXPECT_NE(a.navigator_offset, b.navigator_offset);
  EXPECT_NE(a.pressure.values[0], scene.pressure.values[0]);
  EXPECT_EQ(perturbed(scene, 1).vine.wall.modulus, a.vine.wall.modulus);
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "magvine_test_trials";
  std::filesystem::remove_all(dir);
  const std::vector<TrialOutcome> one = run_trials(scene, {"0-0", "0-1"}, 2, 1);
  // On two threads, keeping each trial's outputs (--keep-runs): each folder's metrics are that trial's.
  const std::vector<TrialOutcome> two = run_trials(scene, {"0-0", "0-1"}, 2, 2, nullptr, dir / "runs");
  ASSERT_EQ(one.size(), 4u);
  ASSERT_EQ(two.size(), 4u);
  for (std::size_t i = 0; i < one.size(); ++i) {
    EXPECT_EQ(one[i].target, two[i].target);
    EXPECT_EQ(one[i].seed, two[i].seed);
    EXPECT_EQ(one[i].time_to_target, two[i].time_to_target);
    EXPECT_EQ(one[i].final_error, two[i].final_error);
    EXPECT_TRUE(one[i].success) << one[i].target << " repeat " << one[i].repeat;
    const std::filesystem::path run = dir / "runs" / (two[i].target + "_r" + std::to_string(two[i].repeat));
    std::ifstream in(run / "metrics.json");
    ASSERT_TRUE(in) << run;
    const nlohmann::json m = nlohmann::json::parse(in);
    EXPECT_EQ(m.at("seed").get<std::uint64_t>(), two[i].seed) << run;
    EXPECT_EQ(m.at("success").get<bool>(), two[i].success) << run;
    EXPECT_EQ(m.at("time_to_target_s").get<double>(), two[i].time_to_target) << run;
    EXPECT_TRUE(std::filesystem::exists(run / "events.json")) << run;
    EXPECT_TRUE(std::filesystem::exists(run / "tip_trajectory.csv")) << run;
  }
  write_trial_outputs(one, dir);
  std::ifstream md(dir / "summary.md");
  const std::string table(std::istreambuf_iterator<char>(md), {});
  std::printf("%s", table.c_str());
  EXPECT_NE(table.find("| 0-0 | "), std::string::npos);
  EXPECT_NE(table.find("| 2/2 |"), std::string::npos);
  std::filesystem::remove_all(dir);
  EXPECT_THROW(run_trials(scene, {"0-9"}, 1, 1), InputError);

  // A failure carries its reason: cut to 1 s the runs cannot reach the daughter's end (~100 mm at ~30 mm/s).
  ExperimentScene short_scene = scene;
  short_scene.duration = 1.0;
  const std::vector<TrialOutcome> cut = run_trials(short_scene, {"0-1"}, 1, 1);
  ASSERT_EQ(cut.size(), 1u);
  EXPECT_FALSE(cut[0].success);
  std::printf("  reason: %s\n", cut[0].reason.c_str());
  EXPECT_EQ(cut[0].reason.rfind("the time ran out, last in branch 0", 0), 0u) << cut[0].reason;
  EXPECT_NE(cut[0].reason.find("mm from the target"), std::string::npos);
  write_trial_outputs(cut, dir);
  std::ifstream failed(dir / "summary.md");
  const std::string listed(std::istreambuf_iterator<char>(failed), {});
  EXPECT_NE(listed.find("Failures:\n\n- 0-1, repeat 0 (seed "), std::string::npos) << listed;
  // No success: no path length, mean time or SD to show (a dash, not "nan").
  EXPECT_NE(listed.find("| 0-1 | — | 0/1 | — | — |"), std::string::npos) << listed;
  std::filesystem::remove_all(dir);
}

TEST(Experiment, AFailedRunLeavesItsCompleteMetricsOnly) {
  // The rule for failed runs (docs/cli.md): a run whose last step has no equilibrium writes metrics.json alone, with
  // every key and "failed": true; a run that succeeded writes every file and "failed": false.
  ExperimentScene scene = load_experiment_scene(kDemo);
  scene.duration = 0.1;
  ExperimentResult r = run_experiment(scene);
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "magvine_test_failed_run";
  std::filesystem::remove_all(dir);
  // An earlier run's outputs this one does not write (a biopsy's, a camera-guided run's) go; a file of the user's
  // stays.
  std::filesystem::create_directories(dir / "guidance");
  std::ofstream(dir / "guidance" / "001000.png") << "old";
  std::ofstream(dir / "puncture.csv") << "old";
  std::ofstream(dir / "notes.txt") << "mine";
  write_experiment_outputs(scene, r, dir);
  EXPECT_FALSE(std::filesystem::exists(dir / "guidance"));
  EXPECT_FALSE(std::filesystem::exists(dir / "puncture.csv"));
  EXPECT_TRUE(std::filesystem::exists(dir / "notes.txt"));
  std::filesystem::remove(dir / "notes.txt");
  const nlohmann::json ok = nlohmann::json::parse(text_of(dir / "metrics.json"));
  EXPECT_FALSE(ok.at("failed").get<bool>());
  EXPECT_TRUE(std::filesystem::exists(dir / "tip_trajectory.csv"));
  r.converged = false;
  r.failure = "at 0.1 s: Newton did not converge in 200 iterations";
  write_experiment_outputs(scene, r, dir);  // into the same folder: the successful run's files go
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(dir)) files.push_back(e.path().filename().string());
  EXPECT_EQ(files, std::vector<std::string>{"metrics.json"});
  const nlohmann::json failed = nlohmann::json::parse(text_of(dir / "metrics.json"));
  EXPECT_TRUE(failed.at("failed").get<bool>());
  EXPECT_EQ(failed.at("failure").get<std::string>(), r.failure);
  for (const auto& [key, value] : ok.items()) EXPECT_TRUE(failed.contains(key)) << key << " missing";
  std::filesystem::remove_all(dir);
}

TEST(Experiment, EveryBundledSceneLoads) {
  // docs/scenes.md points at these as the examples of each feature: each must load as what it claims to be.
  int experiments = 0;
  int free_space = 0;
  for (const auto& entry : std::filesystem::directory_iterator(kDemo.parent_path())) {
    if (entry.path().extension() != ".yaml") continue;
    if (entry.path().stem().string().starts_with("mpm_")) continue;  // MPM scenes: test_mpm_scene loads them
    SCOPED_TRACE(entry.path().string());
    if (entry.path().stem().string().starts_with("ct_") &&
        !std::filesystem::exists(kDemo.parent_path() / "../../../shared/airways")) {
      continue;  // their meshes are third-party data outside the repository (their tests skip too)
    }
    if (!config::kWithCt && text_of(entry.path()).find("segmentation:") != std::string::npos) {
      continue;  // a CT segmentation needs the CT module
    }
    if (!config::kWithRender && text_of(entry.path()).find("mode: camera") != std::string::npos) {
      continue;  // camera guidance needs the render module (and says so: test_camera_guidance)
    }
    if (is_design_scene(entry.path())) {
      EXPECT_NO_THROW((void)load_design_scene(entry.path()));  // a free-space rod scene plus design:
    } else if (is_calibrate_scene(entry.path())) {
      EXPECT_NO_THROW((void)load_calibrate_scene(entry.path()));  // a free-space vine scene plus calibrate:
    } else if (is_experiment_scene(entry.path())) {
      EXPECT_NO_THROW((void)load_experiment_scene(entry.path()));
      ++experiments;
    } else {
      EXPECT_NO_THROW((void)load_free_space_scene(entry.path()));
      ++free_space;
    }
  }
  EXPECT_GE(experiments, 4);
  EXPECT_GE(free_space, 2);
}

TEST(Experiment, SameSceneSameResult) {
  const ExperimentScene scene = load_experiment_scene(kDemo);
  const ExperimentResult a = run_experiment(scene);
  const ExperimentResult b = run_experiment(scene);
  ASSERT_EQ(a.samples.size(), b.samples.size());
  for (std::size_t i = 0; i < a.samples.size(); ++i) {
    ASSERT_EQ(a.samples[i].tip, b.samples[i].tip) << i;
    ASSERT_EQ(a.samples[i].total_normal, b.samples[i].total_normal) << i;
  }
}

TEST(Experiment, OutputsCarryTheContractKeys) {
  const ExperimentScene scene = load_experiment_scene(kDemo);
  ExperimentScene short_run = scene;
  short_run.duration = 0.5;
  const ExperimentResult r = run_experiment(short_run);
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "magvine_test_experiment";
  std::filesystem::remove_all(dir);
  write_experiment_outputs(short_run, r, dir);
  for (const char* f : {"metrics.json", "tip_trajectory.csv", "magnet_trajectory.csv", "events.json", "shape.csv"}) {
    EXPECT_TRUE(std::filesystem::exists(dir / f)) << f;
  }
  std::ifstream in(dir / "metrics.json");
  const nlohmann::json m = nlohmann::json::parse(in);
  for (const char* key :
       {"success", "time_to_target_s", "final_tip_error_m", "tip_position_m", "everted_length_m", "tip_path_length_m",
        "branches_reached", "max_wall_normal_N", "mean_wall_normal_N", "max_wall_shear_N", "max_contact_pressure_Pa",
        "max_force_imbalance", "stalls", "magnet_travel_m", "runtime_s", "real_time_factor", "converged", "seed",
        "max_contact_pressure_over_inflation"}) {
    EXPECT_TRUE(m.contains(key)) << key;
  }
  // Half a second in, the body has not touched the trachea yet: no contact pressure.
  EXPECT_EQ(m["max_contact_pressure_over_inflation"].get<double>(), 0.0);
  // The magnet moves 140 mm towards the axis and 20 mm back along it in the first second, in a straight line: in
  // half a second, half that path.
  EXPECT_NEAR(m["magnet_travel_m"].get<double>() * 1e3, 0.5 * std::hypot(20.0, 140.0), 1e-6);
  // Every step's converged body balances: Σ(wall + friction + magnetic + gravity + clamp) within 1e-3 of its
  // largest load (the solver's tolerance, scaled gradient 1e-7, leaves far less).
  EXPECT_LT(m["max_force_imbalance"].get<double>(), 1e-3);
  EXPECT_FALSE(std::filesystem::exists(dir / "shapes.csv"));  // opt-in
  std::filesystem::remove_all(dir);

  // outputs.shape_interval: the body at the first step at or past each multiple of 0.1 s (steps of 0.02 s: t = 0.02,
  // 0.1, 0.2, 0.3, 0.4, 0.5), the last one the final shape.
  ExperimentScene shaped = short_run;
  shaped.shape_interval = 0.1;
  const ExperimentResult rs = run_experiment(shaped);
  write_experiment_outputs(shaped, rs, dir);
  std::ifstream shapes(dir / "shapes.csv");
  std::string line;
  std::getline(shapes, line);
  EXPECT_EQ(line,
            "t_s,node,x_m,y_m,z_m,normal_N,shear_N,normal_x_N,normal_y_N,normal_z_N,shear_x_N,shear_y_N,"
            "shear_z_N,pressure_Pa");
  std::vector<std::string> rows;
  while (std::getline(shapes, line)) rows.push_back(line);
  ASSERT_EQ(rs.shapes.size(), 6u);
  std::size_t expected_rows = 0;
  for (const ShapeSample& sample : rs.shapes) expected_rows += sample.nodes.size();
  EXPECT_EQ(rows.size(), expected_rows);
  EXPECT_NEAR(rs.shapes.front().time, 0.02, 1e-12);
  EXPECT_NEAR(rs.shapes[1].time, 0.1, 1e-9);
  EXPECT_NEAR(rs.shapes[4].time, 0.4, 1e-9);
  EXPECT_EQ(rs.shapes.back().nodes.back(), rs.final_state.tip());
  // The per-node wall forces of each shape are that step's: they add up to its total and peak at its maximum (a
  // longer run, the body on the wall from 0.78 s).
  shaped.duration = 2.0;
  shaped.shape_interval = 0.5;
  const ExperimentResult walled = run_experiment(shaped);
  ASSERT_EQ(walled.shapes.size(), 5u);  // t = 0.02, 0.5, 1, 1.5, 2
  EXPECT_GT(walled.shapes.back().normal.size(), 0u);
  EXPECT_GT(*std::max_element(walled.shapes.back().normal.begin(), walled.shapes.back().normal.end()), 0.0);
  for (const ShapeSample& sample : walled.shapes) {
    const auto step = std::find_if(walled.samples.begin(), walled.samples.end(),
                                   [&](const ExperimentSample& s) { return s.time == sample.time; });
    ASSERT_NE(step, walled.samples.end());
    ASSERT_EQ(sample.normal.size(), sample.nodes.size());
    EXPECT_NEAR(std::accumulate(sample.normal.begin(), sample.normal.end(), 0.0), step->total_normal, 1e-12);
    EXPECT_NEAR(std::accumulate(sample.shear.begin(), sample.shear.end(), 0.0), step->total_shear, 1e-12);
    EXPECT_EQ(*std::max_element(sample.normal.begin(), sample.normal.end()), step->max_normal);
    // The vectors: the friction's magnitude is its vector's length; the net normal force (the converged solve's) is
    // at most what the node's contacts carry together (two walls of a slot push from both sides; the magnitude is
    // the lagged λ, settled to within friction_tolerance, 1e-3, of the step's total normal force).
    ASSERT_EQ(sample.shear_vector.size(), sample.nodes.size());
    ASSERT_EQ(sample.normal_vector.size(), sample.nodes.size());
    for (std::size_t i = 0; i < sample.nodes.size(); ++i) {
      EXPECT_NEAR(sample.shear_vector[i].norm(), sample.shear[i], 1e-12) << i;
      EXPECT_LE(sample.normal_vector[i].norm(), sample.normal[i] + 1e-3 * step->total_normal + 1e-15) << i;
    }
  }
  std::filesystem::remove_all(dir);
}

TEST(Experiment, SchedulesAreLinearBetweenKeyframesAndHeldBeyond) {
  Schedule s;
  s.times = {1.0, 3.0};
  s.values = {10.0, 30.0};
  EXPECT_EQ(s.at(0.0), 10.0);
  EXPECT_DOUBLE_EQ(s.at(2.5), 25.0);
  EXPECT_EQ(s.at(9.0), 30.0);
}

TEST(Experiment, BadScenesNameTheFileAndKey) {
  const std::string text = demo_text();
  const auto expect_error = [&](const std::string& scene, const std::string& part) {
    const std::string what = error_of(scene);
    EXPECT_NE(what.find("bad.yaml"), std::string::npos) << what;
    EXPECT_NE(what.find(part), std::string::npos) << what;
  };
  expect_error(replaced(text, "  pressure: [[0, 35]]", "  presure: [[0, 35]]"), "did you mean 'pressure'");
  expect_error(replaced(text, "{time: 1, position", "{time: 0, position"), "times must increase");
  expect_error(replaced(text, "{magnet: 0, keyframes", "{magnet: 3, keyframes"), "control.magnets[0].magnet");
  expect_error(replaced(text, "phantom: {kind: y_bifurcation}", "phantom: {kind: y_junction}"), "anatomy.phantom.kind");
  expect_error(replaced(text, "phantom: {kind: y_bifurcation}", "mesh: no_such_airway.stl"), "no_such_airway.stl");
  expect_error(replaced(text, "duration: 8, ", ""), "simulation.duration");
  expect_error(replaced(text, "kind: vine", "kind: tentacle"), "robot.kind");
  expect_error(replaced(text, "growth: {yield_pressure: 20}", "growth: {yield_pressure: 20, contact: planes}"),
               "growth.contact: the planes contact model and its keys are gone");
  expect_error(replaced(text, "growth: {yield_pressure: 20}", "growth: {yield_pressure: 20, friction_slip: -1}"),
               "growth.friction_slip");
  expect_error(replaced(text, "growth: {yield_pressure: 20}",
                        "growth: {yield_pressure: 20, catheter: {outer_diameter: 4, inner_diameter: 3, "
                        "youngs_modulus: 26000}}"),
               "growth.catheter: a catheter tube is pushed");
  const std::string navigated =
      replaced(text, "  pressure: [[0, 35]]\n", "  pressure: [[0, 35]]\n  navigator: {target: \"0-7\"}\n");
  expect_error(navigated, "control.navigator.target: no branch '0-7'");  // (and magnet 0 is also keyframed)
  // A magnet inside the body: its rest pose or a keyframe with the Ø101.6 mm EPM on the phantom.
  expect_error(
      replaced(text, "position: [90, 250, 0], axis: [0, -1, 0]}\n", "position: [60, 30, 0], axis: [0, -1, 0]}\n"),
      "magnets[0].position: the magnet would overlap the anatomy");
  expect_error(replaced(text, "{time: 1, position: [70, 110, 0]", "{time: 1, position: [70, 40, 0]"),
               "control.magnets[0].keyframes[1].position: on its way there");
  // control.navigator.recover retracts a deflated vine: the growth must say at what pressure it inverts.
  const std::string recovering =
      replaced(text,
               "  magnets:\n    - {magnet: 0, keyframes: [{time: 0, position: [90, 250, 0], axis: [0, -1, 0]},\n"
               "                              {time: 1, position: [70, 110, 0], axis: [0, -1, 0]}]}",
               "  navigator: {target: \"0-1\", magnet: 0, recover: {retries: 2}}");
  expect_error(recovering,
               "control.navigator.recover.retries: the navigator retracts a deflated vine: set "
               "growth.retraction_pressure");
  const std::string retractable =
      replaced(recovering, "growth: {yield_pressure: 20}", "growth: {yield_pressure: 20, retraction_pressure: 5}");
  expect_error(replaced(retractable, "retries: 2", "retries: 1.5"),
               "control.navigator.recover.retries: must be a whole");
  expect_error(replaced(retractable, "retries: 2", "retries: 2, bak: 10"), "did you mean 'back'");
  expect_error(replaced(retractable, "recover: {retries: 2}", "recover: {back: 10}"),
               "control.navigator.recover.retries");
  if (!config::kWithRender) {  // with the render module: test_video_outputs
    // Without it a video is checked and skipped (a warning), so bundled scenes with videos still run.
    EXPECT_EQ(error_of(text + "outputs: {video: {camera: tip}}\n"), "no error");
    expect_error(text + "outputs: {video: {camera: nose}}\n", "outputs.video.camera");
  }
}

TEST(Experiment, GamepadCommandsBecomeTheSameKeyframesAsWrittenOut) {
  // control.commands: the demo's magnet sweep written as one gamepad move (from the rest pose by (−20, −140, 0) mm
  // over 1 s) gives the demo's keyframes, so the same run; pressure steps ramp over `over` (0.5 s
  // default) and grow commands release the tether from the initial length.
  const std::string text = demo_text();
  const std::string scripted =
      replaced(text,
               "  magnets:\n    - {magnet: 0, keyframes: [{time: 0, position: [90, 250, 0], axis: [0, -1, 0]},\n"
               "                              {time: 1, position: [70, 110, 0], axis: [0, -1, 0]}]}",
               "  commands:\n    - {time: 0, over: 1, move: [-20, -140, 0]}");
  const ExperimentScene a = parse_experiment_scene(text, "a.yaml", MAGVINE_SOURCE_DIR);
  const ExperimentScene b = parse_experiment_scene(scripted, "b.yaml", MAGVINE_SOURCE_DIR);
  ASSERT_EQ(b.magnet_keyframes[0].size(), 2u);
  for (std::size_t k = 0; k < 2; ++k) {
    EXPECT_EQ(a.magnet_keyframes[0][k].time, b.magnet_keyframes[0][k].time);
    EXPECT_LT((a.magnet_keyframes[0][k].position - b.magnet_keyframes[0][k].position).norm(), 1e-15);
    EXPECT_LT((a.magnet_keyframes[0][k].axis - b.magnet_keyframes[0][k].axis).norm(), 1e-15);
  }
  const ExperimentResult ra = run_experiment(a);
  const ExperimentResult rb = run_experiment(b);
  // The keyframe positions differ in the last bit (0.09 − 0.02 against 0.07); the tips by round-off, nothing more.
  EXPECT_LT((ra.final_state.tip() - rb.final_state.tip()).norm(), 1e-9);

  std::string more = replaced(scripted, "  pressure: [[0, 35]]\n", "");
  more = replaced(more, "move: [-20, -140, 0]}",
                  "move: [-20, -140, 0]}\n    - {time: 2, pressure: -5}\n    - {time: 3, over: 2, grow: 20}\n"
                  "    - {time: 4, rotate: {axis: [0, 0, 1], angle: 90}}");
  const ExperimentScene c = parse_experiment_scene(more, "c.yaml", MAGVINE_SOURCE_DIR);
  EXPECT_DOUBLE_EQ(c.pressure.at(1.0), 35e3);     // robot.pressure until the command
  EXPECT_DOUBLE_EQ(c.pressure.at(2.25), 32.5e3);  // half way down the 0.5 s ramp
  EXPECT_DOUBLE_EQ(c.pressure.at(9.0), 30e3);
  ASSERT_TRUE(c.tether.has_value());
  EXPECT_DOUBLE_EQ(c.tether->at(0.0), 5e-3);  // the initial everted length
  EXPECT_DOUBLE_EQ(c.tether->at(4.0), 15e-3);
  EXPECT_DOUBLE_EQ(c.tether->at(6.0), 25e-3);
  const MagnetKeyframe turned = c.magnet_keyframes[0].back();
  EXPECT_DOUBLE_EQ(turned.time, 4.5);
  EXPECT_LT((turned.axis - Vec3(1.0, 0.0, 0.0)).norm(), 1e-12);  // −y turned 90° about +z

  EXPECT_NE(error_of(replaced(more, "{time: 2, pressure: -5}", "{time: 0.5, move: [0, 10, 0]}"))
                .find("control.commands[1].move: starts before the previous command on this magnet ends"),
            std::string::npos);
  EXPECT_NE(error_of(replaced(more, "{time: 2, pressure: -5}", "{time: 2, pressure: -5, grow: 3}"))
                .find("each command does exactly one of"),
            std::string::npos);
  EXPECT_NE(error_of(replaced(more, "{time: 2, pressure: -5}", "{time: 2, pressure: -50}")).find("below 0"),
            std::string::npos);
  const std::string onto = error_of(replaced(more, "{time: 2, pressure: -5}", "{time: 2, move: [0, -180, 0]}"));
  EXPECT_NE(onto.find("control.commands[1].move: "), std::string::npos) << onto;
  EXPECT_NE(onto.find("the magnet would overlap the anatomy"), std::string::npos) << onto;
  // Clear at both ends, through the phantom on the way: from (70, 110, 0) to (70, −250, 0).
  EXPECT_NE(error_of(replaced(more, "{time: 2, pressure: -5}", "{time: 2, move: [0, -360, 0]}"))
                .find("control.commands[1].move: on its way there, at "),
            std::string::npos);
}

TEST(Experiment, ASwingAcrossAnObstacleDoesNotCarryTheBodyThroughIt) {
  // The S-bend gamepad scene with the EPM brought in 10 mm further back (x = 75 mm): at 1 kPa its pull swings the
  // body's free part against the first obstacle's far side, and as the loads ramp up in one solve a node can move
  // farther than the wall planes it was given. A node whose centre crossed a wall undoes that solve and keeps the
  // wall as a plane (robot/growth.cpp). Before that, the tip went through the 20 mm obstacle (to x = 57.7,
  // y = −15.1 mm, 2 mm inside it) and grew on under the second one to "reach" the target. Asserted: the tip inside
  // the lumen at every step, and every node at the end.
  const std::filesystem::path file = std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes/s_bend_gamepad.yaml";
  std::ifstream in(file);
  const std::string text(std::istreambuf_iterator<char>(in), {});
  const ExperimentScene scene = parse_experiment_scene(replaced(text, "move: [0, 215, 0]}", "move: [-10, 215, 0]}"),
                                                       file.string(), file.parent_path());
  const ExperimentResult r = run_experiment(scene);
  const anatomy::CollisionWorld& world = scene.anatomy->world;
  for (const ExperimentSample& s : r.samples) {
    ASSERT_TRUE(world.contains(s.tip)) << "the tip left the lumen at " << s.time << " s: (" << 1e3 * s.tip.x() << ", "
                                       << 1e3 * s.tip.y() << ") mm";
  }
  for (const Vec3& x : r.final_state.x) EXPECT_TRUE(world.contains(x));
  std::printf("  tip at (%.1f, %.1f) mm, %.0f mm everted, target %s\n", 1e3 * r.final_state.tip().x(),
              1e3 * r.final_state.tip().y(), 1e3 * r.samples.back().length, r.success ? "reached" : "not reached");
}

TEST(Experiment, TheSBendScriptTakesTheSkinVineAroundBothObstacles) {
  // Thesis 4.7.3 (fig 4.10) by gamepad, assets/scenes/s_bend_gamepad.yaml: the Ø8 mm skin MVR grown past the first
  // obstacle at 12 kPa, deflated to 1 kPa with the EPM beside the channel (the body creases towards it), regrown at
  // 12 kPa: its tip meets the second obstacle's rounded end, rolls off it into the gap below it (y < −6 mm) and
  // grows on along the far wall to the target past it. Asserted: the target reached, the tip through that gap
  // (beside the obstacle, 100 mm < x < 120 mm, at y < −6 mm) and past it (x > 120 mm), inside the lumen at every
  // step and every node at the end. Without the magnet (moved 5 mm instead of 215 mm) the body grows straight into
  // the second obstacle's flat face and is blocked there.
  const std::filesystem::path file = std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes/s_bend_gamepad.yaml";
  const std::string text = text_of(file);
  const ExperimentScene scene = load_experiment_scene(file);
  const anatomy::CollisionWorld& world = scene.anatomy->world;
  const ExperimentResult r = run_experiment(scene);
  bool through_gap = false;
  for (const ExperimentSample& s : r.samples) {
    ASSERT_TRUE(world.contains(s.tip)) << "the tip left the lumen at " << s.time << " s";
    if (s.tip.x() > 0.100 && s.tip.x() < 0.120 && s.tip.y() < -6e-3) through_gap = true;
  }
  for (const Vec3& x : r.final_state.x) EXPECT_TRUE(world.contains(x)) << "a node left the lumen";
  const Vec3 tip = 1e3 * r.final_state.tip();
  std::printf("  %s at %.1f s, tip (%.1f, %.1f, %.1f) mm, %.0f mm everted, %zu events\n",
              r.success ? "reached" : "not reached", r.time_to_target, tip.x(), tip.y(), tip.z(),
              1e3 * r.samples.back().length, r.events.size());
  for (const RunEvent& e : r.events) {
    std::printf("    %.2f s %s: %s\n", e.time, std::string(event_name(e.kind)).c_str(), e.detail.c_str());
  }
  EXPECT_TRUE(r.success);
  EXPECT_TRUE(through_gap);
  EXPECT_GT(tip.x(), 120.0);
  const std::string away =
      replaced(replaced(text, "move: [0, 215, 0]}", "move: [0, 5, 0]}"), "move: [0, -215, 0]}", "move: [0, -5, 0]}");
  const ExperimentResult none = run_experiment(parse_experiment_scene(away, file.string(), file.parent_path()));
  const Vec3 stopped = 1e3 * none.final_state.tip();
  std::printf("  without the magnet: tip (%.1f, %.1f) mm, %s\n", stopped.x(), stopped.y(),
              none.success ? "reached" : "not reached");
  EXPECT_FALSE(none.success);
  EXPECT_LT(stopped.x(), 100.0);  // before the second obstacle's face (x = 100 mm)
  bool blocked = false;
  for (const RunEvent& e : none.events) blocked = blocked || e.kind == EventKind::kBlocked;
  EXPECT_TRUE(blocked);
}

TEST(Experiment, AGamepadSteersTheSkinVineIntoEitherMainBronchus) {
  // Thesis 4.7.4 by gamepad (assets/scenes/bronchial_tree_skin_vine.yaml): the Ø8 mm skin MVR grown down the tree's
  // trachea at 12 kPa, deflated to 1 kPa for 2 s with the EPM brought in beside main bronchus 0-0, regrown at 12 kPa:
  // it reaches 0-0's end; the same script mirrored (magnet and target at −x) reaches 0-1's; with the magnet left
  // 300 mm away it does not reach 0-1's: it rolls off the carina into 0-0 (re-measured with the barrier model,
  // issue 28: the planes model's incidence rule stopped it at the carina), so the mirrored run's 0-1 is the
  // magnet's doing.
  const std::filesystem::path file =
      std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes/bronchial_tree_skin_vine.yaml";
  std::ifstream in(file);
  const std::string text(std::istreambuf_iterator<char>(in), {});
  const auto run = [&](const std::string& scene_text, const char* what) {
    const ExperimentResult r = run_experiment(parse_experiment_scene(scene_text, file.string(), file.parent_path()));
    const Vec3 tip = 1e3 * r.final_state.tip();
    std::printf("  %s: tip (%.1f, %.1f, %.1f) mm, %.0f mm everted, target %s", what, tip.x(), tip.y(), tip.z(),
                1e3 * r.samples.back().length, r.success ? "reached" : "not reached");
    if (r.success) std::printf(" at %.1f s", r.time_to_target);
    std::printf("\n");
    return r;
  };
  const ExperimentResult right = run(text, "EPM beside 0-0");
  std::string mirrored = replaced(text, "move: [-190, 0, -5]", "move: [190, 0, -5]");
  mirrored = replaced(mirrored, "position: [300, 0, -130]", "position: [-300, 0, -130]");
  mirrored = replaced(mirrored, "target: {position: [28, 0, -167.5]", "target: {position: [-28, 0, -167.5]");
  const ExperimentResult left = run(mirrored, "EPM beside 0-1");
  const ExperimentResult none = run(replaced(text, "    - {time: 10, over: 1, move: [-190, 0, -5]}", "#"), "EPM away");
  EXPECT_TRUE(right.success);
  EXPECT_TRUE(left.success);
  EXPECT_GT(none.final_state.tip().x(), 0.0);  // not in 0-1 (−x)
  EXPECT_GT(right.final_state.tip().x(), 15e-3);
  EXPECT_LT(left.final_state.tip().x(), -15e-3);
}

TEST(Experiment, TheNavigatorDeflatesTheSkinVineAtTheCarinaAndSteersItIntoAMainBronchus) {
  // assets/scenes/bronchial_tree_skin_navigator.yaml: the navigator's pressure regulation and gradient mode for a
  // magnetic skin. Asserted: the pressure held at 1 kPa for 2 s exactly once (at the carina, the only junction before
  // 0-0's end), at 12 kPa otherwise, and the tip pulled to the magnet's side of the carina (+x). Whether it then
  // reaches 0-0's end turns on round-off (1 of 4 perturbed trials does, none towards 0-1: docs/experiments.md), so it
  // is printed, not asserted.
  const std::filesystem::path file =
      std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes/bronchial_tree_skin_navigator.yaml";
  const ExperimentScene scene = load_experiment_scene(file);
  const ExperimentResult r = run_experiment(scene);
  double low_from = -1.0;
  double low_to = -1.0;
  int drops = 0;
  double last = scene.pressure.at(0.0);
  for (const ExperimentSample& s : r.samples) {
    if (s.pressure < last) {
      ++drops;
      low_from = s.time;
    }
    if (s.pressure > last) low_to = s.time;
    last = s.pressure;
    EXPECT_TRUE(s.pressure == 1e3 || s.pressure == 12e3) << s.pressure;
  }
  std::printf("  deflated from %.1f to %.1f s; target %s at %.1f s, tip (%.1f, %.1f, %.1f) mm\n", low_from, low_to,
              r.success ? "reached" : "not reached", r.time_to_target, 1e3 * r.final_state.tip().x(),
              1e3 * r.final_state.tip().y(), 1e3 * r.final_state.tip().z());
  EXPECT_EQ(drops, 1);
  EXPECT_NEAR(low_to - low_from, 2.0, 0.1 + 1e-9);  // steps of 0.1 s
  EXPECT_GT(r.final_state.tip().x(), 2e-3);         // towards 0-0 (+x)
}

TEST(Experiment, TheNavigatorsTorqueModeTurnsASkinTowardsTheAimAndItsGradientModeAlignsTheField) {
  // A tip going down −z on a path that turns to +x, the skin's moment m along +x (in the turn's plane). Gradient
  // mode: the field at the tip runs along m (a pull, no torque). Torque mode: along ω × m, so m × B lies along
  // ω = t × (aim's side) = −y, the axis that turns the tangent towards +x. The magnet is the scene's Ø101.6 mm N52
  // cylinder, placed by the dipole inverse m_e ∝ (3/2)(b·r̂)r̂ − b; its exact field is checked. Tolerance 10°: at
  // 110 mm, about one magnet length, the cylinder's field direction differs from the dipole's by a few degrees.
  // With m along y instead (the turn about m itself, which no torque gives), torque mode falls back to gradient.
  const std::vector<Vec3> path = {Vec3(0.0, 0.0, 0.0), Vec3(0.0, 0.0, -0.1), Vec3(0.05, 0.0, -0.15)};
  const Vec3 tip(0.0, 0.0, -0.095);
  Mat3 frame;
  frame.col(0) = Vec3(0.0, 0.0, -1.0);
  frame.col(1) = Vec3(1.0, 0.0, 0.0);
  frame.col(2) = frame.col(0).cross(frame.col(1));
  magnetics::FieldModel epm;
  epm.add(magnetics::CylinderMagnet(50.8e-3, 101.6e-3, Vec3(0.0, 0.0, 1.48)), magnetics::Pose{}, "EPM");
  const auto field_at_tip = [&](const MagnetKeyframe& k) {
    const std::vector<magnetics::Pose> poses = {magnetics::Pose::from_axis(k.position, k.axis)};
    return magnetics::field(epm, poses, tip);
  };
  const auto degrees = [](const Vec3& a, const Vec3& b) {
    return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) / kDegToRad;
  };
  Navigator nav;
  nav.lateral = 0.7;
  Vec3 line;
  const Vec3 m = frame * Vec3::UnitY();  // +x
  const MagnetKeyframe pulled = navigate(nav, path, tip, frame, Vec3::UnitY(), 0.0, Vec3::Zero(), line);
  const Vec3 b_pull = field_at_tip(pulled);
  nav.skin_mode = Navigator::SkinMode::kTorque;
  const MagnetKeyframe turned = navigate(nav, path, tip, frame, Vec3::UnitY(), 0.0, Vec3::Zero(), line);
  const Vec3 b_turn = field_at_tip(turned);
  const Vec3 omega(0.0, -1.0, 0.0);
  std::printf(
      "  gradient mode: |B| %.1f mT, %.1f deg from m; torque mode: |B| %.1f mT, %.1f deg from m, m x B %.1f "
      "deg from the turning axis\n",
      1e3 * b_pull.norm(), degrees(b_pull, m), 1e3 * b_turn.norm(), degrees(b_turn, m),
      degrees(m.cross(b_turn), omega));
  EXPECT_LT(degrees(b_pull, m), 10.0);
  EXPECT_NEAR(degrees(b_turn, m), 90.0, 10.0);
  EXPECT_LT(degrees(m.cross(b_turn), omega), 10.0);
  EXPECT_GT(b_turn.norm(), 10e-3);  // a field that steers: tens of mT at 110 mm
  // The moment along y: the turn is about m, torque mode places the magnet as gradient mode does.
  const MagnetKeyframe along_axis = navigate(nav, path, tip, frame, Vec3::UnitZ(), 0.0, Vec3::Zero(), line);
  nav.skin_mode = Navigator::SkinMode::kGradient;
  const MagnetKeyframe along_axis_pull = navigate(nav, path, tip, frame, Vec3::UnitZ(), 0.0, Vec3::Zero(), line);
  EXPECT_TRUE(along_axis.axis.isApprox(along_axis_pull.axis, 1e-12));
  // A scene asks for it by name, for a skin only.
  const std::string text =
      text_of(std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes/bronchial_tree_skin_navigator.yaml");
  const std::string wrong = error_of(replaced(text, "lateral: 0.7}", "lateral: 0.7, mode: twist}"));
  EXPECT_NE(wrong.find("control.navigator.mode: must be gradient or torque"), std::string::npos) << wrong;
  const std::string fluid = error_of(
      replaced(text_of(std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes/bronchial_tree_generation4.yaml"),
               "boost_pressure: 42\n", "boost_pressure: 42\n    mode: torque\n"));
  EXPECT_NE(fluid.find("control.navigator.mode: steers a magnetic skin (robot.skin)"), std::string::npos) << fluid;
}

TEST(Experiment, TheNavigatorSteersTheSkinVineByTorqueIntoEitherMainBronchus) {
  // assets/scenes/bronchial_tree_skin_torque_navigator.yaml (thesis 4.7.4's skin MVR, steered automatically in
  // torque mode): unperturbed, it reaches the end of 0-0 and of 0-1 (7 of 8 perturbed trials with seed 1, 8 of 8
  // with seed 0, docs/experiments.md), every node inside the lumen.
  const std::filesystem::path file =
      std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes/bronchial_tree_skin_torque_navigator.yaml";
  const ExperimentScene loaded = load_experiment_scene(file);
  ASSERT_TRUE(loaded.navigator);
  EXPECT_EQ(loaded.navigator->skin_mode, Navigator::SkinMode::kTorque);
  const anatomy::CollisionWorld& world = loaded.anatomy->world;
  for (const std::string target : {"0-0", "0-1"}) {
    const ExperimentResult r = run_experiment(with_target(loaded, target));
    const Vec3 tip = r.final_state.tip();
    std::printf("  %s: %s at %.1f s, tip (%.1f, %.1f, %.1f) mm, %zu events\n", target.c_str(),
                r.success ? "reached" : "not reached", r.time_to_target, 1e3 * tip.x(), 1e3 * tip.y(), 1e3 * tip.z(),
                r.events.size());
    EXPECT_TRUE(r.success) << target;
    for (const Vec3& x : r.final_state.x) EXPECT_TRUE(world.contains(x)) << target << ": a node left the lumen";
  }
}

TEST(Experiment, EveryStepOfAGenerationFourBatchBalancesAndKeepsTheBodyInTheLumen) {
  // Issue 28's statics over a batch: the generation-4 scene's first trial towards each of its four targets (the
  // trials' own seeds, seed·1000003 + target·10007), every step recorded. Each step either converges or ends the run
  // (none may end so here); each converged body balances, |Σ(wall + friction + magnetic + gravity + clamp)| within
  // 1e-3 of its largest load (the Newton tolerance, a scaled gradient of 1e-7, leaves far less: the bound is the
  // issue's); and no node of any step leaves the lumen (the barrier's line search refuses every crossing).
  const std::filesystem::path file =
      std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes/bronchial_tree_generation4.yaml";
  const ExperimentScene loaded = load_experiment_scene(file);
  const anatomy::CollisionWorld& world = loaded.anatomy->world;
  const std::vector<std::string> targets = {"0-0-0-0-1", "0-0-1-1-0", "0-1-0-1-1", "0-1-1-0-0"};
  int steps = 0;
  int reached = 0;
  double worst = 0.0;
  for (std::size_t t = 0; t < targets.size(); ++t) {
    ExperimentScene scene = perturbed(with_target(loaded, targets[t]), loaded.seed * 1000003ULL + t * 10007ULL);
    scene.shape_interval = scene.dt;  // every step's body
    const ExperimentResult r = run_experiment(scene);
    EXPECT_TRUE(r.converged) << targets[t] << ": " << r.failure;
    EXPECT_EQ(r.failed_steps, 0) << targets[t];
    reached += r.success ? 1 : 0;
    for (const ExperimentSample& sample : r.samples) {
      worst = std::max(worst, sample.imbalance);
      EXPECT_LT(sample.imbalance, 1e-3) << targets[t] << " at " << sample.time << " s";
    }
    ASSERT_EQ(r.shapes.size(), r.samples.size()) << targets[t];
    int outside = 0;
    for (const ShapeSample& shape : r.shapes) {
      for (std::size_t i = 1; i < shape.nodes.size(); ++i) outside += world.contains(shape.nodes[i]) ? 0 : 1;
    }
    EXPECT_EQ(outside, 0) << targets[t] << ": node positions outside the lumen";
    steps += static_cast<int>(r.samples.size());
  }
  std::printf("  %d steps over 4 trials (%d reached): largest imbalance %.2e of the largest load\n", steps, reached,
              worst);
}

TEST(Experiment, TheNavigatorRaisesThePressureOnlyForAHeldTipAndOnlyBelowBurst) {
  // assets/scenes/bronchial_tree_generation4.yaml: boost_pressure 42 kPa after 0.5 s without growth, until the tip
  // has grown 5 mm. With the magnet's placement error widened to σ = 30 mm (the scene's is 2 mm), trial seed
  // 1·1000003 + 3·10007 + 2 towards 0-1-1-0-0 (the third `magvine trials --targets 0-0-0-0-1,0-1-0-1-1,0-0-1-1-0,
  // 0-1-1-0-0` runs towards it) is held near 7.7 s, boosted from 8.16 s, grows 5 mm and reaches the target at
  // 8.54 s. (Re-measured with the film's flattening, 2026-12-06: before it, the unperturbed vine towards 0-0-1-1-0
  // was held at its generation-4 entry near 7.9 s, and no trial of the scene's batch is held any more; before the
  // barrier model, towards 0-1-0-1-1 near 7 s.) Asserted from the samples: the pressure is the schedule's (35 kPa,
  // perturbed) or the boost's 42 kPa; every rise comes at least 0.5 s after the everted length last changed, every
  // fall once the length is 5 mm past where the rise began (edges of 2 mm: the first edge at or past it); and at
  // least one boost happens.
  const std::filesystem::path file =
      std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes/bronchial_tree_generation4.yaml";
  ExperimentScene wide = with_target(load_experiment_scene(file), "0-1-1-0-0");
  wide.perturbation.magnet_position_sd = 30e-3;
  ExperimentScene scene = perturbed(wide, 1 * 1000003ULL + 3 * 10007ULL + 2);
  ASSERT_TRUE(scene.navigator);
  EXPECT_DOUBLE_EQ(scene.navigator->boost_pressure, 42e3);
  scene.navigator->recover.retries = 0;  // the boost alone (the retractions: the test after the next)
  scene.duration = 9.0;
  const ExperimentResult r = run_experiment(scene);
  int rises = 0;
  double changed_at = 0.0;  // when the everted length last changed
  double previous_length = scene.vine.length;
  ASSERT_FALSE(r.samples.empty());
  const double schedule = r.samples.front().pressure;  // the trial's perturbed 35 kPa
  EXPECT_NEAR(schedule, 35e3, 1e3);
  double previous_pressure = schedule;
  double rise_length = 0.0;
  for (const ExperimentSample& s : r.samples) {
    EXPECT_TRUE(s.pressure == schedule || s.pressure == 42e3) << s.time << " s: " << s.pressure;
    if (s.pressure > previous_pressure) {
      ++rises;
      EXPECT_GE(s.time - changed_at, 0.5 - 1e-9) << "rise at " << s.time << " s";
      rise_length = previous_length;
    }
    if (s.pressure < previous_pressure) {
      EXPECT_GE(previous_length, rise_length + 5e-3 - 1e-12) << "fall at " << s.time << " s";
      EXPECT_LT(previous_length, rise_length + 5e-3 + 2e-3) << "fall at " << s.time << " s";
    }
    if (s.length != previous_length) changed_at = s.time;
    previous_length = s.length;
    previous_pressure = s.pressure;
  }
  std::printf("  %d boost(s) to 42 kPa by %.1f s, %.0f mm everted\n", rises, scene.duration, 1e3 * previous_length);
  EXPECT_GE(rises, 1);
  // 45 kPa is above this Ø4 mm film's burst (44.6 kPa with its diametric extension): refused at load.
  std::string text = text_of(file);
  const std::string error = error_of(replaced(text, "boost_pressure: 42", "boost_pressure: 45"));
  EXPECT_NE(error.find("bad.yaml:"), std::string::npos) << error;
  EXPECT_NE(error.find("control.navigator.boost_pressure: must be below the vine's burst pressure, 44.6 kPa"),
            std::string::npos)
      << error;
}

TEST(Experiment, AGenerationFourEntryIsEnteredWithEdgesOfTwoAndOneAndAHalfMillimetres) {
  // assets/scenes/bronchial_tree_generation4.yaml towards 0-0-1-1-0, unperturbed: entering the Ø4.5 mm branch bends
  // the Ø4 mm body by ~35°. The growth's energy balance runs over the last body diameter of growth: taken per edge,
  // the run with 1.5 mm edges was blocked at that entry (0.633 mJ stored against 0.269 mJ of work in one edge) while
  // the one with 2 mm edges got in. The outcome must not turn on the resolution.
  const std::filesystem::path file =
      std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes/bronchial_tree_generation4.yaml";
  for (const double edge : {2e-3, 1.5e-3}) {
    ExperimentScene scene = with_target(load_experiment_scene(file), "0-0-1-1-0");
    scene.growth.edge_length = edge;
    scene.navigator->recover.retries = 0;  // entered at the first try, not after a retraction
    const ExperimentResult r = run_experiment(scene);
    std::printf("  edges of %.1f mm: %s at %.2f s, %.0f mm everted\n", 1e3 * edge,
                r.success ? "reached" : "not reached", r.time_to_target, 1e3 * r.samples.back().length);
    for (const RunEvent& e : r.events) {
      std::printf("    %.2f s %s: %s\n", e.time, std::string(event_name(e.kind)).c_str(), e.detail.c_str());
    }
    EXPECT_TRUE(r.success) << "edges of " << edge << " m";
  }
}

TEST(Experiment, TheNavigatorBacksTheVineOutOfAWrongBranchAndGrowsItAgain) {
  // assets/scenes/bronchial_tree_generation4.yaml with the magnet's placement error widened to σ = 30 mm (the
  // scene's is 2 mm), the trial towards 0-1-1-0-0 that `magvine trials --targets 0-0-0-0-1,0-1-0-1-1,0-0-1-1-0,
  // 0-1-1-0-0` runs second towards it (seed 1·1000003 + 3·10007 + 1): the misplaced magnet turns the vine into the
  // wrong generation-3 daughter, 0-1-1-1, and on into 0-1-1-1-1, where it is held. Without retractions it stays
  // there. With control.navigator.recover (retries 3, past 4 mm, back 20 mm) the navigator deflates it to the
  // growth's retraction pressure, 5 kPa, once it has grown 4 mm into 0-1-1-1, pulls it back to 20 mm short of where
  // it left the path, gives the pressure back, and grows it again: the magnet's error is the same each time, so
  // each of the three tries turns into 0-1-1-1 again, and the run ends there.
  // Asserted from the samples: the length only falls at or below 5 kPa; the first retraction takes back 24 mm (4
  // past, 20 back) within an edge either way; the tip was in 0-1-1-1; all three retries were spent. (Re-measured
  // with the film's flattening, 2026-12-06: the trial this test used before it, 1·1000003 + 1·10007 + 2 towards
  // 0-1-0-1-1, now ends in a lag that does not settle after its first retraction (growth-and-contact.md, known
  // gaps); with the planes model, the scene's own trial 1·1000003 + 1·10007 towards 0-0-1-1-0 turned into 0-0-1-1-1
  // and reached the target after one retraction; with the barrier model none of the scene's 80 trials turns the
  // wrong way.)
  const std::filesystem::path file =
      std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes/bronchial_tree_generation4.yaml";
  ExperimentScene aimed = with_target(load_experiment_scene(file), "0-1-1-0-0");
  ASSERT_TRUE(aimed.navigator);
  EXPECT_EQ(aimed.navigator->recover.retries, 3);
  EXPECT_DOUBLE_EQ(aimed.growth.retraction_pressure, 5e3);
  aimed.perturbation.magnet_position_sd = 30e-3;
  ExperimentScene scene = perturbed(aimed, 1 * 1000003ULL + 3 * 10007ULL + 1);
  const auto describe = [](const char* label, const ExperimentResult& r) {
    std::printf("  %s: %s at %.2f s, %.0f mm everted, %d retraction(s)\n", label, r.success ? "reached" : "not reached",
                r.time_to_target, 1e3 * r.samples.back().length, r.recoveries);
    for (const RunEvent& e : r.events) {
      if (e.kind != EventKind::kRecover && e.kind != EventKind::kBlocked) continue;
      std::printf("    %.2f s %s: %s\n", e.time, std::string(event_name(e.kind)).c_str(), e.detail.c_str());
    }
  };
  scene.navigator->recover.retries = 0;
  const ExperimentResult stuck = run_experiment(scene);
  describe("without retractions", stuck);
  EXPECT_FALSE(stuck.success);
  EXPECT_EQ(stuck.recoveries, 0);
  ASSERT_TRUE(scene.anatomy->graph);
  ASSERT_GE(stuck.samples.back().branch, 0);
  EXPECT_EQ(scene.anatomy->graph->branches[static_cast<std::size_t>(stuck.samples.back().branch)].name, "0-1-1-1-1");

  scene.navigator->recover.retries = 3;
  const ExperimentResult r = run_experiment(scene);
  describe("with them", r);
  EXPECT_FALSE(r.success);
  EXPECT_EQ(r.recoveries, 3);
  bool wrong = false;
  double peak = 0.0;    // the everted length when the first retraction began
  double lowest = 1.0;  // and where it ended
  bool retracting = false;
  bool first_done = false;
  double previous = scene.vine.length;
  for (const ExperimentSample& s : r.samples) {
    wrong =
        wrong || (s.branch >= 0 && scene.anatomy->graph->branches[static_cast<std::size_t>(s.branch)].name == "0-1-1-1");
    if (s.length < previous) {
      EXPECT_LE(s.pressure, 5e3) << s.time << " s";
      if (!retracting && !first_done) peak = previous;
      retracting = true;
      if (!first_done) lowest = s.length;
    } else if (retracting && s.length > previous) {
      retracting = false;
      first_done = true;
    }
    previous = s.length;
  }
  const double h = 2e-3;  // the scene's edges: R
  std::printf("  first retraction: %.1f -> %.1f mm\n", 1e3 * peak, 1e3 * lowest);
  EXPECT_TRUE(wrong);
  EXPECT_NEAR(peak - lowest, 24e-3, h + 1e-9);

  // The count in metrics.json, and a retractions column in the trials' summary (absent where none happened: the
  // trials test above).
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "magvine_test_recovery";
  std::filesystem::remove_all(dir);
  write_experiment_outputs(scene, r, dir / "run");
  std::ifstream in(dir / "run" / "metrics.json");
  ASSERT_TRUE(in);
  EXPECT_EQ(nlohmann::json::parse(in).at("retractions").get<int>(), r.recoveries);
  TrialOutcome o;
  o.target = "0-1-1-0-0";
  o.success = r.success;
  o.time_to_target = r.time_to_target;
  o.everted_length = r.samples.back().length;
  o.retractions = r.recoveries;
  write_trial_outputs({o}, dir);
  std::ifstream md(dir / "summary.md");
  const std::string table(std::istreambuf_iterator<char>(md), {});
  EXPECT_NE(table.find("| SD [s] | retractions |\n|---|---|---|---|---|---|\n"), std::string::npos) << table;
  EXPECT_NE(table.find(" | " + std::to_string(r.recoveries) + " |\n"), std::string::npos) << table;
  std::filesystem::remove_all(dir);
}

TEST(Experiment, TheNavigatorBacksAHeldTipOutAndGrowsItInAgain) {
  // The other trigger of control.navigator.recover: a tip held for `after` (2 s) with nothing but the wall holding
  // it. With the magnet's placement error widened to σ = 30 mm (the scene's is 2 mm), trial seed 1·1000003 +
  // 1·10007 + 2 (the third towards 0-1-0-1-1) turns into 0-1-1 and is held at the end of 0-1-1-0-0, through the
  // boost; the wrong-branch trigger is put out of reach (`past` 100 mm) so that the held one acts. Asserted from the
  // samples: before the first retraction the everted length stood still for at least 2 s; the retraction takes it
  // back 20 mm (within an edge), shortening only at 5 kPa; then it grows again. (Re-measured with the film's
  // flattening, 2026-12-06: before it, trial 1·1000003 + 2 towards 0-0-1-1-0 with σ = 15 mm was held at the
  // generation-4 entry and reached the target after its retraction; with the film no trial of the scene's batch,
  // nor of it with σ = 15 or 30 mm, is held with its retries left, so none shows the retry that then succeeds. With
  // the planes model, trial 3·1000003 towards 0-0-0-0-1 of the scene as it is was held by the energy test.)
  const std::filesystem::path file =
      std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes/bronchial_tree_generation4.yaml";
  ExperimentScene wide = with_target(load_experiment_scene(file), "0-1-0-1-1");
  wide.perturbation.magnet_position_sd = 30e-3;
  ExperimentScene scene = perturbed(wide, 1 * 1000003ULL + 1 * 10007ULL + 2);
  ASSERT_TRUE(scene.navigator);
  scene.navigator->recover.past = 0.1;
  scene.duration = 16.0;
  const ExperimentResult r = run_experiment(scene);
  std::printf("  %s at %.2f s, %d retraction(s)\n", r.success ? "reached" : "not reached", r.time_to_target,
              r.recoveries);
  for (const RunEvent& e : r.events) {
    if (e.kind != EventKind::kRecover && e.kind != EventKind::kBlocked) continue;
    std::printf("    %.2f s %s: %s\n", e.time, std::string(event_name(e.kind)).c_str(), e.detail.c_str());
  }
  ASSERT_GE(r.recoveries, 1);
  double still_since = 0.0;  // when the everted length last changed before the first retraction
  double held = -1.0;        // how long it had stood still when the retraction began
  double from = 0.0;
  double lowest = 1.0;
  bool regrew = false;
  double previous = scene.vine.length;
  for (const ExperimentSample& s : r.samples) {
    if (held < 0.0 && s.length < previous) {
      held = s.time - scene.dt - still_since;
      from = previous;
    }
    if (held >= 0.0) {
      if (s.length > previous) {  // growing again
        regrew = true;
        break;
      }
      if (s.length < previous) {
        EXPECT_LE(s.pressure, 5e3) << s.time << " s";
      }
      lowest = std::min(lowest, s.length);
    } else if (s.length != previous) {
      still_since = s.time;
    }
    previous = s.length;
  }
  std::printf("  held %.2f s at %.1f mm, then back to %.1f mm\n", held, 1e3 * from, 1e3 * lowest);
  EXPECT_GE(held, 2.0 - 1e-9);
  EXPECT_NEAR(from - lowest, 20e-3, 2e-3 + 1e-9);  // back 20 mm, in whole 2 mm edges
  EXPECT_TRUE(regrew);
}

TEST(Experiment, ATargetOrABaseOutsideTheLumenIsRefusedBeforeTheRun) {
  // Checked by the collision world's ray parity when the run starts, before any step or output.
  const std::string text = demo_text();
  const std::string target =
      error_of(replaced(text, "position: [100, 24, 0], tolerance", "position: [100, 60, 0], tolerance"), true);
  EXPECT_NE(target.find("bad.yaml:"), std::string::npos) << target;
  EXPECT_NE(target.find("target.position: (100, 60, 0) mm is outside the lumen"), std::string::npos) << target;
  const std::string base = error_of(replaced(text, "position: [2, 0, -0.5]", "position: [2, 0, -9]"), true);
  EXPECT_NE(base.find("robot.base.position: (2, 0, -9) mm is outside the lumen"), std::string::npos) << base;
}

/// Runs `scene` aimed at `target` (a branch of generation ≥ 4 of its extracted graph) and expects success.
void expect_reaches(const ExperimentScene& scene, const std::string& target, const std::string& label) {
  const auto branch = anatomy::find_branch(*scene.anatomy->graph, target);
  ASSERT_TRUE(branch) << target;
  EXPECT_GE(scene.anatomy->graph->branches[static_cast<std::size_t>(*branch)].generation, 4);
  const ExperimentResult r = run_experiment(with_target(scene, target));
  std::cout << "[ " << label << " ] " << target << ": " << (r.success ? "reached" : "NOT reached") << " at "
            << r.time_to_target << " s, " << 1e3 * r.samples.back().length << " mm everted, " << r.events.size()
            << " events, " << r.runtime_s << " s of computing\n";
  for (const auto& e : r.events)
    std::cout << "   " << e.time << " s " << event_name(e.kind) << ": " << e.detail << "\n";
  EXPECT_TRUE(r.success) << target;
}

TEST(Experiment, TheNavigatorReachesGenerationFourInARealPhantomWithTheExtractedGraph) {
  // Issue 8: a real airway (the silicone phantom siliconmodel3, from ../shared/airways) with no graph of its own:
  // the scene extracts it, and the navigator steers the Ø4 mm fluid vine to two generation-4 branches, one per main
  // bronchus. The unperturbed run to 0-1-0-0-0 flips with round-off-sized changes of the model (it reached the
  // target until the fill's Maxwell-Garnett factor took the particles' susceptibility, 0.08 % less χ, and now
  // turns into a neighbouring branch), so for both targets the success rate over 8 perturbed trials (EPM ±2 mm,
  // pressure ±0.5 kPa, material ±5 %) is asserted: measured 6/8 and 6/8 (6/8 and 5/8 before that change); at least
  // half, the unperturbed 0-0-0-1-1 run besides.
  if (!std::filesystem::exists(kDemo.parent_path() / "../../../shared/airways/siliconmodel3_airway.stl")) {
    GTEST_SKIP() << "../shared/airways (siliconmodel3) is absent";
  }
  const ExperimentScene scene = load_experiment_scene(kDemo.parent_path() / "ct_phantom_navigator.yaml");
  ASSERT_TRUE(scene.anatomy->graph);
  EXPECT_EQ(anatomy::leaves(*scene.anatomy->graph).size(), 60u);  // the phantom's 60 leaves (VMTK's count)
  expect_reaches(scene, "0-0-0-1-1", "ct phantom");
  const std::vector<TrialOutcome> trials = run_trials(scene, {"0-0-0-1-1", "0-1-0-0-0"}, 8, 2);
  for (const std::string target : {"0-0-0-1-1", "0-1-0-0-0"}) {
    // A success is the tip within the target's tolerance; the target itself is a generation-4 branch.
    const auto branch = anatomy::find_branch(*scene.anatomy->graph, target);
    ASSERT_TRUE(branch.has_value()) << target;
    EXPECT_GE(scene.anatomy->graph->branches[static_cast<std::size_t>(*branch)].generation, 4) << target;
    const auto reached = std::count_if(trials.begin(), trials.end(),
                                       [&](const TrialOutcome& o) { return o.target == target && o.success; });
    std::printf("  %s: %ld of 8 perturbed trials reach it\n", target.c_str(), static_cast<long>(reached));
    EXPECT_GE(reached, 4) << target;
  }
}

TEST(Experiment, TheNavigatorReachesGenerationFourInAPatientsCtAirwayWithTheExtractedGraph) {
  // Issue 8 in a patient's airway: LIDC-IDRI-0525's marching-cubes mesh (../shared/airways), graph extracted.
  if (!std::filesystem::exists(kDemo.parent_path() / "../../../shared/airways/lidc0525_medmpd_p5_airway_mc.stl")) {
    GTEST_SKIP() << "../shared/airways (lidc0525) is absent";
  }
  const ExperimentScene scene = load_experiment_scene(kDemo.parent_path() / "ct_patient_navigator.yaml");
  ASSERT_TRUE(scene.anatomy->graph && scene.navigator);
  expect_reaches(scene, scene.navigator->target, "ct patient");
}

TEST(Experiment, ATautPathDropsAWiggleInsideItsClearanceAndCutsABendOnlyAsFarAsItsClearance) {
  // taut_path (camera guidance's dead reckoning): a 0.5 mm wiggle in a straight line with 1 mm of clearance
  // everywhere goes, the line straight and its length the chord (evenly spaced points, each within its clearance of
  // where it was); with no clearance nothing moves; a right-angle corner with 0.2 mm of clearance, its neighbours
  // with none, moves 0.2 mm along the bisector towards the inside (the middle of its neighbours lies 3.5 mm away).
  const double mm = 1e-3;
  const std::vector<Vec3> wiggle{Vec3(0, 0, 0), Vec3(mm, 0, 0), Vec3(2 * mm, 0.5 * mm, 0), Vec3(3 * mm, 0, 0),
                                 Vec3(4 * mm, 0, 0)};
  const std::vector<Vec3> straight = taut_path(wiggle, std::vector<double>(wiggle.size(), mm));
  double length = 0.0;
  for (std::size_t i = 0; i < straight.size(); ++i) {
    EXPECT_NEAR((straight[i] - Vec3(i * mm, 0, 0)).norm(), 0.0, 1e-5) << i;  // the sweeps stop under 1 µm a sweep
    if (i > 0) length += (straight[i] - straight[i - 1]).norm();
  }
  EXPECT_NEAR(length, 4 * mm, 1e-8);
  EXPECT_EQ(taut_path(wiggle, std::vector<double>(wiggle.size(), 0.0)), wiggle);
  const std::vector<Vec3> bend{Vec3(0, 0, 0), Vec3(5 * mm, 0, 0), Vec3(10 * mm, 0, 0), Vec3(10 * mm, 5 * mm, 0),
                               Vec3(10 * mm, 10 * mm, 0)};
  const std::vector<Vec3> cut = taut_path(bend, {0.0, 0.0, 0.2 * mm, 0.0, 0.0});
  EXPECT_NEAR((cut[2] - (bend[2] + 0.2 * mm * Vec3(-1, 1, 0).normalized())).norm(), 0.0, 1e-15);
  for (const std::size_t i : {0u, 1u, 3u, 4u}) EXPECT_EQ(cut[i], bend[i]);
  EXPECT_THROW(taut_path(bend, {0.0, 0.0}), std::invalid_argument);  // one clearance per point
}

TEST(Experiment, ANavigatorTargetGivenAsAPointSnapsToTheNearestBranchAndTheMetricsUseTheGraph) {
  // Issue 8: a target by point. 3 mm off the centreline of branch 0-0-1 of the tree: the navigator plans to 0-0-1
  // and succeeds within 1.5 radii of the snapped point; metrics.json then carries the graph's metrics.
  const std::filesystem::path file = kDemo.parent_path() / "bronchial_tree_navigator.yaml";
  const std::string text = text_of(file);
  const ExperimentScene by_name = load_experiment_scene(file);
  const auto b = anatomy::find_branch(*by_name.anatomy->graph, "0-0-1");
  ASSERT_TRUE(b);
  const auto& branch = by_name.anatomy->graph->branches[static_cast<std::size_t>(*b)];
  const Vec3 mid = by_name.anatomy->graph->nodes[branch.nodes[branch.nodes.size() / 2]].position;
  const Vec3 axis = (by_name.anatomy->graph->nodes[branch.nodes.back()].position -
                     by_name.anatomy->graph->nodes[branch.nodes.front()].position)
                        .normalized();
  const Vec3 point = mid + 3e-3 * axis.unitOrthogonal();
  std::ostringstream target;
  target << "target: [" << 1e3 * point.x() << ", " << 1e3 * point.y() << ", " << 1e3 * point.z() << "]";
  ExperimentScene scene =
      parse_experiment_scene(replaced(text, "target: \"0-0-1\"", target.str()), file.string(), file.parent_path());
  scene.videos.clear();  // the demo scene films itself; not needed here
  ASSERT_TRUE(scene.navigator);
  EXPECT_EQ(scene.navigator->target, "0-0-1");
  ASSERT_TRUE(scene.target);
  EXPECT_LT((*scene.target - mid).norm(), 0.5e-3);  // the snapped point: on the centreline beside `point`
  const ExperimentResult r = run_experiment(scene);
  EXPECT_TRUE(r.success);
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "magvine_test_point_target";
  std::filesystem::remove_all(dir);
  write_experiment_outputs(scene, r, dir);
  std::ifstream metrics_file(dir / "metrics.json");
  const auto m = nlohmann::json::parse(metrics_file);
  std::cout << "[ point target ] reached at " << r.time_to_target << " s; generation " << m["generation_reached"]
            << ", progress " << m["path_progress"] << ", tip to centreline "
            << 1e3 * m["tip_to_centreline_m"].get<double>() << " mm (mean "
            << 1e3 * m["mean_tip_to_centreline_m"].get<double>() << " mm)\n";
  EXPECT_EQ(m["generation_reached"], 2);
  // Success puts the tip within 1.5 radii of the snapped point, which lies about half-way along 0-0-1.
  EXPECT_GT(m["path_progress"].get<double>(), 0.8);
  EXPECT_LE(m["path_progress"].get<double>(), 1.0);
  // The tip stays inside the lumen: its distance to the centreline is below the lumen radius (≤ 9 mm, trachea).
  EXPECT_LT(m["tip_to_centreline_m"].get<double>(), 9e-3);
  EXPECT_LT(m["mean_tip_to_centreline_m"].get<double>(), 9e-3);
}

}  // namespace
}  // namespace magvine::scene

namespace magvine::scene {
namespace {

/// The generated tree to generation 1 meshed coarser than a scene's phantom (1.5 mm, 40 k triangles), written to
/// `dir` as tree.stl and tree.json (a run refits it every step), and the start of a scene on it: breathing with a
/// 2 s period, the carina 5 mm; the Ø5 mm fluid vine down the trachea; the EPM. The caller adds control and
/// simulation.
std::string breathing_tree_scene(const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir);
  const anatomy::Phantom tree =
      anatomy::make_bronchial_tree({.max_generation = 1, .clearance = 3e-3, .spacing = 1.5e-3});
  anatomy::write_stl(dir / "tree.stl", tree.mesh);
  anatomy::write_graph(dir / "tree.json", tree.graph);
  return R"(units: {length: mm, pressure: kPa}
anatomy:
  mesh: tree.stl
  graph: tree.json
  breathing: {period: 2, profile: 1, carina_amplitude: 5}
robot:
  kind: vine
  length: 5
  diameter: 5
  pressure: 35
  wall: {thickness: 0.038, youngs_modulus: 10000, density: 1100, strength: 2900}
  fill: {kind: magnetic_fluid, volume_fraction: 0.23}
  base: {position: [0, 0, -12], direction: [0, 0, -1], normal: [1, 0, 0]}
growth: {yield_pressure: 20}
magnets:
  - {kind: cylinder, diameter: 101.6, length: 101.6, polarisation: 1.48, position: [0, -250, -100], axis: [0, 1, 0]}
)";
}

// anatomy.breathing: the vine rides the moving wall. The navigator steers the Ø5 mm fluid vine down the generated
// tree's trachea (generation 1, meshed at 1.5 mm) into main bronchus 0-0, 35° off the vertical, the tether stopping
// it 30 mm in; then the airway breathes (period 2 s, the carina 5 mm, the bronchus up to 7 mm): the bronchus moves
// across its own axis and its wall pushes the body sideways. Every step converges and every node lies inside the
// moved airway (a world built from scratch on the mesh at that time) at every recorded shape; tip_trajectory's phase
// is Lujan's. (It passes without carrying the body by the displacement too, measured: the barrier shrinks a node's
// contact radius to the room it finds, so a wall moving 0.2 mm in a step does not strand it; the carry keeps the
// friction references on the material's wall point, so that breathing alone does not drag the wall along the body.)
TEST(Experiment, BreathingCarriesTheVineWithTheWall) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "magvine_breathing_test";
  const std::string text = breathing_tree_scene(dir) + R"(control:
  pressure: [[0, 35]]
  tether: [[0, 150]]
  navigator: {target: "0-0", magnet: 0, distance: 110}
simulation: {duration: 14, dt: 0.02, gravity: [0, 9.81, 0], stop_at_target: false}
outputs: {shape_interval: 0.25}
)";
  const ExperimentScene scene = parse_experiment_scene(text, "breathing.yaml", dir);
  ASSERT_TRUE(scene.breathing.has_value());
  std::printf("  airway %zu triangles\n", scene.anatomy->mesh().triangles.size());
  const anatomy::BreathingParams& b = *scene.breathing;
  const ExperimentResult r = run_experiment(scene);
  ASSERT_TRUE(r.converged) << r.failure;
  for (const ExperimentSample& s : r.samples) {
    ASSERT_NEAR(s.inspiration, anatomy::inspiration(b, s.time), 1e-15);
  }
  const anatomy::TriangleMesh& rest = scene.anatomy->mesh();
  int checked = 0;
  for (const ShapeSample& shape : r.shapes) {
    if (std::fmod(shape.time, 1.0) > 1e-9 && std::fmod(shape.time + 0.5, 1.0) > 1e-9) continue;  // every 0.5 s
    anatomy::TriangleMesh moved = rest;
    for (Vec3& v : moved.vertices) v += anatomy::breathing_displacement(b, v, shape.time);
    const anatomy::CollisionWorld world(moved);
    for (std::size_t i = 1; i < shape.nodes.size(); ++i) {
      EXPECT_TRUE(world.contains(shape.nodes[i])) << "node " << i << " at " << shape.time << " s";
    }
    ++checked;
  }
  EXPECT_GE(checked, 20);
  // In the bronchus, held by the tether, the body moves with the wall's breathing.
  const ExperimentSample& last = r.samples.back();
  std::printf("  %d shapes inside the moving airway; %.1f mm everted, the tip in branch %d\n", checked,
              1e3 * last.length, last.branch);
  EXPECT_NEAR(last.length, 0.15, 1e-6);
  EXPECT_EQ(scene.anatomy->graph->branches[static_cast<std::size_t>(last.branch)].name, "0-0");
}

TEST(Experiment, AGatedNavigatorGrowsTheVineOnlyNearExhalation) {
  // control.navigator.gate: {from: 0, to: 0.2}: the vine grows only while inspiration(t) ≤ 0.2 and never while the
  // window is shut. Lujan's profile with n = 1 and τ = 2 s: cos²(πt/τ) ≤ 0.2 for a share 1 − 2·acos(√0.2)/π = 29.5 %
  // of the time (closed form), so the gated vine grows about that share of what the ungated one does. The same
  // coarse tree as above.
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "magvine_gate_test";
  const std::string text = breathing_tree_scene(dir) + R"(control:
  pressure: [[0, 35]]
  navigator: {target: "0-0", magnet: 0, distance: 110, gate: {from: 0, to: 0.2}}
simulation: {duration: 4, dt: 0.02, gravity: [0, 9.81, 0]}
)";
  const ExperimentScene scene = parse_experiment_scene(text, "gate.yaml", dir);
  ASSERT_TRUE(scene.navigator && scene.navigator->gate);
  const ExperimentResult r = run_experiment(scene);
  ASSERT_TRUE(r.converged) << r.failure;
  // Growth in each step, against the window at the step's time (the phase the step's control was set at).
  double grown_open = 0.0;
  double grown_shut = 0.0;
  int open_steps = 0;
  for (std::size_t k = 1; k < r.samples.size(); ++k) {
    const double grown = r.samples[k].length - r.samples[k - 1].length;
    if (anatomy::inspiration(*scene.breathing, r.samples[k].time) <= 0.2) {
      grown_open += grown;
      ++open_steps;
    } else {
      grown_shut = std::max(grown_shut, grown);
    }
  }
  // The same run without the gate grows all the time: the gated vine grows about the window's share of that.
  const std::string ungated_text = std::regex_replace(text, std::regex(", gate: \\{from: 0, to: 0.2\\}"), "");
  const ExperimentScene ungated_scene = parse_experiment_scene(ungated_text, "gate.yaml", dir);
  ASSERT_FALSE(ungated_scene.navigator->gate);
  const ExperimentResult ungated = run_experiment(ungated_scene);
  ASSERT_TRUE(ungated.converged) << ungated.failure;
  const double free_growth = ungated.samples.back().length - ungated.samples.front().length;
  const double share = 1.0 - 2.0 * std::acos(std::sqrt(0.2)) / kPi;
  std::printf(
      "  grown %.1f mm in %d open steps, at most %.2g m in a shut one; ungated %.1f mm (the window's share of "
      "the time %.0f %%)\n",
      1e3 * grown_open, open_steps, grown_shut, 1e3 * free_growth, 100.0 * share);
  EXPECT_GT(grown_open, 10e-3);
  EXPECT_LE(grown_shut, 1e-9);  // the tether holds the everted length
  // Growing only inside the window: not above the window's share of the ungated growth plus a half (the tip's speed
  // varies along the path; the bound says the gate cut most of the growth).
  EXPECT_LT(grown_open, 1.5 * share * free_growth);
  // Without breathing there is no phase to gate to.
  const std::string still = std::regex_replace(text, std::regex("  breathing: \\{[^}]*\\}\n"), "");
  EXPECT_THROW((void)parse_experiment_scene(still, "gate.yaml", dir), InputError);
}

}  // namespace
}  // namespace magvine::scene
