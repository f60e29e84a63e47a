#include "platform_entry.hpp"

#include <cmath>
#include <variant>

#include "magvine/core/units.hpp"
#include "ranges.hpp"

namespace magvine::scene {

namespace {

/// Sintered N52 NdFeB [kg/m³] (manufacturers' data sheets give 7.50–7.65 g/cm³): the EPM's weight on the arm.
constexpr double kMagnetDensity = 7500.0;

/// `key` of `p` absent (the default), a map (its settings) or the word none (left out).
bool wanted(const YamlMap& p, const std::string& key) {
  if (!p.has(key)) return true;
  const YAML::Node n = p.node(key);
  if (n.IsScalar()) {
    if (n.as<std::string>() == "none") return false;
    p.fail(key, "must be a map of settings or none");
  }
  return true;
}

/// The trachea (the graph's root) of the scene's airway: its last node (the carina) and its direction.
void trachea_of(const anatomy::AirwayGraph& graph, Vec3& carina, Vec3& caudal) {
  for (const anatomy::AirwayBranch& b : graph.branches) {
    if (b.parent >= 0) continue;
    carina = graph.nodes[b.nodes.back()].position;
    caudal = (carina - graph.nodes[b.nodes.front()].position).normalized();
    return;
  }
}

}  // namespace

std::shared_ptr<const platform::PlatformModel> parse_platform(const YamlMap& p, const FileUnits& units,
                                                              const ExperimentScene& scene) {
  p.allow_only({"body", "table", "clearance", "up", "arms"});
  auto model = std::make_shared<platform::PlatformModel>();
  if (!scene.anatomy->graph) {
    p.fail("body",
           "the platform places the patient round the airway's trachea and carina, from the airway graph: a generated "
           "phantom's, or anatomy.graph (extract | FILE.json) for a mesh");
  }
  if (!scene.magnets) p.fail("arms", "the arms hold the scene's magnets, but it has none (magnets:)");
  Vec3 up;
  if (p.has("up")) {
    up = p.direction("up");
  } else if (scene.growth.gravity.norm() > 0.0) {
    up = -scene.growth.gravity.normalized();
  } else {
    p.fail("up", "is needed without gravity (simulation.gravity): which way the patient's front faces");
  }
  Vec3 carina = Vec3::Zero(), caudal = -Vec3::UnitZ();
  trachea_of(*scene.anatomy->graph, carina, caudal);
  if (std::abs(caudal.dot(up)) > 0.9) {
    p.fail(p.has("up") ? "up" : "body",
           "the trachea runs along the vertical (within 26°): the platform models a patient lying on the table");
  }
  // Torso: the median adult chest (Pheasant, Bodyspace: depth 250 mm; ANSUR II: breadth ≈ 330 mm, male), from the
  // shoulders (90 mm above the carina, which lies level with the sternal angle) 600 mm towards the hips.
  platform::TorsoModel torso;
  double above_carina = 0.09;
  const bool body = wanted(p, "body");
  if (body && p.has("body")) {
    const YamlMap b = p.map("body");
    b.allow_only({"breadth", "depth", "length", "above_carina"});
    if (b.has("breadth")) torso.breadth = b.quantity("breadth", units.len, Range{0.05, 2.0});
    if (b.has("depth")) torso.depth = b.quantity("depth", units.len, Range{0.05, 2.0});
    if (b.has("length")) torso.length = b.quantity("length", units.len, Range{0.1, 3.0});
    if (b.has("above_carina")) above_carina = b.quantity("above_carina", units.len, Range{0.0, 3.0});
    if (above_carina >= torso.length) b.fail("above_carina", "must be less than the torso's length");
  }
  platform::TableModel table;
  const bool with_table = wanted(p, "table");
  if (with_table && p.has("table")) {
    const YamlMap t = p.map("table");
    t.allow_only({"width", "length", "thickness"});
    if (t.has("width")) table.width = t.quantity("width", units.len, Range{0.1, 3.0});
    if (t.has("length")) table.length = t.quantity("length", units.len, Range{0.1, 5.0});
    if (t.has("thickness")) table.thickness = t.quantity("thickness", units.len, Range{0.005, 1.0});
  }
  platform::place_patient(carina, caudal, up, above_carina, torso, &table);
  if (body) model->body = torso;
  if (with_table) model->table = table;
  if (p.has("clearance")) model->clearance = p.quantity("clearance", units.len, Range{0.0, 1.0});
  model->gravity = scene.growth.gravity;

  // Arms: one by default, holding the navigator's magnet (or magnets[0]).
  std::vector<YamlMap> entries;
  if (p.has("arms")) {
    const YAML::Node list = p.node("arms");
    if (!list.IsSequence() || list.size() == 0 || list.size() > 2) p.fail("arms", "must be a list of one or two arms");
    for (std::size_t i = 0; i < list.size(); ++i) {
      entries.emplace_back(list[i], p.file(), p.key_path("arms") + "[" + std::to_string(i) + "]");
    }
  }
  const int default_magnet = scene.navigator ? scene.navigator->magnet : 0;
  // The first arm stands on the side of the scene's target (the navigator's or target:), where the magnet will work;
  // the patient's right without one.
  int target_side = 1;
  if (scene.target) target_side = (*scene.target - carina).dot(torso.frame.linear().col(0)) < 0.0 ? -1 : 1;
  const std::size_t count = entries.empty() ? 1 : entries.size();
  for (std::size_t i = 0; i < count; ++i) {
    platform::ArmMount mount;
    int side = i == 0 ? target_side : -target_side;
    bool side_fixed = false;
    double lateral = 0.55, below_top = 0.0, along = 0.0, holder = 0.05;
    bool radial = true;
    mount.magnet = default_magnet;
    // Home: upright (the iiwa's candle posture), clear of the patient, the table and another arm.
    mount.home.setZero();
    if (!entries.empty()) {
      const YamlMap& a = entries[i];
      a.allow_only({"magnet", "side", "lateral", "below_top", "along", "mount", "holder", "home"});
      mount.magnet = static_cast<int>(a.whole("magnet", 0, static_cast<long>(scene.magnets->size()) - 1));
      side_fixed = a.has("side");
      if (side_fixed) {
        side = a.choice("side", std::pair{std::string_view("right"), 1}, std::pair{std::string_view("left"), -1});
      }
      if (a.has("lateral")) lateral = a.quantity("lateral", units.len, Range{0.0, 5.0});
      if (a.has("below_top")) below_top = a.quantity("below_top", units.len, Range{-2.0, 2.0});
      if (a.has("along")) along = a.quantity("along", units.len, Range{-3.0, 3.0});
      if (a.has("mount")) {
        radial =
            a.choice("mount", std::pair{std::string_view("radial"), true}, std::pair{std::string_view("axial"), false});
      }
      if (a.has("holder")) holder = a.quantity("holder", units.len, Range{0.0, 1.0});
      if (a.has("home")) {
        const YAML::Node h = a.node("home");
        if (!h.IsSequence() || h.size() != platform::kArmJoints) a.fail("home", "must be 7 joint angles [deg]");
        for (int j = 0; j < platform::kArmJoints; ++j) {
          mount.home[j] = checked_number(h[static_cast<std::size_t>(j)], a.file(), a.key_path("home")) * kDegToRad;
          if (mount.home[j] < model->arm.q_min[j] || mount.home[j] > model->arm.q_max[j]) {
            a.fail("home", "joint " + std::to_string(j + 1) + " is outside its range");
          }
        }
      }
      for (std::size_t k = 0; k < i; ++k) {
        if (model->arms[k].magnet == mount.magnet) a.fail("magnet", "another arm holds this magnet");
      }
    }
    const auto* cylinder =
        std::get_if<magnetics::CylinderMagnet>(&scene.magnets->sources[static_cast<std::size_t>(mount.magnet)]);
    if (cylinder == nullptr) {
      const std::string why =
          "an arm holds a cylinder magnet (kind: cylinder); magnets[" + std::to_string(mount.magnet) + "] is not one";
      if (entries.empty()) p.fail("arms", why);
      entries[i].fail("magnet", why);
    }
    mount.magnet_radius = cylinder->radius();
    mount.magnet_length = cylinder->length();
    // Radial (default): the magnet's axis across the flange (along its x), its side `holder` from the flange, so that
    // any axis direction can face the patient from an arm outside (measured round a chest: 95 % of the placements
    // reachable from one side, half with the axial mount). Axial: the axis along the flange's z, its face `holder`
    // from the flange, the arm holding it from behind.
    mount.tool.flange_to_magnet = platform::Iso3::Identity();
    if (radial) {
      mount.tool.flange_to_magnet.linear() << 0, 0, 1, 1, 0, 0, 0, 1, 0;  // columns: x_m = y_f, y_m = z_f, z_m = x_f
      mount.tool.flange_to_magnet.translation() = Vec3(0, 0, holder + cylinder->radius());
    } else {
      mount.tool.flange_to_magnet.translation() = Vec3(0, 0, holder + 0.5 * cylinder->length());
    }
    mount.tool.mass = kMagnetDensity * cylinder->volume();
    mount.tool.com = mount.tool.flange_to_magnet.translation();
    const Vec3 at = carina + along * torso.frame.linear().col(2);
    mount.base = platform::arm_base_beside(torso, table, side, lateral, below_top, at);
    // An arm whose side the scene did not fix follows a trial's target to its side (magvine trials --targets).
    if (!side_fixed) mount.other_side = platform::arm_base_beside(torso, table, -side, lateral, below_top, at);
    model->arms.push_back(mount);
  }
  return model;
}

}  // namespace magvine::scene
