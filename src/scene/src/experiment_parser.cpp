// The experiment scene parser (docs/scenes.md: experiment scenes): one function per YAML section, each checking every
// number against its plausible range (ranges.hpp) and every derived quantity (the vine, the growth options, the
// placements of base, target and magnets) before anything runs.

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <initializer_list>
#include <sstream>

#include "anatomy_entry.hpp"
#include "experiment_internal.hpp"
#include "magnet_entries.hpp"
#include "magvine/anatomy/centerline.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/mesh_report.hpp"
#include "magvine/anatomy/phantom.hpp"
#include "magvine/config.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/keyframes.hpp"
#include "magvine/core/text.hpp"
#include "magvine/core/units.hpp"
#if MAGVINE_WITH_CT
#include "magvine/ct/import.hpp"
#endif
#include "magvine/scene/experiment_scene.hpp"
#include "magvine/scene/navigator.hpp"
#include "magvine/scene/video_plugin.hpp"
#include "platform_entry.hpp"
#include "ranges.hpp"
#include "robot_entries.hpp"
#include "yaml_reader.hpp"

namespace magvine::scene {
namespace {

constexpr double kMaxSteps = 1e7;  // duration / dt beyond this is a typo, not an experiment
constexpr const char* kRodHasNoPressure = "a pushed rod (robot.kind: rod) has no pressure";
const Unit kDegrees{kDegToRad, "deg"};

/// Refuses each of `keys` that `map` has, with `why` (a scene entry that does not apply: a pushed rod's pressure).
void refuse_keys(const YamlMap& map, std::initializer_list<const char*> keys, const std::string& why) {
  for (const char* key : keys) {
    if (map.has(key)) map.fail(key, why);
  }
}

/// `[[t, v], ...]` keyframes with increasing times; values in `unit`, within `value_range` (SI).
Schedule schedule_of(const YamlMap& parent, const std::string& key, const Unit& unit, const Range& value_range) {
  const YAML::Node list = parent.node(key);
  const std::string path = parent.key_path(key);
  if (!list.IsSequence() || list.size() == 0) parent.fail(key, "must be a list of [time, value] keyframes");
  Schedule s;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const YAML::Node k = list[i];
    const std::string at = path + "[" + std::to_string(i) + "]";
    if (!k.IsSequence() || k.size() != 2) parent.fail_at(k, at, "must be [time, value]");
    const double t = checked_quantity(checked_number(k[0], parent.file(), at + "[0]"), kSeconds, range::kTime,
                                      parent.file(), k[0], at + "[0]");
    const double v = checked_quantity(checked_number(k[1], parent.file(), at + "[1]"), unit, value_range, parent.file(),
                                      k[1], at + "[1]");
    if (!s.times.empty() && !(t > s.times.back())) parent.fail_at(k, at, "times must increase");
    s.times.push_back(t);
    s.values.push_back(v);
  }
  return s;
}

/// anatomy.phantom: a generated phantom at its defaults (a bronchial tree also takes max_generation).
std::shared_ptr<const SceneAnatomy> phantom_anatomy(const YamlMap& entry, AnatomyCache* cache) {
  entry.allow_only({"kind", "max_generation"});
  const std::string name = entry.text("kind");
  const auto kind = anatomy::parse_phantom_kind(name);
  if (!kind) {
    entry.fail("kind", "must be bronchial_tree, tube, y_bifurcation, s_bend or constriction (got '" + name + "')");
  }
  anatomy::PhantomParams params = anatomy::default_params(*kind);
  std::string key = "phantom " + name;
  if (entry.has("max_generation")) {
    auto* tree = std::get_if<anatomy::BronchialTreeParams>(&params);
    if (tree == nullptr) entry.fail("max_generation", "only a bronchial_tree takes max_generation");
    tree->max_generation = static_cast<int>(entry.whole("max_generation", 0, 10));
    key += " max_generation " + std::to_string(tree->max_generation);
  }
  const auto build = [&] {
    try {
      anatomy::Phantom ph = anatomy::make_phantom(params);
      return std::make_shared<const SceneAnatomy>(
          SceneAnatomy{"phantom " + name, std::move(ph.graph), true, anatomy::CollisionWorld(ph.mesh)});
    } catch (const InputError& e) {
      // The generator names its parameter; the scene's key is max_generation or the kind (its defaults).
      const std::string what = e.what();
      const bool generation = what.find("max_generation") != std::string::npos && entry.has("max_generation");
      entry.fail(generation ? "max_generation" : "kind", what);
    }
  };
  return cache != nullptr ? cache->get(key, build) : build();
}

/// anatomy.mesh (+ mesh_units, graph, graph_root): an imported mesh and its airway graph.
std::shared_ptr<const SceneAnatomy> mesh_anatomy(const YamlMap& entry, const FileUnits& units,
                                                 const std::filesystem::path& directory, AnatomyCache* cache) {
  const LengthUnit mesh_units = entry.has("mesh_units") ? length_unit_of(entry, "mesh_units") : units.length;
  const std::filesystem::path mesh = directory / entry.text("mesh");
  std::optional<Vec3> root;
  std::string graph;
  if (entry.has("graph")) {
    graph = entry.text("graph");
    if (entry.has("graph_root")) {
      if (graph != "extract") entry.fail("graph_root", "only with graph: extract");
      root = entry.vec3_quantity("graph_root", units.len, range::kCoordinate);
    }
  } else if (entry.has("graph_root")) {
    entry.fail("graph_root", "only with graph: extract");
  }
  std::ostringstream key;
  key.precision(17);
  key << "mesh " << std::filesystem::absolute(mesh).lexically_normal().string() << " units "
      << static_cast<int>(mesh_units) << " graph " << graph;
  if (root) key << " root " << root->x() << ' ' << root->y() << ' ' << root->z();
  const auto build = [&] {
    anatomy::TriangleMesh imported;
    bool closed = false;
    try {
      imported = anatomy::import_mesh(mesh, {.units = mesh_units}).mesh;
      closed = anatomy::analyse_mesh(imported).watertight;
    } catch (const InputError& e) {
      entry.fail("mesh", e.what());
    }
    // The airway graph of an imported mesh: extracted from it (anatomy/centerline.hpp), or read from a graph file.
    std::optional<anatomy::AirwayGraph> airway;
    if (!graph.empty()) {
      try {
        if (graph == "extract") {
          anatomy::CenterlineOptions options;
          if (root) options.root = *root;
          airway = anatomy::extract_airway_graph(imported, options);
        } else {
          airway = anatomy::read_graph(directory / graph);
        }
      } catch (const InputError& e) {
        entry.fail("graph", e.what());
      }
    }
    return std::make_shared<const SceneAnatomy>(
        SceneAnatomy{mesh.string(), std::move(airway), closed, anatomy::CollisionWorld(imported)});
  };
  return cache != nullptr ? cache->get(key.str(), build) : build();
}

/// anatomy.segmentation (+ label, graph_root): a CT label map imported as `magvine ct import` would (ct/import.hpp),
/// its graph extracted. Only with the CT module.
std::shared_ptr<const SceneAnatomy> segmentation_anatomy(const YamlMap& entry, const FileUnits& units,
                                                         const std::filesystem::path& directory, AnatomyCache* cache) {
  const std::filesystem::path file = directory / entry.text("segmentation");
  const int label = entry.has("label") ? static_cast<int>(entry.whole("label", -1'000'000, 1'000'000)) : 1;
  std::optional<Vec3> root;
  if (entry.has("graph_root")) root = entry.vec3_quantity("graph_root", units.len, range::kCoordinate);
#if MAGVINE_WITH_CT
  std::ostringstream key;
  key.precision(17);
  key << "segmentation " << std::filesystem::absolute(file).lexically_normal().string() << " label " << label;
  if (root) key << " root " << root->x() << ' ' << root->y() << ' ' << root->z();
  const auto build = [&] {
    ct::ImportOptions options;
    options.surface.label = label;
    if (root) options.graph.root = *root;
    try {
      ct::ImportResult r = ct::import_anatomy(file, options);
      const bool closed = r.report.watertight;
      return std::make_shared<const SceneAnatomy>(
          SceneAnatomy{file.string(), std::move(r.graph), closed, std::move(*r.world)});
    } catch (const InputError& e) {
      entry.fail("segmentation", e.what());
    }
  };
  return cache != nullptr ? cache->get(key.str(), build) : build();
#else
  (void)cache, (void)label, (void)root;  // parsed and checked all the same
  entry.fail("segmentation", "this magvine was built without the CT module (configure with -DMAGVINE_WITH_CT=ON)");
#endif
}

/// anatomy.breathing: the displacement field (anatomy/breathing.hpp), its entry and carina from the airway graph.
void parse_breathing(const YamlMap& b, const FileUnits& units, ExperimentScene& scene) {
  b.allow_only({"period", "profile", "carina_amplitude", "lower_amplitude", "lower_depth", "superior"});
  const std::optional<anatomy::AirwayGraph>& graph = scene.anatomy->graph;
  if (!graph || graph->branches.empty()) {
    b.fail("period", "breathing moves the airway from its carina down: the anatomy needs an airway graph");
  }
  anatomy::BreathingParams p;
  if (b.has("period")) p.period = b.quantity("period", kSeconds, range::kDuration);
  if (b.has("profile")) p.profile = static_cast<int>(b.whole("profile", 1, 10));
  if (b.has("carina_amplitude")) p.carina_amplitude = b.quantity("carina_amplitude", units.len, range::kSmallDistance);
  if (b.has("lower_amplitude")) p.lower_amplitude = b.quantity("lower_amplitude", units.len, range::kSmallDistance);
  if (b.has("lower_depth")) p.lower_depth = b.quantity("lower_depth", units.len, range::kDistance);
  if (b.has("superior")) p.superior = b.direction("superior");
  const anatomy::AirwayBranch& root = graph->branches.front();
  p.entry = graph->nodes[root.nodes.front()].position;
  p.carina = graph->nodes[root.nodes.back()].position;
  anatomy::check_breathing(p);
  scene.breathing = p;
}

/// anatomy: a generated phantom, a mesh file or a CT segmentation.
std::shared_ptr<const SceneAnatomy> parse_anatomy(const YamlMap& entry, const FileUnits& units,
                                                  const std::filesystem::path& directory, AnatomyCache* cache) {
  entry.allow_only({"phantom", "mesh", "mesh_units", "graph", "graph_root", "segmentation", "label", "breathing"});
  if (int(entry.has("phantom")) + int(entry.has("mesh")) + int(entry.has("segmentation")) != 1) {
    entry.fail("phantom", "give exactly one of phantom: {kind: ...}, mesh: FILE or segmentation: FILE.nii.gz");
  }
  if (entry.has("phantom")) {
    refuse_keys(entry, {"mesh_units", "graph", "graph_root", "label"}, "a generated phantom comes with its own graph");
    return phantom_anatomy(entry.map("phantom"), cache);
  }
  if (entry.has("segmentation")) {
    refuse_keys(entry, {"mesh_units", "graph"}, "a segmentation is read in its own mm and its graph is extracted");
    return segmentation_anatomy(entry, units, directory, cache);
  }
  refuse_keys(entry, {"label"}, "label belongs to segmentation: FILE");
  return mesh_anatomy(entry, units, directory, cache);
}

/// robot: the vine, or a rod pushed from the base (returned); and its base.
std::optional<robot::PushedRod> parse_robot(const YamlMap& robot, const FileUnits& units, ExperimentScene& scene) {
  const std::string kind = robot.text("kind");
  std::optional<robot::PushedRod> pushed_rod;
  if (kind == "rod") {
    robot::PushedRod r;
    r.body = parse_rod(robot, units, {"inserted", "insertion_speed"}, &r.radius);
    const double inserted = robot.has("inserted") ? robot.quantity("inserted", units.len, range::kBodyLength)
                                                  : std::min(r.body.length, 4.0 * r.radius);
    if (inserted > r.body.length) robot.fail("inserted", "must not exceed the rod's length");
    if (robot.has("insertion_speed")) {
      r.insertion_speed = robot.quantity("insertion_speed", Unit{units.len.si, units.len.name + "/s"}, range::kSpeed);
    }
    // The inserted length plays the vine's everted length (and its tether caps the insertion); no pressure.
    scene.vine = robot::VineParameters{};
    scene.vine.length = inserted;
    scene.vine.radius = r.radius;
    scene.vine.pressure = 0.0;
    pushed_rod = r;
  } else if (kind == "vine") {
    scene.vine = parse_vine(robot, units);
  } else {
    robot.fail("kind", "an experiment grows a vine (kind: vine) or pushes a rod (kind: rod); got '" + kind + "'");
  }
  const YamlMap base_map = robot.map("base");
  if (base_map.has("entry")) {
    // At the airway's entry: `entry` down the graph's root branch from its first node (where a CT cuts the trachea),
    // along the root's direction there.
    base_map.allow_only({"entry"});
    const std::optional<anatomy::AirwayGraph>& graph = scene.anatomy->graph;
    if (!graph || graph->branches.empty()) {
      base_map.fail("entry", "places the base on the airway graph's root: the anatomy needs a graph");
    }
    const double inset = base_map.quantity("entry", units.len, range::kSmallDistance);
    std::vector<Vec3> root;
    for (const std::uint32_t n : graph->branches.front().nodes) root.push_back(graph->nodes[n].position);
    const double length = anatomy::branch_length(*graph, 0);
    if (inset >= length) {
      base_map.fail("entry", printf_string("must be shorter than the root branch, %.1f mm", length / units.len.si));
    }
    scene.base_position = point_at_arc_length(root, inset);
    const Vec3 ahead = point_at_arc_length(root, std::min(length, inset + 10e-3)) - scene.base_position;
    const Vec3 t = ahead.normalized();
    const Vec3 n = t.unitOrthogonal();
    scene.base_frame.col(0) = t;
    scene.base_frame.col(1) = n;
    scene.base_frame.col(2) = t.cross(n);
    if (scene.anatomy->closed && !scene.anatomy->world.contains(scene.base_position)) {
      base_map.fail("entry", "puts the base outside the airway lumen: take a larger inset");
    }
    return pushed_rod;
  }
  const BasePose base = base_of(robot, units);
  scene.base_position = base.position;
  scene.base_frame = base.frame;
  return pushed_rod;
}

/// growth: the growth law and the insertion mode (a pushed rod refuses the pressure's keys).
void parse_growth(const YamlMap& g, const FileUnits& units, bool rod, ExperimentScene& scene) {
  for (const char* gone : {"contact", "max_incidence"}) {  // the planes contact model's (removed 2026-12-02)
    if (g.has(gone)) {
      g.fail(gone,
             "the planes contact model and its keys are gone: the barrier contact is the only one (drop this "
             "key)");
    }
  }
  g.allow_only({"mode", "yield_pressure", "length_yield", "turning_yield", "extensibility", "friction", "edge_length",
                "catheter", "magnetorheology", "retraction_pressure", "contact_distance", "friction_slip",
                "tissue_modulus", "flattening"});
  robot::GrowthOptions& o = scene.growth;
  if (g.has("flattening")) o.flattening = g.flag("flattening");
  if (g.has("tissue_modulus")) o.tissue_modulus = g.quantity("tissue_modulus", units.stress, range::kModulus);
  if (g.has("contact_distance")) o.contact_distance = g.quantity("contact_distance", units.len, range::kSpacing);
  if (g.has("friction_slip")) o.friction_slip = g.quantity("friction_slip", units.len, range::kSpacing);
  if (g.has("mode")) {
    o.mode = g.choice("mode", std::pair{std::string_view("eversion"), robot::InsertionMode::kEversion},
                      std::pair{std::string_view("pushed"), robot::InsertionMode::kPushed});
  }
  if (g.has("yield_pressure")) o.law.yield_pressure = g.quantity("yield_pressure", units.stress, range::kPressure);
  if (g.has("length_yield")) {
    o.law.length_yield =
        g.quantity("length_yield", Unit{units.stress.si / units.len.si, units.stress.name + "/" + units.len.name},
                   range::kLengthYield);
  }
  if (g.has("turning_yield")) {
    o.law.turning_yield =
        g.quantity("turning_yield", Unit{units.stress.si, units.stress.name + "/rad"}, range::kTurningYield);
  }
  if (g.has("extensibility")) {
    o.law.extensibility = g.quantity("extensibility", Unit{1e-6, "µm/(s·Pa)"}, range::kExtensibility);
  }
  if (g.has("friction")) o.friction = g.quantity("friction", kPlain, range::kFriction);
  if (g.has("edge_length")) o.edge_length = g.quantity("edge_length", units.len, range::kSpacing);
  if (g.has("catheter")) {
    if (o.mode != robot::InsertionMode::kPushed) g.fail("catheter", "a catheter tube is pushed: set mode: pushed");
    const YamlMap c = g.map("catheter");
    c.allow_only({"outer_diameter", "inner_diameter", "youngs_modulus", "density"});
    robot::CatheterTube tube;
    tube.outer_diameter = c.quantity("outer_diameter", units.len, range::kSectionSize);
    tube.inner_diameter = c.quantity("inner_diameter", units.len, Range{0.0, 1.0});
    if (!(tube.inner_diameter < tube.outer_diameter)) {
      c.fail("inner_diameter", "must satisfy 0 <= inner_diameter < outer_diameter");
    }
    tube.modulus = c.quantity("youngs_modulus", units.stress, range::kModulus);
    if (c.has("density")) tube.density = c.quantity("density", kKgPerM3, range::kDensity);
    o.catheter = tube;
  }
  if (g.has("magnetorheology")) {
    o.magnetorheology = g.flag("magnetorheology");
    if (o.magnetorheology && scene.vine.fill != robot::FillKind::kMagneticFluid) {
      g.fail("magnetorheology", "needs a magnetic-fluid fill (robot.fill.kind: magnetic_fluid)");
    }
  }
  if (g.has("retraction_pressure")) {
    o.retraction_pressure = g.quantity("retraction_pressure", units.stress, range::kPressure);
  }
  if (rod) {
    refuse_keys(
        g,
        {"catheter", "magnetorheology", "retraction_pressure", "yield_pressure", "length_yield", "turning_yield",
         "extensibility"},
        std::string(kRodHasNoPressure) + " or growth law: it is inserted at robot.insertion_speed up to the tether");
    if (o.mode != robot::InsertionMode::kPushed && g.has("mode")) g.fail("mode", "a rod is pushed (mode: pushed)");
  }
}

/// magnets: the sources, each clear of the anatomy at rest.
void parse_magnets(const YamlMap& top, const FileUnits& units, ExperimentScene& scene) {
  scene.magnets = parse_magnet_list(top, units.len);
  const YAML::Node list = top.node("magnets");
  for (std::size_t i = 0; i < scene.magnets->size(); ++i) {
    const magnetics::Pose& pose = scene.magnets->rest_poses[i];
    const std::string why =
        detail::overlap_problem(scene.anatomy->mesh(), *scene.magnets, i, pose.position, pose.rotation.col(2));
    if (!why.empty()) top.fail_at(list[i], "magnets[" + std::to_string(i) + "].position", why);
  }
}

/// One outputs.video entry (docs/scenes.md: videos).
VideoOutput video_of(const YamlMap& v, const FileUnits& units) {
  v.allow_only(
      {"camera", "size", "fov", "lens", "fps", "speed", "frames", "depth", "depth_range", "noise", "from", "up"});
  VideoOutput out;
  const std::string camera = v.text("camera");
  if (camera == "overview") {
    out.view = VideoOutput::View::kOverview;
    out.width = 640;
    out.height = 480;
    out.fov = 40.0 * kDegToRad;
    out.fisheye = false;
  } else if (camera != "tip") {
    v.fail("camera", "must be tip or overview, not '" + camera + "'");
  }
  if (v.has("size")) {
    const std::array<int, 2> size = v.pixel_size("size");
    out.width = size[0];
    out.height = size[1];
    if (out.width % 2 != 0 || out.height % 2 != 0) v.fail("size", "video codecs need even sides");
  }
  if (v.has("lens")) {
    const std::string lens = v.text("lens");
    if (lens != "fisheye" && lens != "pinhole") v.fail("lens", "must be fisheye or pinhole, not '" + lens + "'");
    out.fisheye = lens == "fisheye";
  }
  if (v.has("fov")) {
    out.fov = v.quantity("fov", kDegrees, Range{0.0, out.fisheye ? 2.0 * kPi : kPi, true, true});
  }
  if (out.fov >= (out.fisheye ? 2.0 * kPi : kPi) - 1e-9) {
    v.fail("fov", out.fisheye ? "a fisheye's field of view must be below 360 degrees"
                              : "a pinhole's field of view must be below 180 degrees");
  }
  if (v.has("fps")) out.fps = v.quantity("fps", kFramesPerSecond, range::kFrameRate);
  if (v.has("speed")) out.speed = v.quantity("speed", kPlain, range::kPlaybackSpeed);
  if (v.has("frames")) out.frames = v.flag("frames");
  if (v.has("depth")) {
    out.depth = v.flag("depth");
    if (out.depth && out.view != VideoOutput::View::kTip) v.fail("depth", "depth maps are the tip camera's");
  }
  if (v.has("depth_range")) out.depth_range = v.quantity("depth_range", units.len, range::kDistance);
  if (v.has("noise")) out.noise = v.quantity("noise", Unit{1.0, "grey levels"}, Range{0.0, 50.0});
  for (const char* key : {"from", "up"}) {
    if (!v.has(key)) continue;
    if (out.view != VideoOutput::View::kOverview) v.fail(key, "only the overview camera takes a viewing direction");
    (std::string(key) == "from" ? out.from : out.up) = v.direction(key);
  }
  if (out.from && out.up && out.from->cross(*out.up).norm() < 1e-6) v.fail("up", "must not be parallel to from");
  return out;
}

/// outputs: the shape interval and the videos.
void parse_outputs(const YamlMap& o, const FileUnits& units, ExperimentScene& scene) {
  o.allow_only({"shape_interval", "video"});
  if (o.has("shape_interval")) scene.shape_interval = o.quantity("shape_interval", kSeconds, range::kDuration);
  if (!o.has("video")) return;
  const YAML::Node list = o.node("video");
  if (list.IsSequence()) {
    for (std::size_t i = 0; i < list.size(); ++i) {
      scene.videos.push_back(
          video_of(YamlMap(list[i], o.file(), o.key_path("video") + "[" + std::to_string(i) + "]"), units));
    }
  } else {
    scene.videos.push_back(video_of(o.map("video"), units));
  }
  for (std::size_t i = 0; i < scene.videos.size(); ++i) {
    for (std::size_t k = 0; k < i; ++k) {
      if (scene.videos[k].view == scene.videos[i].view) {
        o.fail("video", "two " + scene.videos[i].name() + " videos would write the same file");
      }
    }
  }
}

/// simulation: duration, step, gravity, whether the run stops at the target.
void parse_simulation(const YamlMap& sim, ExperimentScene& scene) {
  sim.allow_only({"duration", "dt", "gravity", "stop_at_target"});
  if (sim.has("stop_at_target")) scene.stop_at_target = sim.flag("stop_at_target");
  scene.duration = sim.quantity("duration", kSeconds, range::kDuration);
  if (sim.has("dt")) scene.dt = sim.quantity("dt", kSeconds, range::kDuration);
  if (scene.duration / scene.dt > kMaxSteps) sim.fail("dt", "gives more than 10 million steps");
  if (sim.has("gravity")) scene.growth.gravity = sim.vec3_quantity("gravity", kMetresPerS2, range::kGravity);
}

/// A magnet's index in magnets: at `key` of `m`.
std::size_t magnet_index(const YamlMap& m, const std::string& key, const ExperimentScene& scene) {
  return static_cast<std::size_t>(m.whole(key, 0, static_cast<long>(scene.magnets->size()) - 1));
}

/// control.magnets: keyframed poses per magnet, each keyframe and each move between them clear of the anatomy.
void parse_magnet_keyframes(const YamlMap& control, const FileUnits& units, ExperimentScene& scene) {
  const YAML::Node list = control.node("magnets");
  if (!list.IsSequence()) control.fail("magnets", "must be a list of {magnet, keyframes}");
  if (!scene.magnets) control.fail("magnets", "keyframes for magnets, but the scene has no magnets: list");
  for (std::size_t i = 0; i < list.size(); ++i) {
    const YamlMap entry(list[i], control.file(), control.key_path("magnets[" + std::to_string(i) + "]"));
    entry.allow_only({"magnet", "keyframes"});
    const std::size_t index = magnet_index(entry, "magnet", scene);
    auto& keys = scene.magnet_keyframes[index];
    if (!keys.empty()) entry.fail("magnet", "this magnet already has keyframes");
    const YAML::Node frames = entry.node("keyframes");
    if (!frames.IsSequence() || frames.size() == 0) entry.fail("keyframes", "must be a list of {time, position, axis}");
    for (std::size_t k = 0; k < frames.size(); ++k) {
      const YamlMap f(frames[k], control.file(), entry.key_path("keyframes[" + std::to_string(k) + "]"));
      f.allow_only({"time", "position", "axis"});
      MagnetKeyframe key;
      key.time = f.quantity("time", kSeconds, range::kTime);
      if (!keys.empty() && !(key.time > keys.back().time)) f.fail("time", "times must increase");
      key.position = f.vec3_quantity("position", units.len, range::kCoordinate);
      key.axis = f.direction("axis");
      const anatomy::TriangleMesh& mesh = scene.anatomy->mesh();
      const std::string why = keys.empty()
                                  ? detail::overlap_problem(mesh, *scene.magnets, index, key.position, key.axis)
                                  : detail::path_overlap_problem(mesh, *scene.magnets, index, keys.back(), key);
      if (!why.empty()) f.fail("position", why);
      keys.push_back(key);
    }
  }
}

/// control.commands, the gamepad script, turned into keyframes: each command ramps its channel (a magnet's pose, the
/// pressure, the tether) linearly from its value at `time` to the new one over `over` seconds.
void parse_commands(const YamlMap& control, const FileUnits& units, ExperimentScene& scene) {
  const YAML::Node list = control.node("commands");
  if (!list.IsSequence() || list.size() == 0) control.fail("commands", "must be a list of {time, ...} commands");
  const bool pressure_keys = !scene.pressure.times.empty();
  const bool tether_keys = scene.tether.has_value();
  Schedule pressure;
  pressure.times = {0.0};
  pressure.values = {scene.vine.pressure};
  Schedule tether;
  tether.times = {0.0};
  tether.values = {scene.vine.length};
  bool grows = false;
  std::vector<std::vector<MagnetKeyframe>> poses;
  if (scene.magnets) poses.resize(scene.magnets->size());
  double last_time = 0.0;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const YamlMap c(list[i], control.file(), control.key_path("commands[" + std::to_string(i) + "]"));
    c.allow_only({"time", "over", "magnet", "move", "rotate", "pressure", "grow"});
    const double t = c.quantity("time", kSeconds, range::kTime);
    if (t < last_time) c.fail("time", "commands must be in time order");
    last_time = t;
    const double over = c.has("over") ? c.quantity("over", kSeconds, range::kDuration) : 0.5;
    const int actions = static_cast<int>(c.has("move")) + static_cast<int>(c.has("rotate")) +
                        static_cast<int>(c.has("pressure")) + static_cast<int>(c.has("grow"));
    if (actions != 1) c.fail("time", "each command does exactly one of move, rotate, pressure, grow");
    // Appends the ramp (t, from) → (t + over, to) to a schedule; the channel must be idle by t.
    const auto ramp = [&](Schedule& sch, double to, const std::string& key) {
      if (t < sch.times.back()) c.fail(key, "starts before the previous command on this channel ends");
      const double from = sch.values.back();
      if (t > sch.times.back()) {
        sch.times.push_back(t);
        sch.values.push_back(from);
      }
      sch.times.push_back(t + over);
      sch.values.push_back(to);
    };
    if (c.has("pressure")) {
      if (pressure_keys) c.fail("pressure", "the pressure has keyframes in control.pressure already");
      if (scene.growth.rod) refuse_keys(c, {"pressure"}, kRodHasNoPressure);
      const double step = c.quantity("pressure", units.stress, Range{-range::kPressure.max, range::kPressure.max});
      const double to = pressure.values.back() + step;
      if (to < 0.0) c.fail("pressure", "would take the pressure (from robot.pressure) below 0");
      if (to > range::kPressure.max) {
        c.fail("pressure", "would take the pressure above " + describe(range::kPressure, units.stress));
      }
      ramp(pressure, to, "pressure");
      continue;
    }
    if (c.has("grow")) {
      if (tether_keys) c.fail("grow", "the tether has keyframes in control.tether already");
      const double step = c.quantity("grow", units.len, Range{-range::kBodyLength.max, range::kBodyLength.max});
      const double to = tether.values.back() + step;
      if (to < 0.0) c.fail("grow", "would pull the tether back beyond the base");
      if (to > range::kBodyLength.max)
        c.fail("grow", "would release more than " + describe(range::kBodyLength, units.len));
      ramp(tether, to, "grow");
      grows = true;
      continue;
    }
    // move or rotate a magnet
    if (!scene.magnets) c.fail(c.has("move") ? "move" : "rotate", "moves a magnet, but the scene has no magnets: list");
    const std::size_t m = c.has("magnet") ? magnet_index(c, "magnet", scene) : 0;
    if (!scene.magnet_keyframes[m].empty()) c.fail("magnet", "this magnet has keyframes in control.magnets already");
    auto& keys = poses[m];
    if (keys.empty()) {
      const magnetics::Pose& rest = scene.magnets->rest_poses[m];
      keys.push_back({0.0, rest.position, rest.rotation.col(2)});
    }
    const std::string key = c.has("move") ? "move" : "rotate";
    if (t < keys.back().time) c.fail(key, "starts before the previous command on this magnet ends");
    MagnetKeyframe next = keys.back();
    if (t > keys.back().time) {
      next.time = t;
      keys.push_back(next);
    }
    next.time = t + over;
    if (c.has("move")) {
      next.position +=
          c.vec3_quantity("move", units.len, Range{-2.0 * range::kCoordinate.max, 2.0 * range::kCoordinate.max});
      if (!range::kCoordinate.contains(next.position.cwiseAbs().maxCoeff())) {
        c.fail("move", "would take the magnet outside " + describe(range::kCoordinate, units.len));
      }
    } else {
      const YamlMap r = c.map("rotate");
      r.allow_only({"axis", "angle"});
      const Vec3 axis = r.direction("axis");
      next.axis = Eigen::AngleAxisd(r.quantity("angle", kDegrees, Range{-1e3 * kPi, 1e3 * kPi}), axis) * next.axis;
    }
    const std::string why = detail::path_overlap_problem(scene.anatomy->mesh(), *scene.magnets, m, keys.back(), next);
    if (!why.empty()) c.fail(key, why);
    keys.push_back(next);
  }
  if (pressure.times.size() > 1) scene.pressure = pressure;
  if (grows) scene.tether = tether;
  for (std::size_t m = 0; m < poses.size(); ++m) {
    if (!poses[m].empty()) scene.magnet_keyframes[m] = std::move(poses[m]);
  }
}

