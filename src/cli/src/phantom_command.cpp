// `magvine phantom KIND [--<parameter> VALUE ...] --out FILE.stl`: one subcommand per generated phantom kind, its
// options named like the metadata keys (unit suffix included: --gap-mm 3, --branch-angle-deg 35) and converted to SI
// here, at the I/O boundary.

#include "phantom_command.hpp"

#include <algorithm>
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

/// Adds the kind's options (anatomy::phantom_options: `gap_mm` as `--gap-mm VALUE` in mm, stored as SI), each showing
/// its default in file units.
void add_phantom_options(CLI::App* cmd, anatomy::PhantomParams& params) {
  for (const anatomy::PhantomOption& o : anatomy::phantom_options(params)) {
    std::string name = "--" + o.name;
    std::replace(name.begin(), name.end(), '_', '-');
    if (double* const* f = std::get_if<double*>(&o.field)) {
      double& field = **f;
      const double scale = o.scale;
      cmd->add_option_function<double>(
             name, [&field, scale](double v) { field = v * scale; }, o.help)
          ->default_str(format_default(field / scale));
    } else if (int* const* i = std::get_if<int*>(&o.field)) {
      cmd->add_option(name, **i, o.help)->capture_default_str();
    } else {
      cmd->add_option(name, *std::get<std::uint64_t*>(o.field), o.help)->capture_default_str();
    }
  }
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
  m_cmd = app.add_subcommand("phantom",
                             "generate a phantom: closed lumen STL (mm) + ground-truth airway graph + metadata (JSON)");
  m_cmd->require_subcommand(1);
  // The options keep pointers into m_params: reserve so that emplace_back never moves them.
  m_params.reserve(anatomy::phantom_kinds().size());
  for (const anatomy::PhantomKindInfo& info : anatomy::phantom_kinds()) {
    CLI::App* sub = m_cmd->add_subcommand(std::string(info.name), std::string(info.description));
    sub->add_option("--out", m_out, "output STL (mm); FILE.graph.json and FILE.meta.json are written beside it")
        ->required();
    m_params.emplace_back(info.kind, anatomy::default_params(info.kind));
    anatomy::PhantomParams& params = m_params.back().second;
    if (info.kind == PhantomKind::kBronchialTree) {
      sub->add_option("--table", m_table, "morphometric table: weibel_a | horsfield")->capture_default_str();
    }
    add_phantom_options(sub, params);
    if (info.kind == PhantomKind::kTube) sub->add_flag("--open", m_open, "leave both ends open (not watertight)");
    m_kinds.push_back(sub);
  }
}

bool PhantomCommand::parsed() const {
  return m_cmd != nullptr && m_cmd->parsed();
}

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
