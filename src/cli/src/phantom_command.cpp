// `magvine phantom KIND [--<parameter> VALUE ...] --out FILE.stl`: one subcommand per generated phantom kind, its
// options named like the metadata keys (unit suffix included: --gap-mm 3, --branch-angle-deg 35) and converted to SI
// here, at the I/O boundary.

#include "phantom_command.hpp"

#include <chrono>
#include <cstdio>
#include <iostream>
#include <sstream>

#include "magvine/anatomy/mesh_report.hpp"
#include "magvine/anatomy/phantom.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/check.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"

namespace magvine::cli {
namespace {

using anatomy::PhantomKind;

std::string format_default(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", value);
  return text;
}

/// Adds `--name VALUE` [file unit] that stores VALUE·scale [SI] into `field`, showing the default in file units.
void add_scaled(CLI::App* cmd, const std::string& name, double& field, double scale, const std::string& help) {
  cmd->add_option_function<double>("--" + name, [&field, scale](double v) { field = v * scale; }, help)
      ->default_str(format_default(field / scale));
}

/// Option names of the metadata (`gap_mm`) with dashes (`--gap-mm`).
void add_length(CLI::App* cmd, const std::string& name, double& field, const std::string& help) {
  add_scaled(cmd, name + "-mm", field, kMmToM, help + " [mm]");
}
void add_angle(CLI::App* cmd, const std::string& name, double& field, const std::string& help) {
  add_scaled(cmd, name + "-deg", field, kDegToRad, help + " [deg]");
}
void add_number(CLI::App* cmd, const std::string& name, double& field, const std::string& help) {
  add_scaled(cmd, name, field, 1.0, help);
}

void add_tree_options(CLI::App* cmd, anatomy::BronchialTreeParams& p, std::string& table) {
  cmd->add_option("--table", table, "morphometric table: weibel_a | horsfield")->capture_default_str();
  cmd->add_option("--max-generation", p.max_generation, "deepest generation (trachea = 0)")->capture_default_str();
  add_number(cmd, "flow-ratio", p.flow_ratio, "Kitaoka flow-dividing ratio r in [0.2, 0.5]; 0.5 = symmetric");
  add_number(cmd, "diameter-exponent", p.diameter_exponent, "Kitaoka diameter exponent n in [2, 4]");
  add_number(cmd, "length-jitter", p.length_jitter, "relative half-range of the branch-length jitter, [0, 0.5)");
  add_angle(cmd, "angle-jitter", p.angle_jitter, "half-range of the branching-angle jitter");
  add_angle(cmd, "rotation-jitter", p.rotation_jitter, "half-range of the jitter on the 90 deg plane rotation");
  cmd->add_option("--seed", p.seed, "seed of the jitter")->capture_default_str();
  add_length(cmd, "clearance", p.clearance, "minimum wall gap between non-adjacent branches");
  add_number(cmd, "blend-factor", p.blend_factor, "junction blend radius / branch radius, [0, 1]");
  add_length(cmd, "spacing", p.spacing, "meshing grid spacing");
}

void add_tube_options(CLI::App* cmd, anatomy::TubeParams& p, bool& open) {
  add_length(cmd, "diameter", p.diameter, "inner diameter");
  add_length(cmd, "length", p.length, "length along +x");
  cmd->add_option("--segments", p.segments, "vertices around the circumference")->capture_default_str();
  cmd->add_flag("--open", open, "leave both ends open (not watertight)");
}

void add_y_options(CLI::App* cmd, anatomy::YBifurcationParams& p) {
  add_length(cmd, "parent-diameter", p.parent_diameter, "parent tube diameter");
  add_length(cmd, "parent-length", p.parent_length, "first graph node to the bifurcation");
  add_length(cmd, "daughter-diameter", p.daughter_diameter, "daughter diameter");
  add_length(cmd, "daughter-length", p.daughter_length, "bifurcation to the blind end");
  add_angle(cmd, "branch-angle", p.branch_angle, "each daughter's angle to the parent axis");
  add_number(cmd, "blend-factor", p.blend_factor, "junction blend radius / daughter radius");
  add_length(cmd, "spacing", p.spacing, "meshing grid spacing");
}

void add_s_bend_options(CLI::App* cmd, anatomy::SBendParams& p) {
  add_length(cmd, "length", p.length, "channel length along x");
  add_length(cmd, "width", p.width, "channel width along y");
  add_length(cmd, "height", p.height, "channel height along z");
  add_length(cmd, "obstacle-thickness", p.obstacle_thickness, "obstacle size along x");
  add_length(cmd, "obstacle-reach", p.obstacle_reach, "how far each obstacle reaches from its side wall");
  add_length(cmd, "first-obstacle-x", p.first_obstacle_x, "centre of the first obstacle (from the -y wall)");
  add_length(cmd, "second-obstacle-x", p.second_obstacle_x, "centre of the second obstacle (from the +y wall)");
  add_length(cmd, "edge-rounding", p.edge_rounding, "rounding radius of the channel's edges");
  add_length(cmd, "spacing", p.spacing, "meshing grid spacing");
}

void add_constriction_options(CLI::App* cmd, anatomy::ConstrictionParams& p) {
  add_length(cmd, "diameter", p.diameter, "tube inner diameter");
  add_length(cmd, "length", p.length, "tube length along x");
  add_length(cmd, "gap", p.gap, "slot width at the constriction");
  add_length(cmd, "constriction-length", p.constriction_length, "jaw length along x");
  add_length(cmd, "constriction-x", p.constriction_x, "jaw centre along x");
  add_length(cmd, "jaw-rounding", p.jaw_rounding, "rounding radius of the jaw edges");
  add_length(cmd, "spacing", p.spacing, "meshing grid spacing");
}

std::string volume_text(const anatomy::MeshReport& report) {
  if (!report.volume) return "open";
  std::ostringstream s;
  s.precision(4);
  s << *report.volume * 1e6 << " mL";  // m³ → mL (cm³)
  return s.str();
}

}  // namespace

void PhantomCommand::attach(CLI::App& app) {
  m_cmd = app.add_subcommand(
      "phantom", "generate a phantom: closed lumen STL (mm) + ground-truth airway graph + metadata (JSON)");
  m_cmd->require_subcommand(1);
  // The options keep pointers into m_params: reserve so that emplace_back never moves them.
  m_params.reserve(anatomy::phantom_kinds().size());
  for (const anatomy::PhantomKindInfo& info : anatomy::phantom_kinds()) {
    CLI::App* sub = m_cmd->add_subcommand(std::string(info.name), std::string(info.description));
    sub->add_option("--out", m_out, "output STL (mm); FILE.graph.json and FILE.meta.json are written beside it")
        ->required();
    m_params.emplace_back(info.kind, anatomy::default_params(info.kind));
    anatomy::PhantomParams& params = m_params.back().second;
    switch (info.kind) {
      case PhantomKind::kBronchialTree:
        add_tree_options(sub, std::get<anatomy::BronchialTreeParams>(params), m_table);
        break;
      case PhantomKind::kTube:
        add_tube_options(sub, std::get<anatomy::TubeParams>(params), m_open);
        break;
      case PhantomKind::kYBifurcation:
        add_y_options(sub, std::get<anatomy::YBifurcationParams>(params));
        break;
      case PhantomKind::kSBend:
        add_s_bend_options(sub, std::get<anatomy::SBendParams>(params));
        break;
      case PhantomKind::kConstriction:
        add_constriction_options(sub, std::get<anatomy::ConstrictionParams>(params));
        break;
    }
    m_kinds.push_back(sub);
  }
}

bool PhantomCommand::parsed() const { return m_cmd != nullptr && m_cmd->parsed(); }

int PhantomCommand::run() {
  std::size_t index = 0;
  while (index < m_kinds.size() && !m_kinds[index]->parsed()) ++index;
  MAGVINE_ASSERT(index < m_kinds.size());
  const PhantomKind kind = m_params[index].first;
  anatomy::PhantomParams params = m_params[index].second;
  const std::string where = "phantom " + std::string(anatomy::to_string(kind));
  if (auto* tree = std::get_if<anatomy::BronchialTreeParams>(&params)) {
    const auto table = anatomy::parse_airway_table(m_table);
    if (!table) throw InputError("--table", 0, "", "must be weibel_a or horsfield (got '" + m_table + "')");
    tree->table = *table;
  }
  if (auto* tube = std::get_if<anatomy::TubeParams>(&params)) tube->capped = !m_open;
  const std::filesystem::path out(m_out);
  if (out.extension() != ".stl" && out.extension() != ".STL") {
    throw InputError("--out", 0, "", "must name an .stl file (got '" + m_out + "')");
  }

  const auto start = std::chrono::steady_clock::now();
  const anatomy::Phantom phantom = anatomy::make_phantom(params);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!out.parent_path().empty()) create_output_directory(out.parent_path());
  anatomy::write_phantom(phantom, out);

  const anatomy::MeshReport report = anatomy::analyse_mesh(phantom.mesh);
  const Vec3 size_mm = (report.bbox.max - report.bbox.min) / kMmToM;
  std::cout << where << ": " << phantom.mesh.triangles.size() << " triangles, " << phantom.graph.branches.size()
            << " branches, " << size_mm.x() << " x " << size_mm.y() << " x " << size_mm.z() << " mm, "
            << (report.watertight ? "watertight" : "open") << ", genus " << report.genus << ", volume "
            << volume_text(report) << " (generated in " << seconds << " s)\n"
            << "  mesh     " << out.string() << '\n'
            << "  graph    " << anatomy::phantom_graph_path(out).string() << '\n'
            << "  metadata " << anatomy::phantom_meta_path(out).string() << '\n';
  return 0;
}

}  // namespace magvine::cli