/// control.field: [[time, [bx, by, bz]], ...] in s and T.
FieldSchedule field_schedule_of(const YamlMap& control) {
  const YAML::Node list = control.node("field");
  const std::string path = control.key_path("field");
  if (!list.IsSequence() || list.size() == 0) control.fail("field", "must be a list of [time, [bx, by, bz]] keyframes");
  FieldSchedule s;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const YAML::Node k = list[i];
    const std::string at = path + "[" + std::to_string(i) + "]";
    if (!k.IsSequence() || k.size() != 2 || !k[1].IsSequence() || k[1].size() != 3) {
      control.fail_at(k, at, "must be [time, [bx, by, bz]] (s, T)");
    }
    const double t = checked_quantity(checked_number(k[0], control.file(), at + "[0]"), kSeconds, range::kTime,
                                      control.file(), k[0], at + "[0]");
    Vec3 b;
    for (int c = 0; c < 3; ++c) {
      const YAML::Node v = k[1][static_cast<std::size_t>(c)];
      b[c] = checked_quantity(checked_number(v, control.file(), at + "[1]"), kTesla, range::kField, control.file(), v,
                              at + "[1]");
    }
    if (!s.times.empty() && !(t > s.times.back())) control.fail_at(k, at, "times must increase");
    s.times.push_back(t);
    s.values.push_back(b);
  }
  return s;
}

