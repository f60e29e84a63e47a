#include "render_command.hpp"

#include <cmath>
#include <filesystem>
#include <iostream>

#include "commands.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "magvine/scene/video_plugin.hpp"

namespace magvine::cli {

void RenderCommand::attach(CLI::App& app) {
  m_cmd = app.add_subcommand("render", "one image of an airway mesh from a camera: the endoscope's view (PNG, and its "
                                       "16-bit depth) or the semi-transparent overview");
  m_cmd->add_option("mesh", m_mesh, "mesh file (STL, OBJ, PLY, glTF/GLB, OFF, ...)")->required();
  m_cmd->add_option("--units", m_units, "unit of the file's coordinates and of --eye, --look, --depth-range: "
                                        "mm | cm | m")->capture_default_str();
  m_cmd->add_option("--eye", m_eye, "camera position X,Y,Z")->delimiter(',')->expected(3)->required();
  m_cmd->add_option("--look", m_look, "point looked at X,Y,Z")->delimiter(',')->expected(3)->required();
  m_cmd->add_option("--up", m_up, "image up direction (default 0,0,1)")->delimiter(',')->expected(3);
  m_cmd->add_option("--view", m_view, "endoscope | overview")->check(CLI::IsMember({"endoscope", "overview"}))
      ->capture_default_str();
  m_cmd->add_option("--lens", m_lens, "fisheye | pinhole (default: fisheye for the endoscope, pinhole otherwise)")
      ->check(CLI::IsMember({"fisheye", "pinhole"}));
  m_cmd->add_option("--fov", m_fov, "field of view across the width [degrees] (default 110 endoscope, 40 overview)");
  m_cmd->add_option("--size", m_size, "W,H in pixels (default 320,320 endoscope, 640,480 overview)")
      ->delimiter(',')->expected(2);
  m_cmd->add_option("--out", m_out, "the image (.png)")->required();
  m_cmd->add_option("--depth", m_depth, "the endoscope's z-depth as a 16-bit PNG");
  m_cmd->add_option("--depth-range", m_depth_range, "depth at level 65535, in --units (default 100 mm)");
}

bool RenderCommand::parsed() const { return m_cmd != nullptr && m_cmd->parsed(); }

int RenderCommand::run() {
  const bool endoscope = m_view == "endoscope";
  const double unit = metres_per(parse_units_option(m_units));
  const auto png = [](const std::string& path, const char* option) {
    if (std::filesystem::path(path).extension() != ".png") throw InputError(option, 0, "", path + " is not a .png path");
  };
  png(m_out, "--out");
  if (!m_depth.empty()) {
    png(m_depth, "--depth");
    if (!endoscope) throw InputError("--depth", 0, "", "depth maps are the endoscope view's");
  }
  if (!(m_depth_range > 0.0 && std::isfinite(m_depth_range))) throw InputError("--depth-range", 0, "", "must be > 0");
  scene::MeshImageRequest request;
  request.eye = Vec3(m_eye[0], m_eye[1], m_eye[2]) * unit;
  request.look = Vec3(m_look[0], m_look[1], m_look[2]) * unit;
  request.up = Vec3(m_up[0], m_up[1], m_up[2]);
  request.endoscope = endoscope;
  request.fisheye = m_lens.empty() ? endoscope : m_lens == "fisheye";
  request.fov = (m_fov > 0.0 ? m_fov : endoscope ? 110.0 : 40.0) * kDegToRad;
  request.width = m_size.empty() ? (endoscope ? 320 : 640) : m_size[0];
  request.height = m_size.empty() ? (endoscope ? 320 : 480) : m_size[1];
  request.depth = !m_depth.empty();
  request.depth_range = m_depth_range * unit;
  if (request.width < 16 || request.height < 16 || request.width > 8192 || request.height > 8192) {
    throw InputError("--size", 0, "", "each side must lie between 16 and 8192 px");
  }
  if (m_fov < 0.0 || !std::isfinite(m_fov)) throw InputError("--fov", 0, "", "must be a positive angle in degrees");
  const scene::VideoPlugin& plugin = scene::video_plugin("magvine render");
  plugin.check_mesh_image(request);  // the camera before the mesh is read
  const anatomy::ImportedMesh imported = anatomy::import_mesh(m_mesh, {.units = parse_units_option(m_units)});
  request.mesh = &imported.mesh;
  const scene::EncodedImages images = plugin.mesh_image(request);
  write_file_atomically(m_out, images.png);
  if (request.depth) write_file_atomically(m_depth, images.depth_png);
  if (endoscope) {
    std::cerr << "magvine render: " << imported.mesh.triangles.size() << " triangles, " << request.width << " x "
              << request.height << " endoscope view -> " << m_out << (m_depth.empty() ? "" : " + " + m_depth) << "; "
              << 100.0 * images.hit_fraction << " % of the rays hit the wall"
              << (images.hit_fraction < 0.999 ? " (the eye is outside the lumen or the mesh has openings)" : "")
              << "\n";
  } else {
    std::cerr << "magvine render: " << imported.mesh.triangles.size() << " triangles, overview " << request.width
              << " x " << request.height << " -> " << m_out << "\n";
  }
  return 0;
}

}  // namespace magvine::cli
