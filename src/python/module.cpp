// `import magvine` (docs/python.md): the simulator's verbs as Python functions returning what the command line writes.
// A bad input raises ValueError with the command line's one line; a run whose step fails raises
// magvine.SimulationError naming the step. The GIL is released while a run computes, so runs in several Python
// threads run in parallel (the core holds no global state).

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <random>
#include <stdexcept>
#include <string>

#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/mesh_report.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/field_function.hpp"
#include "magvine/scene/experiment.hpp"
#include "magvine/scene/magnets_file.hpp"

namespace py = pybind11;
namespace fs = std::filesystem;

namespace {

/// A run whose step found no equilibrium (magvine.SimulationError).
class SimulationFailure : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// JSON text into Python objects (through the json module: the same doubles the text holds).
py::object from_json(const std::string& text) {
  return py::module_::import("json").attr("loads")(text);
}

std::string read_text(const fs::path& file) {
  std::ifstream in(file);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

/// A scene: a path (str or os.PathLike), or a dict with the scene file's keys (read as JSON, which YAML contains;
/// relative paths in it resolve against the working directory).
magvine::scene::ExperimentScene experiment_scene(const py::object& scene) {
  if (py::isinstance<py::dict>(scene)) {
    const std::string text = py::module_::import("json").attr("dumps")(scene).cast<std::string>();
    return magvine::scene::parse_experiment_scene(text, "<dict>", fs::current_path());
  }
  const fs::path file = py::module_::import("os").attr("fspath")(scene).cast<std::string>();
  return magvine::scene::load_experiment_scene(file);
}

}  // namespace

PYBIND11_MODULE(magvine, m) {
  m.doc() = "magvine: magnetically steered soft robots in anatomy (docs/python.md)";
  py::register_exception<SimulationFailure>(m, "SimulationError", PyExc_RuntimeError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const magvine::InputError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });

  m.def(
      "run",
      [](const py::object& scene, const py::object& out) -> py::object {
        const magvine::scene::ExperimentScene sc = experiment_scene(scene);
        fs::path dir;
        if (out.is_none()) {
          std::random_device seed;
          dir = fs::temp_directory_path() / ("magvine_python_run_" + std::to_string(seed()));
        } else {
          dir = py::module_::import("os").attr("fspath")(out).cast<std::string>();
        }
        magvine::scene::ExperimentResult result;
        {
          const py::gil_scoped_release release;
          result = magvine::scene::run_experiment(sc);
          magvine::scene::write_experiment_outputs(sc, result, dir);
        }
        const std::string metrics = read_text(dir / "metrics.json");
        if (out.is_none()) fs::remove_all(dir);
        if (!result.converged) throw SimulationFailure(result.failure);
        return from_json(metrics);
      },
      py::arg("scene"), py::arg("out") = py::none(),
      "Runs an experiment scene (a path, or a dict with the scene file's keys) as `magvine run` does, writing its "
      "outputs to `out` (a folder; None: none kept), and returns its metrics (metrics.json as a dict). Raises "
      "ValueError for a bad scene and magvine.SimulationError when a step fails.");

  m.def(
      "mesh_check",
      [](const std::string& file, const std::string& units) -> py::object {
        const auto unit = magvine::parse_length_unit(units);
        if (!unit) throw magvine::InputError("units", 0, "", "must be mm, cm or m (got '" + units + "')");
        const magvine::anatomy::ImportedMesh imported = magvine::anatomy::import_mesh(file, {.units = *unit});
        const magvine::anatomy::MeshReport report = magvine::anatomy::analyse_mesh(imported.mesh);
        return from_json(magvine::anatomy::report_json(file, imported, report, *unit));
      },
      py::arg("file"), py::arg("units") = "mm", "The report of `magvine mesh check --json FILE` as a dict.");

  m.def(
      "field",
      [](const std::string& magnets, const py::array_t<double, py::array::c_style | py::array::forcecast>& points) {
        if (points.ndim() != 2 || points.shape(1) != 3) {
          throw magvine::InputError("points", 0, "", "must be an (N, 3) array of positions in metres");
        }
        const magvine::magnetics::FieldModel model = magvine::scene::load_magnets_file(magnets);
        const magvine::magnetics::FieldFunction f = magvine::magnetics::field_function(model, model.rest_poses);
        const auto n = static_cast<std::size_t>(points.shape(0));
        py::array_t<double> b({static_cast<py::ssize_t>(n), py::ssize_t{3}});
        py::array_t<double> g({static_cast<py::ssize_t>(n), py::ssize_t{3}, py::ssize_t{3}});
        const auto x = points.unchecked<2>();
        auto bo = b.mutable_unchecked<2>();
        auto go = g.mutable_unchecked<3>();
        {
          const py::gil_scoped_release release;
          for (std::size_t i = 0; i < n; ++i) {
            const auto k = static_cast<py::ssize_t>(i);
            const magvine::Vec3 p(x(k, 0), x(k, 1), x(k, 2));
            if (!p.allFinite()) throw magvine::InputError("points", 0, "", "a position is not finite");
            const magvine::magnetics::FieldSample s = f(p);
            for (int r = 0; r < 3; ++r) {
              bo(k, r) = s.b[r];
              for (int c = 0; c < 3; ++c) go(k, r, c) = s.g(r, c);
            }
          }
        }
        return py::make_tuple(b, g);
      },
      py::arg("magnets"), py::arg("points"),
      "The field B [T] (N, 3) and its gradient G = ∂B/∂x [T/m] (N, 3, 3) of a magnets file's magnets at their poses, "
      "at points [m] (N, 3).");
}