/// control: the pressure and tether schedules, the uniform field, the magnets' keyframes and the gamepad script (the
/// navigator below).
void parse_control(const YamlMap& control, const FileUnits& units, ExperimentScene& scene) {
  control.allow_only({"pressure", "tether", "field", "magnets", "navigator", "commands"});
  if (control.has("field")) scene.uniform_field = field_schedule_of(control);
  if (control.has("pressure")) {
    if (scene.growth.rod) refuse_keys(control, {"pressure"}, kRodHasNoPressure);
    scene.pressure = schedule_of(control, "pressure", units.stress, range::kPressure);
  }
  if (control.has("tether")) scene.tether = schedule_of(control, "tether", units.len, range::kSmallDistance);
  if (scene.magnets) scene.magnet_keyframes.resize(scene.magnets->size());
  if (control.has("magnets")) parse_magnet_keyframes(control, units, scene);
  if (control.has("commands")) parse_commands(control, units, scene);
  if (scene.pressure.times.empty()) {  // neither keyframes nor commands: held at robot.pressure
    scene.pressure.times = {0.0};
    scene.pressure.values = {scene.vine.pressure};
  }
  // A schedule's pressure above the vine's burst pressure is an outcome (a burst event), not an input error: a
  // scene may script a burst.
}

/// control.navigator.recover.
Navigator::Recovery parse_recovery(const YamlMap& r, const FileUnits& units, const ExperimentScene& scene) {
  r.allow_only({"retries", "past", "after", "back", "speed"});
  Navigator::Recovery rec;
  rec.retries = static_cast<int>(r.whole("retries", 0, 100));
  if (r.has("past")) rec.past = r.quantity("past", units.len, range::kDistance);
  if (r.has("after")) rec.after = r.quantity("after", kSeconds, range::kDuration);
  if (r.has("back")) rec.back = r.quantity("back", units.len, range::kDistance);
  if (r.has("speed")) rec.speed = r.quantity("speed", Unit{units.len.si, units.len.name + "/s"}, range::kPositiveSpeed);
  if (scene.growth.rod) r.fail("retries", "a pushed rod is withdrawn by its tether schedule, not by the navigator");
  if (rec.retries > 0 && scene.growth.retraction_pressure < 0.0) {
    r.fail("retries", "the navigator retracts a deflated vine: set growth.retraction_pressure (e.g. 5 kPa)");
  }
  return rec;
}

