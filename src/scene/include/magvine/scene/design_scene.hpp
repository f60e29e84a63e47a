#pragma once
/// Design files (`magvine design DESIGN.yaml`, issue 29; format in docs/design.md): a free-space rod scene as
/// `magvine run` takes it plus a `design:` section, and the outputs of a design: design.json, the designed rod as a
/// scene (scene.yaml) that `magvine run` reproduces, its shape and the target.

#include <cstdint>
#include <filesystem>
#include <string>

#include "magvine/design/design.hpp"
#include "magvine/scene/free_space.hpp"

namespace magvine::scene {

/// design.method: `least-squares` (default: Levenberg–Marquardt with the exact Jacobian), `lbfgsb` (L-BFGS-B with the
/// exact adjoint gradient) or `bayesian` (the derivative-free baseline).
using DesignMethod = design::DesignMethod;

/// The method's name in files.
const char* method_name(DesignMethod m);

struct DesignScene {
  FreeSpaceScene scene;
  design::DesignProblem problem;
  DesignMethod method = DesignMethod::least_squares;
  int max_iterations = 100;   ///< design.iterations (the Bayesian baseline: evaluations after its initial ones)
  int starts = 1;             ///< design.starts: random starts (seeds seed, seed + 1, …), the best kept
  std::uint64_t seed = 1;     ///< the scene's seed: the random first design
  std::string file;           ///< as given (messages)
  std::string text;           ///< the file's text: scene.yaml is written from it
  double length_unit = 1e-3;  ///< one file length unit [m]
};

/// Whether `file` is a design file (YAML with a top-level `design:`); false for anything unreadable.
bool is_design_scene(const std::filesystem::path& file);

/// Reads and checks a design file; InputError (exit 2) naming the file, line and key otherwise.
DesignScene load_design_scene(const std::filesystem::path& file);
DesignScene parse_design_scene(const std::string& text, const std::string& file_label);

/// Runs the scene's method from its seeded random starts (design::multi_start_design).
design::DesignResult run_design(const DesignScene& scene, const std::function<void(int, double)>& progress = {});

/// The designed rod as a scene file: the design file without `design:`, its `robot.magnetisation` replaced by the
/// design's sections (file units, 17 significant digits) and, with a free field, `magnets` by the designed uniform
/// field.
std::string designed_scene_yaml(const DesignScene& scene, const design::Design& design);

/// Writes DIR/design.json, DIR/scene.yaml, DIR/shape.csv (the design's equilibrium) and DIR/target.csv (each target
/// point, the body's point at its arc length and their distance), each atomically (the folder is created).
void write_design_outputs(const DesignScene& scene, const design::DesignResult& result,
                          const std::filesystem::path& dir);

}  // namespace magvine::scene
