#pragma once
// The `magvine render MESH ...` verb (render module only): one image of an airway mesh from a camera pose, the
// endoscope's view (with its depth map on request) or the semi-transparent overview, to check an imported CT mesh
// or make a figure.

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace magvine::cli {

class RenderCommand {
 public:
  void attach(CLI::App& app);
  bool parsed() const;
  /// Renders and writes the image (and depth); InputError for a bad option, mesh or camera.
  int run();

 private:
  CLI::App* m_cmd = nullptr;
  std::string m_mesh;
  std::string m_units = "mm";
  std::vector<double> m_eye;
  std::vector<double> m_look;
  std::vector<double> m_up{0.0, 0.0, 1.0};
  std::string m_view = "endoscope";
  std::string m_lens;
  double m_fov = 0.0;
  std::vector<int> m_size;
  std::string m_out;
  std::string m_depth;
  double m_depth_range = 100.0;
};

}  // namespace magvine::cli