/// A planning problem's file at `key` (relative to the scene's folder): N finite numbers in mm, whitespace
/// apart, and no more; `needs` and `more` finish the messages for too few (or bad) and too many numbers.
template <std::size_t N>
std::array<double, N> planning_numbers(const YamlMap& t, const std::string& key, const std::filesystem::path& directory,
                                       const char* file_kind, const std::string& needs, const std::string& more) {
  const std::filesystem::path file = directory / t.text(key);
  std::istringstream in(read_text_file(file.string(), file_kind));
  std::array<double, N> m{};
  for (double& v : m) {
    if (!(in >> v) || !std::isfinite(v) || std::abs(v) > 1e4) t.fail(key, file.string() + ": " + needs);
  }
  std::string rest;
  if (in >> rest) t.fail(key, file.string() + ": " + more);
  return m;
}

/// A nodule file at `nodule`: three numbers in mm (Med-MPD's target.txt).
Vec3 nodule_file(const YamlMap& t, const std::filesystem::path& directory) {
  const auto x = planning_numbers<3>(t, "nodule", directory, "nodule file",
                                     "needs three finite numbers in mm (a point), as Med-MPD's target.txt",
                                     "more than three numbers (a point in mm)");
  return 1e-3 * Vec3(x[0], x[1], x[2]);
}

