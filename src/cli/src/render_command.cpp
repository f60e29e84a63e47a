#include "render_command.hpp"

#include <cmath>
#include <filesystem>
#include <iostream>

#include <opencv2/core.hpp>

#include "commands.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "magvine/render/renderer.hpp"
#include "magvine/render/video.hpp"

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
  render::Camera cam;
  cam.position = Vec3(m_eye[0], m_eye[1], m_eye[2]) * unit;
  cam.forward = Vec3(m_look[0], m_look[1], m_look[2]) * unit - cam.position;
  cam.up = Vec3(m_up[0], m_up[1], m_up[2]);
  cam.lens = (m_lens.empty() ? endoscope : m_lens == "fisheye") ? render::Lens::kFisheye : render::Lens::kPinhole;
  cam.fov = (m_fov > 0.0 ? m_fov : endoscope ? 110.0 : 40.0) * kDegToRad;
  cam.width = m_size.empty() ? (endoscope ? 320 : 640) : m_size[0];
  cam.height = m_size.empty() ? (endoscope ? 320 : 480) : m_size[1];
  if (cam.width < 16 || cam.height < 16 || cam.width > 8192 || cam.height > 8192) {
    throw InputError("--size", 0, "", "each side must lie between 16 and 8192 px");
  }
  if (m_fov < 0.0 || !std::isfinite(m_fov)) throw InputError("--fov", 0, "", "must be a positive angle in degrees");
  (void)render::focal_pixels(cam);  // checks the field of view for the lens before the mesh is read
  (void)render::camera_frame(cam);
  const anatomy::ImportedMesh imported = anatomy::import_mesh(m_mesh, {.units = parse_units_option(m_units)});
  const render::AirwayRenderer renderer(imported.mesh, 2);
  if (endoscope) {
    const render::EndoscopeFrame f = renderer.render_endoscope(cam, render::EndoscopeLook{});
    const double hits = cv::countNonZero(f.depth) / static_cast<double>(f.depth.total());
    render::write_png(m_out, f.color);
    if (!m_depth.empty()) render::write_png(m_depth, render::depth_to_u16(f.depth, m_depth_range * unit));
    std::cerr << "magvine render: " << imported.mesh.triangles.size() << " triangles, " << cam.width << " x "
              << cam.height << " endoscope view -> " << m_out << (m_depth.empty() ? "" : " + " + m_depth) << "; "
              << 100.0 * hits << " % of the rays hit the wall"
              << (hits < 0.999 ? " (the eye is outside the lumen or the mesh has openings)" : "") << "\n";
  } else {
    render::write_png(m_out, renderer.render_overview(cam, render::OverviewContent{}));
    std::cerr << "magvine render: " << imported.mesh.triangles.size() << " triangles, overview " << cam.width << " x "
              << cam.height << " -> " << m_out << "\n";
  }
  return 0;
}

}  // namespace magvine::cli