/// A planning problem's start pose at `stop` (Med-MPD's startN.txt: a 4×4 homogeneous matrix by rows, 16 numbers,
/// lengths in mm): its position, the translation column [m].
Vec3 pose_file_position(const YamlMap& t, const std::filesystem::path& directory) {
  const auto m = planning_numbers<16>(t, "stop", directory, "start pose file",
                                      "needs 16 finite numbers (a 4x4 pose by rows, mm), as Med-MPD's startN.txt",
                                      "more than 16 numbers (a 4x4 pose by rows, mm)");
  if (m[12] != 0.0 || m[13] != 0.0 || m[14] != 0.0 || m[15] != 1.0) {
    t.fail("stop", (directory / t.text("stop")).string() + ": the last row of a 4x4 pose must be 0 0 0 1");
  }
  return 1e-3 * Vec3(m[3], m[7], m[11]);
}

/// control.navigator.guidance: the oracle (the tip's position read; the default) or the tip camera.
std::optional<Navigator::Camera> parse_guidance(const YamlMap& g, const FileUnits& units) {
  g.allow_only({"mode", "size", "fov", "noise", "min_area", "junction_window", "frames"});
  const bool camera = g.choice<bool>("mode", {"oracle", false}, {"camera", true});
  if (!camera) {
    refuse_keys(g, {"size", "fov", "noise", "min_area", "junction_window", "frames"},
                "belongs to camera guidance (mode: camera)");
    return std::nullopt;
  }
  if (!video_plugin_built()) {
    g.fail("mode",
           "camera guidance renders the tip camera: this magvine was built without the render module "
           "(MAGVINE_WITH_RENDER=ON)");
  }
  Navigator::Camera c;
  if (g.has("size")) c.size = static_cast<int>(g.whole("size", 32, 1024));
  if (g.has("fov")) c.fov = g.quantity("fov", Unit{kDegToRad, "deg"}, Range{0.0, 180.0 * kDegToRad, true, true});
  if (g.has("noise")) c.noise = g.quantity("noise", kPlain, Range{0.0, 64.0});
  if (g.has("min_area")) c.min_area = g.quantity("min_area", kPlain, Range{0.0, 0.5, true});
  if (g.has("junction_window")) c.junction_window = g.quantity("junction_window", units.len, range::kDistance);
  if (g.has("frames")) c.frames = g.flag("frames");
  return c;
}

/// control.navigator: its target on the airway graph, its magnet and its settings.
void parse_navigator(const YamlMap& n, const FileUnits& units, const std::filesystem::path& directory,
                     ExperimentScene& scene) {
  n.allow_only({"target", "magnet", "distance", "min_distance", "max_distance", "lead", "interval", "deflate_pressure",
                "deflate_time", "junction_distance", "lateral", "mode", "boost_pressure", "boost_after", "boost_length",
                "recover", "guidance", "gate"});
  const std::optional<anatomy::AirwayGraph>& graph = scene.anatomy->graph;
  if (!graph) {
    n.fail("target",
           "the navigator plans on an airway graph: a generated phantom's, or anatomy.graph (extract | "
           "FILE.json) for a mesh");
  }
  if (!scene.magnets) n.fail("magnet", "the navigator moves a magnet, but the scene has no magnets: list");
  Navigator nav;
  if (n.node("target").IsMap()) {
    // A nodule outside the airway: the stop from which a straight needle reaches it (anatomy/biopsy_plan.hpp).
    const YamlMap t = n.map("target");
    t.allow_only({"nodule", "radius", "max_needle", "max_angle", "needle", "aim_time", "stop"});
    anatomy::BiopsyOptions options;
    options.tool_radius = scene.growth.rod ? scene.growth.rod->radius : scene.vine.radius;
    if (t.has("max_needle")) options.max_needle = t.quantity("max_needle", units.len, range::kDistance);
    if (t.has("max_angle")) {
      options.max_angle = t.quantity("max_angle", Unit{kDegToRad, "deg"}, Range{kDegToRad, 90.0 * kDegToRad});
    }
    // The nodule: a point, or a planning problem's file of three numbers in mm (Med-MPD's target.txt).
    const Vec3 nodule = t.node("nodule").IsScalar() ? nodule_file(t, directory)
                                                    : t.vec3_quantity("nodule", units.len, range::kCoordinate);
    if (scene.anatomy->closed && scene.anatomy->world.contains(nodule)) {
      t.fail("nodule", "lies inside the airway lumen; a biopsy target lies in the tissue outside it");
    }
    // A given stop: a point, or a planning problem's start pose file; its nearest node the tool fits to.
    if (t.has("stop")) {
      if (t.has("max_needle") || t.has("max_angle")) {
        t.fail("stop", "a given stop is taken as given: max_needle and max_angle limit the planner's own choice");
      }
      options.stop = t.node("stop").IsScalar() ? pose_file_position(t, directory)
                                               : t.vec3_quantity("stop", units.len, range::kCoordinate);
    }
    const anatomy::BiopsyPlan plan = anatomy::plan_biopsy(*graph, scene.anatomy->world, nodule, options);
    if (!plan.found) t.fail(t.has("stop") ? "stop" : "nodule", plan.why);
    nav.target_branch = plan.branch;
    nav.target = graph->branches[static_cast<std::size_t>(plan.branch)].name;
    scene.target = plan.start;
    scene.target_tolerance = 1.5 * plan.lumen_radius;
    Biopsy biopsy;
    biopsy.nodule = nodule;
    biopsy.plan = plan;
    biopsy.given_stop = options.stop;
    if (t.has("radius")) biopsy.radius = t.quantity("radius", units.len, range::kSectionSize);
    if (t.has("aim_time")) biopsy.aim_time = t.quantity("aim_time", kSeconds, range::kTime);
    if (t.has("needle")) {
      const YamlMap m = t.map("needle");
      m.allow_only({"length", "diameter", "force", "friction", "puncture_depth", "max_slide", "speed", "increment"});
      robot::NeedleTool& tool = biopsy.needle;
      if (m.has("length")) tool.length = m.quantity("length", units.len, range::kBodyLength);
      if (m.has("diameter")) tool.diameter = m.quantity("diameter", units.len, range::kSectionSize);
      if (m.has("force")) tool.cutting_force = m.quantity("force", Unit{1.0, "N"}, range::kForce);
      if (m.has("friction")) tool.shaft_friction = m.quantity("friction", Unit{1e3, "N/mm"}, range::kForcePerLength);
      if (m.has("puncture_depth")) tool.puncture_depth = m.quantity("puncture_depth", units.len, range::kDistance);
      if (m.has("max_slide")) tool.max_slide = m.quantity("max_slide", units.len, range::kDistance);
      if (m.has("speed"))
        tool.speed = m.quantity("speed", Unit{units.len.si, units.len.name + "/s"}, range::kPositiveSpeed);
      if (m.has("increment")) tool.increment = m.quantity("increment", units.len, range::kDistance);
    }
    scene.biopsy = biopsy;
  } else if (n.node("target").IsSequence()) {
    // A point: snapped to the nearest centreline; success within 1.5 lumen radii of the snapped point.
    const anatomy::CentrelinePoint at =
        anatomy::nearest_centreline_point(*graph, n.vec3_quantity("target", units.len, range::kCoordinate));
    nav.target_branch = at.branch;
    nav.target = graph->branches[static_cast<std::size_t>(at.branch)].name;
    scene.target = at.position;
    scene.target_tolerance = 1.5 * at.radius;
  } else {
    nav.target = n.text("target");
    const auto branch = anatomy::find_branch(*graph, nav.target);
    if (!branch) n.fail("target", "no branch '" + nav.target + "' in the airway graph (names like 0-1-0)");
    nav.target_branch = *branch;
  }
  if (n.has("magnet")) nav.magnet = static_cast<int>(magnet_index(n, "magnet", scene));
  if (!scene.magnet_keyframes[static_cast<std::size_t>(nav.magnet)].empty()) {
    n.fail("magnet", "this magnet is keyframed in control.magnets; the navigator moves it itself");
  }
  if (n.has("min_distance")) nav.min_distance = n.quantity("min_distance", units.len, range::kDistance);
  if (n.has("max_distance")) nav.max_distance = n.quantity("max_distance", units.len, range::kDistance);
  if (nav.max_distance < nav.min_distance) n.fail("max_distance", "must be >= min_distance");
  nav.distance = n.has("distance") ? n.quantity("distance", units.len, range::kDistance) : nav.min_distance;
  if (n.has("lead")) nav.lead = n.quantity("lead", units.len, range::kDistance);
  if (n.has("interval")) nav.interval = n.quantity("interval", kSeconds, range::kDuration);
  if (n.has("lateral")) nav.lateral = n.quantity("lateral", kPlain, Range{0.0, 1.0});
  if (n.has("mode")) {
    const std::string mode = n.text("mode");
    if (mode == "torque") {
      nav.skin_mode = Navigator::SkinMode::kTorque;
    } else if (mode != "gradient") {
      n.fail("mode", "must be gradient or torque");
    }
    if (!robot::has_magnetic_skin(scene.vine)) {
      n.fail("mode", "steers a magnetic skin (robot.skin) with a remanence; a fill or a rod follows the magnet's pull");
    }
  }
  if (n.has("deflate_pressure"))
    nav.deflate_pressure = n.quantity("deflate_pressure", units.stress, range::kPositivePressure);
  if (n.has("deflate_time")) nav.deflate_time = n.quantity("deflate_time", kSeconds, range::kDuration);
  if (n.has("junction_distance")) nav.junction_distance = n.quantity("junction_distance", units.len, range::kDistance);
  if (scene.growth.rod) refuse_keys(n, {"boost_pressure", "deflate_pressure"}, kRodHasNoPressure);
  if (n.has("boost_pressure")) {
    nav.boost_pressure = n.quantity("boost_pressure", units.stress, range::kPositivePressure);
    const double burst = robot::burst_pressure(scene.vine);
    if (!scene.growth.catheter && nav.boost_pressure >= burst) {
      n.fail("boost_pressure",
             printf_string("must be below the vine's burst pressure, %.1f kPa (hoop stress P·R/t at the wall strength)",
                           burst / kKpaToPa));
    }
  }
  if (n.has("boost_after")) nav.boost_after = n.quantity("boost_after", kSeconds, range::kDuration);
  if (n.has("boost_length")) nav.boost_length = n.quantity("boost_length", units.len, range::kDistance);
  if (n.has("recover")) nav.recover = parse_recovery(n.map("recover"), units, scene);
  if (n.has("guidance")) nav.camera = parse_guidance(n.map("guidance"), units);
  if (n.has("gate")) {
    const YamlMap g = n.map("gate");
    g.allow_only({"from", "to"});
    if (!scene.breathing) g.fail("from", "gates to the breathing phase: the anatomy needs breathing: {...}");
    Navigator::Gate gate;
    if (g.has("from")) gate.from = g.quantity("from", kPlain, Range{0.0, 1.0});
    if (g.has("to")) gate.to = g.quantity("to", kPlain, Range{0.0, 1.0});
    if (gate.to <= gate.from) g.fail("to", "must be above from (inspiration fractions, 0 exhalation to 1 full)");
    nav.gate = gate;
  }
  scene.navigator = nav;
}

/// target: a point and a tolerance.
void parse_target(const YamlMap& t, const FileUnits& units, ExperimentScene& scene) {
  t.allow_only({"position", "tolerance"});
  scene.target = t.vec3_quantity("position", units.len, range::kCoordinate);
  scene.target_tolerance = t.quantity("tolerance", units.len, range::kDistance);
}

/// trials: the perturbations of `magvine trials`.
void parse_trials(const YamlMap& t, const FileUnits& units, ExperimentScene& scene) {
  t.allow_only({"magnet_position_sd", "pressure_sd", "material_spread"});
  TrialPerturbation& p = scene.perturbation;
  if (t.has("magnet_position_sd")) p.magnet_position_sd = t.quantity("magnet_position_sd", units.len, Range{0.0, 1.0});
  if (t.has("pressure_sd")) p.pressure_sd = t.quantity("pressure_sd", units.stress, range::kPressure);
  if (t.has("material_spread")) p.material_spread = t.quantity("material_spread", kPlain, Range{0.0, 0.3, false, true});
}

/// Where `p` is, for messages: "(x, y, z) mm".
std::string where(const Vec3& p, const Unit& len) {
  std::ostringstream s;
  s.precision(4);
  s << "(" << p.x() / len.si << ", " << p.y() / len.si << ", " << p.z() / len.si << ") " << len.name;
  return s.str();
}

/// What only the whole scene can check: the growth options against the vine (robot::check_growth), and the base and
/// target inside the lumen of closed anatomy (ray parity through the collision world).
void check_scene(const YamlMap& top, const FileUnits& units, const ExperimentScene& scene) {
  try {
    robot::check_growth(scene.vine, scene.growth, scene.base_frame);
  } catch (const robot::VineParameterError& e) {
    const std::string& p = e.parameter();
    if (p == "base") top.map("robot").fail("base", e.what());
    if (p == "gravity") top.map("simulation").fail("gravity", e.what());
    if (top.has("growth") && top.map("growth").has(p)) top.map("growth").fail(p, e.what());
    const YamlMap robot = top.map("robot");
    robot.fail(robot.has(p) ? p : "kind", e.what());
  }
  if (!scene.anatomy->closed) return;
  const anatomy::CollisionWorld& world = scene.anatomy->world;
  if (!world.contains(scene.base_position)) {
    top.map("robot").map("base").fail(
        "position", where(scene.base_position, units.len) + " is outside the lumen of the " + scene.anatomy->label);
  }
  if (scene.target && !world.contains(*scene.target)) {
    const std::string why = where(*scene.target, units.len) + " is outside the lumen of the " + scene.anatomy->label;
    if (top.has("target")) top.map("target").fail("position", why);
    top.map("control").map("navigator").fail("target", why);
  }
}

}  // namespace

std::shared_ptr<const SceneAnatomy> detail::parse_anatomy_entry(const YamlMap& entry, const FileUnits& units,
                                                                const std::filesystem::path& directory,
                                                                AnatomyCache* cache) {
  return parse_anatomy(entry, units, directory, cache);
}

double Schedule::at(double time) const {
  const KeyframeSpan s = keyframe_span(times.size(), time, [&](std::size_t k) { return times[k]; });
  return lerp(values[s.before], values[s.after], s.u);
}

Vec3 FieldSchedule::at(double time) const {
  const KeyframeSpan s = keyframe_span(times.size(), time, [&](std::size_t k) { return times[k]; });
  return (1.0 - s.u) * values[s.before] + s.u * values[s.after];
}

bool is_experiment_scene(const std::filesystem::path& file) {
  const YAML::Node root = parse_yaml(read_text_file(file.string(), "scene file"), file.string());
  return root && root.IsMap() && static_cast<bool>(root["anatomy"]);
}

ExperimentScene parse_experiment_scene(const std::string& text, const std::string& file_label,
                                       const std::filesystem::path& directory, AnatomyCache* cache) {
  const YAML::Node root = parse_yaml(text, file_label);
  if (!root || root.IsNull()) throw InputError(file_label, 0, "", "empty scene file");
  const YamlMap top(root, file_label, "");
  top.allow_only({"units", "seed", "anatomy", "robot", "growth", "magnets", "control", "simulation", "target", "trials",
                  "outputs", "platform"});
  const FileUnits units = file_units(top);

  ExperimentScene scene;
  scene.file = file_label;
  scene.seed = seed_of(top, scene.seed);
  scene.anatomy = parse_anatomy(top.map("anatomy"), units, directory, cache);
  if (top.map("anatomy").has("breathing")) parse_breathing(top.map("anatomy").map("breathing"), units, scene);
  const std::optional<robot::PushedRod> rod = parse_robot(top.map("robot"), units, scene);
  if (top.has("growth")) parse_growth(top.map("growth"), units, rod.has_value(), scene);
  if (rod) {
    scene.growth.mode = robot::InsertionMode::kPushed;
    scene.growth.rod = *rod;
    scene.growth.max_length = rod->body.length;  // inserted up to its whole length
  }
  if (top.has("magnets")) parse_magnets(top, units, scene);
  if (top.has("outputs")) parse_outputs(top.map("outputs"), units, scene);
  parse_simulation(top.map("simulation"), scene);
  const YamlMap control = top.map("control");
  parse_control(control, units, scene);
  if (control.has("navigator")) parse_navigator(control.map("navigator"), units, directory, scene);
  if (top.has("target")) parse_target(top.map("target"), units, scene);
  if (top.has("trials")) parse_trials(top.map("trials"), units, scene);
  if (scene.navigator && !scene.target) detail::aim_at(scene, scene.navigator->target_branch);
  if (top.has("platform")) scene.platform = parse_platform(top.map("platform"), units, scene);
  if (scene.platform && scene.navigator && scene.navigator->camera) {
    control.map("navigator")
        .map("guidance")
        .fail("mode", "camera guidance through the platform's arms is not built yet");
  }
  check_scene(top, units, scene);
  return scene;
}

ExperimentScene load_experiment_scene(const std::filesystem::path& file, AnatomyCache* cache) {
  return parse_experiment_scene(read_text_file(file.string(), "scene file"), file.string(), file.parent_path(), cache);
}

}  // namespace magvine::scene
