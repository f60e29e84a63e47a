// `import magvine` (docs/python.md): the compiled part of the package, magvine._magvine. The simulator's verbs as
// Python functions returning what the command line writes, and Simulation, an experiment stepped from Python with
// numpy copies of its state. A bad input raises ValueError with the command line's one line; a step that finds no
// equilibrium raises magvine.SimulationError naming the step. The GIL is released while the core computes, so
// simulations in several Python threads run in parallel (the core holds no global state).

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#include "magvine/anatomy/airway_graph.hpp"
#include "magvine/anatomy/centerline.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/mesh_report.hpp"
#include "magvine/anatomy/phantom.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/stopwatch.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/scene/design_scene.hpp"
#include "magvine/scene/experiment.hpp"
#include "magvine/scene/magnets_file.hpp"
#include "magvine/scene/navigator.hpp"
#include "magvine/scene/trials.hpp"
#include "magvine/scene/video_plugin.hpp"

namespace py = pybind11;
namespace fs = std::filesystem;
namespace sc = magvine::scene;
using magvine::InputError;
using magvine::Mat3;
using magvine::Vec3;

namespace {

/// A step that found no equilibrium (magvine.SimulationError).
class SimulationFailure : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// JSON text into Python objects (through the json module: the same doubles the text holds).
py::object from_json(const std::string& text) {
  return py::module_::import("json").attr("loads")(text);
}

std::string fspath(const py::object& path) {
  return py::module_::import("os").attr("fspath")(path).cast<std::string>();
}

/// A scene or design file from Python: a path (str or os.PathLike), or a dict with the file's keys (read as JSON, which
/// YAML contains; relative paths in it resolve against the working directory); `parse` reads the dict's text, `load`
/// the file, with the GIL released.
template <class Parse, class Load>
auto read_scene(const py::object& scene, Parse parse, Load load) {
  if (py::isinstance<py::dict>(scene)) {
    const std::string text = py::module_::import("json").attr("dumps")(scene).cast<std::string>();
    const py::gil_scoped_release release;
    return parse(text);
  }
  const fs::path file = fspath(scene);
  const py::gil_scoped_release release;
  return load(file);
}

sc::ExperimentScene experiment_scene(const py::object& scene) {
  return read_scene(
      scene, [](const std::string& text) { return sc::parse_experiment_scene(text, "<dict>", fs::current_path()); },
      [](const fs::path& file) { return sc::load_experiment_scene(file); });
}

/// A scene loaded once (magvine.Scene), for many simulations: its anatomy (mesh, collision world, graph) is shared.
struct SceneHandle {
  std::shared_ptr<const sc::ExperimentScene> scene;
};

/// A scene given as a magvine.Scene, a path or a dict.
sc::ExperimentScene scene_of(const py::object& scene) {
  if (py::isinstance<SceneHandle>(scene)) return *scene.cast<const SceneHandle&>().scene;
  return experiment_scene(scene);
}

/// Where a verb writes its files: `out` (a folder), or for None a fresh temporary folder removed when this goes (also
/// when the verb throws).
class OutputFolder {
 public:
  OutputFolder(const py::object& out, const char* what) : m_temporary(out.is_none()) {
    if (m_temporary) {
      std::random_device seed;
      m_dir = fs::temp_directory_path() / ("magvine_python_" + std::string(what) + "_" + std::to_string(seed()));
    } else {
      m_dir = fspath(out);
    }
  }
  ~OutputFolder() {
    std::error_code ec;
    if (m_temporary) fs::remove_all(m_dir, ec);
  }
  OutputFolder(const OutputFolder&) = delete;
  OutputFolder& operator=(const OutputFolder&) = delete;
  const fs::path& dir() const { return m_dir; }
  /// One of the files written there, as a dict (JSON).
  py::object json(const char* name) const {
    std::ifstream in(m_dir / name);
    return from_json(std::string(std::istreambuf_iterator<char>(in), {}));
  }

 private:
  bool m_temporary;
  fs::path m_dir;
};

/// The run's files written into `out` (a folder; None: none kept) and its metrics.json as a dict, as `magvine run`
/// writes them. Raises SimulationError after writing a failed run's metrics.json.
py::object outputs_and_metrics(const sc::ExperimentScene& scene, const sc::ExperimentResult& result,
                               const py::object& out) {
  const OutputFolder folder(out, "run");
  {
    const py::gil_scoped_release release;
    sc::write_experiment_outputs(scene, result, folder.dir());
  }
  if (!result.converged) throw SimulationFailure(result.failure);
  return folder.json("metrics.json");
}

/// An (N, 3) array of doubles from points.
py::array_t<double> rows(const std::vector<Vec3>& v) {
  py::array_t<double> a({static_cast<py::ssize_t>(v.size()), py::ssize_t{3}});
  auto o = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < v.size(); ++i) {
    for (int c = 0; c < 3; ++c) o(static_cast<py::ssize_t>(i), c) = v[i][c];
  }
  return a;
}

py::array_t<double> vec(const Vec3& v) {
  py::array_t<double> a(3);
  auto o = a.mutable_unchecked<1>();
  for (int c = 0; c < 3; ++c) o(c) = v[c];
  return a;
}

/// Three finite numbers from a Python sequence, or ValueError naming `key`.
Vec3 three(const py::handle& h, const std::string& key) {
  const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(h);
  if (!a || a.ndim() != 1 || a.shape(0) != 3) throw InputError("step", 0, key, "must be 3 numbers");
  const Vec3 v(a.at(0), a.at(1), a.at(2));
  if (!v.allFinite()) throw InputError("step", 0, key, "must be finite");
  return v;
}

/// `value` as a T, or ValueError naming `key` (pybind11's own cast error names neither).
template <class T>
T argument(const py::handle& value, const std::string& where, const std::string& key) {
  try {
    return value.cast<T>();
  } catch (const py::cast_error&) {
    throw InputError(where, 0, key,
                     "must be " +
                         std::string(std::is_same_v<T, std::string> ? "a string"
                                     : std::is_same_v<T, bool>      ? "a bool"
                                     : std::is_floating_point_v<T>  ? "a number"
                                     : std::is_unsigned_v<T>        ? "an integer >= 0"
                                                                    : "an integer") +
                         " (got " + py::repr(value).cast<std::string>() + ")");
  }
}

/// An experiment stepped from Python (magvine.Simulation). The scene is owned here (the experiment borrows it); one
/// thread at a time may use it: every member that reads or moves the run holds its lock, and a second thread gets
/// RuntimeError rather than a data race.
class Simulation {
 public:
  Simulation(const py::object& scene, const py::object& seed) {
    sc::ExperimentScene s = scene_of(scene);
    if (!seed.is_none()) s = sc::perturbed(s, argument<std::uint64_t>(seed, "Simulation", "seed"));
    m_scene = std::make_unique<sc::ExperimentScene>(std::move(s));
    const py::gil_scoped_release release;
    m_path = sc::target_path(*m_scene);
    m_run = std::make_unique<sc::Experiment>(*m_scene);
  }

  /// The lock of a member that reads or moves the run.
  std::unique_lock<std::mutex> use(const char* what) const {
    std::unique_lock<std::mutex> lock(m_busy, std::try_to_lock);
    if (!lock.owns_lock()) {
      throw std::runtime_error(std::string("Simulation.") + what + ": this simulation is in use in another thread");
    }
    return lock;
  }

  void step(const py::object& dt, const py::object& pressure, const py::object& tether, const py::object& magnets) {
    // The request read from Python first; the lock then held in plain C++ and with the GIL released only (see
    // state()).
    sc::StepRequest r;
    if (!dt.is_none()) r.dt = argument<double>(dt, "step", "dt");
    if (!pressure.is_none()) r.pressure = argument<double>(pressure, "step", "pressure");
    if (!tether.is_none()) r.tether = argument<double>(tether, "step", "tether");
    if (!magnets.is_none()) {
      // (position, axis) for magnet 0, or {index: (position, axis)}.
      const auto pose = [&](int i, const py::handle& h) {
        const std::string key = "magnet_pose[" + std::to_string(i) + "]";
        const py::sequence p = py::reinterpret_borrow<py::sequence>(h);
        if (!py::isinstance<py::sequence>(h) || py::len(p) != 2) {
          throw InputError("step", 0, key, "must be (position, axis)");
        }
        r.magnets.push_back({i, three(p[0], key + ".position"), three(p[1], key + ".axis")});
      };
      if (py::isinstance<py::dict>(magnets)) {
        for (const auto& [k, v] : magnets.cast<py::dict>()) pose(argument<int>(k, "step", "magnet_pose"), v);
      } else {
        pose(0, magnets);
      }
    }
    bool converged = false;
    std::string failure;
    {
      const auto lock = use("step");
      if (m_run->ended()) {
        throw std::runtime_error(m_finished ? "Simulation.step: finish() ended this run"
                                 : !m_run->result().converged
                                     ? "Simulation.step: a step failed and ended this run: " + m_run->result().failure
                                     : "Simulation.step: the biopsy's aiming is done; finish() pushes the needle");
      }
      const py::gil_scoped_release release;
      const magvine::Stopwatch clock;
      converged = m_run->step(r);
      m_step_seconds += clock.seconds();
      if (!converged) failure = m_run->result().failure;
    }
    if (!converged) throw SimulationFailure(failure);
  }

  /// The state now, as numpy arrays (copies: the body gains nodes as it grows).
  py::object state() const {
    // A snapshot under the lock in plain C++ (no Python call there: Python may hand the GIL to another thread, which
    // would then find the lock held for as long as this one waits), the arrays built after.
    struct Snapshot {
      double time = 0.0, length = 0.0, pressure = 0.0, max_normal = 0.0;
      long steps = 0;
      bool success = false, burst = false;
      std::vector<Vec3> nodes, tangents, field, normal, shear, positions, axes;
      std::vector<double> contact;
      Mat3 frame = Mat3::Identity();
    } s;
    {
      const auto lock = use("state");
      const magvine::robot::GrowthState& g = m_run->state();
      const std::size_t n = g.body.x.size();
      s.nodes = g.body.x;
      s.tangents.resize(n);
      s.field.resize(n);
      s.normal.assign(n, Vec3::Zero());
      s.shear.assign(n, Vec3::Zero());
      s.contact.assign(n, 0.0);
      for (std::size_t i = 0; i < n; ++i) {
        // Frames are per edge: a node takes the edge towards the tip, the tip its last edge.
        s.tangents[i] = g.body.frames[std::min(i, g.body.frames.size() - 1)].col(0);
        s.field[i] = m_run->field_at(g.body.x[i]).b;
        if (i < g.forces.normal_vector.size()) s.normal[i] = g.forces.normal_vector[i];
        if (i < g.forces.shear_vector.size()) s.shear[i] = g.forces.shear_vector[i];
        if (i < g.forces.pressure.size()) s.contact[i] = g.forces.pressure[i];
      }
      for (const magvine::magnetics::Pose& p : m_run->magnet_poses()) {
        s.positions.push_back(p.position);
        s.axes.push_back(p.rotation.col(2));
      }
      s.frame = g.body.frames.back();
      s.time = m_run->time();
      s.steps = m_run->steps();
      s.length = m_run->everted_length();
      s.pressure = m_run->pressure();
      s.max_normal = g.forces.max_normal;
      s.success = m_run->result().success;
      s.burst = g.burst;
    }
    py::array_t<double> frame({py::ssize_t{3}, py::ssize_t{3}});
    auto f = frame.mutable_unchecked<2>();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) f(r, c) = s.frame(r, c);
    }
    py::dict d;
    d["time"] = s.time;
    d["steps"] = s.steps;
    d["everted_length"] = s.length;
    d["pressure"] = s.pressure;
    d["nodes"] = rows(s.nodes);
    d["tangents"] = rows(s.tangents);
    d["wall_normal"] = rows(s.normal);
    d["wall_shear"] = rows(s.shear);
    d["contact_pressure"] = py::array_t<double>(static_cast<py::ssize_t>(s.contact.size()), s.contact.data());
    d["max_wall_normal"] = s.max_normal;
    d["field"] = rows(s.field);
    d["tip_position"] = vec(s.nodes.back());
    d["tip_frame"] = frame;
    d["magnet_positions"] = rows(s.positions);
    d["magnet_axes"] = rows(s.axes);
    d["success"] = s.success;
    d["burst"] = s.burst;
    return py::module_::import("types").attr("SimpleNamespace")(**d);
  }

  /// How far along the path to the target the tip has got (path_progress), or None.
  py::object progress() const {
    if (m_path.empty()) return py::none();
    double progress = 0.0;
    {
      const auto lock = use("progress");
      progress = sc::path_progress(m_path, *m_scene->target, m_run->tip_at_rest());
    }
    return py::float_(progress);
  }

  py::object path() const { return m_path.empty() ? py::none() : py::object(rows(m_path)); }

  py::object finish(const py::object& out) {
    sc::ExperimentResult result;
    {
      const auto lock = use("finish");  // held with the GIL released or in plain C++ only (see state())
      if (m_finished) throw std::runtime_error("Simulation.finish: called twice");
      m_finished = true;
      const py::gil_scoped_release release;
      result = m_run->finish();
    }
    return outputs_and_metrics(*m_scene, result, out);
  }

  /// The tip camera's picture as an (height, width, 3) RGB array of bytes.
  py::array_t<std::uint8_t> render(const std::string& camera, int width, int height, double fov_deg, bool fisheye,
                                   double noise) {
    if (camera != "tip") throw InputError("render", 0, "camera", "must be 'tip' (got '" + camera + "')");
    if (width < 16 || height < 16 || width > 4096 || height > 4096) {
      throw InputError("render", 0, "width", "width and height must be 16–4096 pixels");
    }
    if (!(fov_deg > 0.0 && fov_deg < (fisheye ? 360.0 : 180.0))) {
      throw InputError("render", 0, "fov", "must be in (0, 180) degrees, (0, 360) with the fisheye lens");
    }
    if (!(noise >= 0.0 && std::isfinite(noise))) throw InputError("render", 0, "noise", "must be finite and >= 0");
    const sc::VideoPlugin& plugin = sc::video_plugin("Simulation.render");
    const sc::TipViewSettings s{fisheye, fov_deg * magvine::kDegToRad, width, height, noise, m_scene->seed};
    // One view per camera asked for (an environment's observation and its render() differ): each keeps its
    // renderer, auto-exposure and noise sequence.
    const auto same = [&](const View& v) {
      return v.settings.fisheye == s.fisheye && v.settings.fov == s.fov && v.settings.width == s.width &&
             v.settings.height == s.height && v.settings.noise == s.noise;
    };
    sc::Picture p;
    {
      const auto lock = use("render");  // held with the GIL released only (see state())
      const py::gil_scoped_release release;
      auto view = std::find_if(m_views.begin(), m_views.end(), same);
      if (view == m_views.end()) {
        m_views.push_back({s, plugin.tip_view(m_scene->anatomy->mesh(), s)});
        view = std::prev(m_views.end());
      }
      if (m_scene->breathing) view->view->move(m_run->airway_vertices());
      const magvine::robot::GrowthState& g = m_run->state();
      p = view->view->look(g.body.tip(), g.body.frames.back());
    }
    py::array_t<std::uint8_t> a(
        {static_cast<py::ssize_t>(p.height), static_cast<py::ssize_t>(p.width), py::ssize_t{3}});
    std::copy(p.rgb.begin(), p.rgb.end(), a.mutable_data());
    return a;
  }

  /// A plain value read from the run under its lock (done, ended, time, steps, magnets).
  template <class F>
  auto read(const char* what, F f) const {
    const auto lock = use(what);
    return f(*m_run);
  }

  const sc::ExperimentScene& scene() const { return *m_scene; }
  bool finished() const { return m_finished; }
  double step_seconds() const {
    const auto lock = use("step_seconds");
    return m_step_seconds;
  }

 private:
  std::unique_ptr<sc::ExperimentScene> m_scene;
  std::unique_ptr<sc::Experiment> m_run;
  std::vector<Vec3> m_path;
  bool m_finished = false;
  double m_step_seconds = 0.0;
  mutable std::mutex m_busy;
  struct View {
    sc::TipViewSettings settings;
    std::unique_ptr<sc::TipView> view;
  };
  std::vector<View> m_views;
};

py::dict outcome_dict(const sc::TrialOutcome& o) {
  const auto maybe = [](double v) { return std::isfinite(v) ? py::object(py::float_(v)) : py::object(py::none()); };
  py::dict d;
  d["target"] = o.target;
  d["repeat"] = o.repeat;
  d["seed"] = o.seed;
  d["success"] = o.success;
  d["burst"] = o.burst;
  d["time_to_target_s"] = o.time_to_target >= 0.0 ? py::object(py::float_(o.time_to_target)) : py::none();
  d["everted_length_m"] = o.everted_length;
  d["final_error_m"] = o.final_error;
  d["max_wall_normal_N"] = o.max_normal;
  d["retractions"] = o.retractions;
  d["biopsy"] = o.biopsy < 0 ? py::object(py::none()) : py::object(py::bool_(o.biopsy == 1));
  d["needle_to_nodule_m"] = maybe(o.needle_to_nodule);
  d["slide_back_m"] = maybe(o.slide_back);
  d["runtime_s"] = o.runtime_s;
  d["reason"] = o.reason;
  return d;
}

}  // namespace

PYBIND11_MODULE(_magvine, m) {
  m.doc() = "magvine's compiled core (docs/python.md); import magvine";
  py::register_exception<SimulationFailure>(m, "SimulationError", PyExc_RuntimeError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const InputError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });

  m.def(
      "run",
      [](const py::object& scene, const py::object& out) -> py::object {
        const sc::ExperimentScene s = scene_of(scene);
        sc::ExperimentResult result;
        {
          const py::gil_scoped_release release;
          result = sc::run_experiment(s);
        }
        return outputs_and_metrics(s, result, out);
      },
      py::arg("scene"), py::arg("out") = py::none(),
      "Runs an experiment scene (a path, or a dict with the scene file's keys) as `magvine run` does, writing its "
      "outputs to `out` (a folder; None: none kept), and returns its metrics (metrics.json as a dict). Raises "
      "ValueError for a bad scene and magvine.SimulationError when a step fails.");

  m.def(
      "trials",
      [](const py::object& scene, const std::vector<std::string>& targets, int repeats, int jobs,
         const py::object& out) {
        if (repeats < 1) throw InputError("trials", 0, "repeats", "must be at least 1");
        if (jobs < 0) throw InputError("trials", 0, "jobs", "must be >= 0 (0: one thread per core)");
        const sc::ExperimentScene s = scene_of(scene);
        const int threads = jobs > 0 ? jobs : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
        std::vector<sc::TrialOutcome> outcomes;
        const std::string dir = out.is_none() ? std::string() : fspath(out);
        {
          const py::gil_scoped_release release;
          outcomes = sc::run_trials(s, targets, repeats, threads);
          if (!dir.empty()) sc::write_trial_outputs(outcomes, dir);
        }
        py::list l;
        for (const sc::TrialOutcome& o : outcomes) l.append(outcome_dict(o));
        return l;
      },
      py::arg("scene"), py::arg("targets") = std::vector<std::string>{}, py::arg("repeats") = 4, py::arg("jobs") = 0,
      py::arg("out") = py::none(),
      "Runs `repeats` perturbed trials towards each target (branch names; empty: the scene's own) as `magvine trials` "
      "does, on `jobs` threads (0: one per core), writing trials.csv and the summary into `out` when given; returns "
      "one dict per trial in (target, repeat) order (SI units).");

  m.def(
      "design",
      [](const py::object& scene, const py::object& out) -> py::object {
        const sc::DesignScene s = read_scene(
            scene, [](const std::string& text) { return sc::parse_design_scene(text, "<dict>"); },
            [](const fs::path& file) { return sc::load_design_scene(file); });
        const OutputFolder folder(out, "design");
        magvine::design::DesignResult r;
        {
          const py::gil_scoped_release release;
          r = sc::run_design(s);
          if (std::isfinite(r.rms)) sc::write_design_outputs(s, r, folder.dir());
        }
        if (!std::isfinite(r.rms)) {
          throw SimulationFailure("design: no design had a stable equilibrium (" + r.message + ")");
        }
        return folder.json("design.json");
      },
      py::arg("scene"), py::arg("out") = py::none(),
      "Designs a rod's magnetisation as `magvine design SCENE --out OUT` does (without the MPM check) and returns "
      "design.json as a dict, writing design.json, scene.yaml, shape.csv and target.csv into `out` (None: none "
      "kept). Raises magvine.SimulationError when no design has a stable equilibrium.");

  m.def(
      "phantom",
      [](const std::string& kind, const py::object& out, const py::kwargs& params) -> py::object {
        namespace an = magvine::anatomy;
        const std::optional<an::PhantomKind> k = an::parse_phantom_kind(kind);
        if (!k) {
          throw InputError("phantom", 0, "kind",
                           "must be bronchial_tree, tube, y_bifurcation, s_bend or constriction (got '" + kind + "')");
        }
        const std::string where = "phantom " + kind;
        an::PhantomParams p = an::default_params(*k);
        const std::vector<an::PhantomOption> options = an::phantom_options(p);
        for (const auto& [key, value] : params) {
          const std::string name = key.cast<std::string>();
          if (auto* tree = std::get_if<an::BronchialTreeParams>(&p); tree && name == "table") {
            const std::string t = argument<std::string>(value, where, "table");
            const auto table = an::parse_airway_table(t);
            if (!table) throw InputError(where, 0, "table", "must be weibel_a or horsfield (got '" + t + "')");
            tree->table = *table;
            continue;
          }
          if (auto* tube = std::get_if<an::TubeParams>(&p); tube && name == "open") {
            tube->capped = !argument<bool>(value, where, "open");
            continue;
          }
          const auto o =
              std::find_if(options.begin(), options.end(), [&](const an::PhantomOption& x) { return x.name == name; });
          if (o == options.end()) {
            std::string known = std::holds_alternative<an::BronchialTreeParams>(p) ? "table" : "";
            for (const an::PhantomOption& x : options) known += (known.empty() ? "" : ", ") + x.name;
            if (std::holds_alternative<an::TubeParams>(p)) known += ", open";
            throw InputError(where, 0, name, "is not a parameter of this kind (it has " + known + ")");
          }
          if (double* const* f = std::get_if<double*>(&o->field)) {
            const double v = argument<double>(value, where, name);
            if (!std::isfinite(v)) throw InputError(where, 0, name, "must be finite");
            **f = v * o->scale;
          } else if (int* const* i = std::get_if<int*>(&o->field)) {
            **i = argument<int>(value, where, name);
          } else {
            *std::get<std::uint64_t*>(o->field) = argument<std::uint64_t>(value, where, name);
          }
        }
        const std::string file = out.is_none() ? std::string() : fspath(out);
        if (!file.empty() && fs::path(file).extension() != ".stl" && fs::path(file).extension() != ".STL") {
          throw InputError(where, 0, "out", "must name an .stl file (got '" + file + "')");
        }
        an::Phantom ph;
        {
          const py::gil_scoped_release release;
          ph = an::make_phantom(p);
          if (!file.empty()) an::write_phantom(ph, file);
        }
        py::array_t<std::uint32_t> triangles({static_cast<py::ssize_t>(ph.mesh.triangles.size()), py::ssize_t{3}});
        auto t = triangles.mutable_unchecked<2>();
        for (std::size_t i = 0; i < ph.mesh.triangles.size(); ++i) {
          for (int c = 0; c < 3; ++c) t(static_cast<py::ssize_t>(i), c) = ph.mesh.triangles[i][c];
        }
        py::dict d;
        d["vertices"] = rows(ph.mesh.vertices);
        d["triangles"] = triangles;
        d["graph"] = from_json(an::graph_to_json(ph.graph));
        d["metadata"] = from_json(an::phantom_metadata_json(ph));
        return d;
      },
      py::arg("kind"), py::arg("out") = py::none(),
      "Generates a phantom as `magvine phantom KIND --out OUT` does, its parameters as keywords named as in the "
      "metadata (gap_mm=3, branch_angle_deg=35, max_generation=4, table='horsfield', open=True); writes OUT (an .stl) "
      "with its graph and metadata beside it when given, and returns a dict: vertices [m] (V, 3), triangles (T, 3), "
      "graph, metadata.");

  m.def(
      "mesh_check",
      [](const std::string& file, const std::string& units) -> py::object {
        const auto unit = magvine::parse_length_unit(units);
        if (!unit) throw InputError("units", 0, "", "must be mm, cm or m (got '" + units + "')");
        std::string json;
        {
          const py::gil_scoped_release release;
          const magvine::anatomy::ImportedMesh imported = magvine::anatomy::import_mesh(file, {.units = *unit});
          const magvine::anatomy::MeshReport report = magvine::anatomy::analyse_mesh(imported.mesh);
          json = magvine::anatomy::report_json(file, imported, report, *unit);
        }
        return from_json(json);
      },
      py::arg("file"), py::arg("units") = "mm", "The report of `magvine mesh check --json FILE` as a dict.");

  m.def(
      "airway_graph",
      [](const std::string& file, const std::string& units, double voxel, const py::object& root) -> py::object {
        const auto unit = magvine::parse_length_unit(units);
        if (!unit) throw InputError("units", 0, "", "must be mm, cm or m (got '" + units + "')");
        if (!(voxel >= 0.0 && std::isfinite(voxel))) throw InputError("voxel", 0, "", "must be a length >= 0");
        magvine::anatomy::CenterlineOptions options;
        options.voxel = voxel * magvine::metres_per(*unit);
        if (!root.is_none()) options.root = three(root, "root") * magvine::metres_per(*unit);
        std::string json;
        {
          const py::gil_scoped_release release;
          const magvine::anatomy::ImportedMesh imported = magvine::anatomy::import_mesh(file, {.units = *unit});
          json = magvine::anatomy::graph_to_json(magvine::anatomy::extract_airway_graph(imported.mesh, options));
        }
        return from_json(json);
      },
      py::arg("file"), py::arg("units") = "mm", py::arg("voxel") = 0.0, py::arg("root") = py::none(),
      "The airway graph of a mesh as `magvine mesh graph FILE --out graph.json` writes it, as a dict (voxel and root "
      "in `units`; voxel 0: automatic).");

  m.def(
      "field",
      [](const std::string& magnets, const py::array_t<double, py::array::c_style | py::array::forcecast>& points,
         const py::object& out) {
        if (points.ndim() != 2 || points.shape(1) != 3) {
          throw InputError("points", 0, "", "must be an (N, 3) array of positions in metres");
        }
        magvine::magnetics::FieldModel model;
        {
          const py::gil_scoped_release release;
          model = sc::load_magnets_file(magnets);
        }
        const py::ssize_t n = points.shape(0);
        // The results in fresh arrays, or in the caller's (out=(B, G): C-contiguous float64 of the right shapes), which
        // a loop over many calls reuses instead of having the kernel clear fresh memory each time.
        py::array_t<double> b;
        py::array_t<double> g;
        if (out.is_none()) {
          b = py::array_t<double>({n, py::ssize_t{3}});
          g = py::array_t<double>({n, py::ssize_t{3}, py::ssize_t{3}});
        } else {
          if (!py::isinstance<py::tuple>(out) || py::len(out) != 2) {
            throw InputError("out", 0, "", "must be a tuple (B, G) of float64 arrays");
          }
          const py::tuple pair = py::reinterpret_borrow<py::tuple>(out);
          if (!py::isinstance<py::array_t<double>>(pair[0]) || !py::isinstance<py::array_t<double>>(pair[1])) {
            throw InputError("out", 0, "", "must be a tuple (B, G) of float64 arrays");
          }
          b = pair[0].cast<py::array_t<double>>();
          g = pair[1].cast<py::array_t<double>>();
          const auto fits = [](const py::array_t<double>& a, std::initializer_list<py::ssize_t> shape) {
            if (!(a.flags() & py::array::c_style) || !a.writeable() ||
                a.ndim() != static_cast<py::ssize_t>(shape.size())) {
              return false;
            }
            py::ssize_t k = 0;
            for (const py::ssize_t d : shape) {
              if (a.shape(k++) != d) return false;
            }
            return true;
          };
          if (!fits(b, {n, 3}) || !fits(g, {n, 3, 3})) {
            throw InputError("out", 0, "",
                             "must be writable C-contiguous float64 arrays of shapes (N, 3) and (N, 3, 3)");
          }
        }
        const double* x = points.data();
        double* bo = b.mutable_data();
        double* go = g.mutable_data();
        {
          // The core's batch evaluation (field_gradient_batch), in blocks that stay in cache.
          const py::gil_scoped_release release;
          constexpr py::ssize_t kBlock = 4096;
          std::vector<Vec3> block;
          std::vector<magvine::magnetics::FieldSample> samples;
          for (py::ssize_t start = 0; start < n; start += kBlock) {
            const py::ssize_t count = std::min(kBlock, n - start);
            block.resize(static_cast<std::size_t>(count));
            samples.resize(static_cast<std::size_t>(count));
            for (py::ssize_t i = 0; i < count; ++i) {
              const double* p = x + 3 * (start + i);
              block[static_cast<std::size_t>(i)] = Vec3(p[0], p[1], p[2]);
              if (!block[static_cast<std::size_t>(i)].allFinite()) {
                throw InputError("points", 0, "", "a position is not finite");
              }
            }
            magvine::magnetics::field_gradient_batch(model, model.rest_poses, block, samples);
            for (py::ssize_t i = 0; i < count; ++i) {
              const magvine::magnetics::FieldSample& f = samples[static_cast<std::size_t>(i)];
              const py::ssize_t k = start + i;
              for (int r = 0; r < 3; ++r) {
                bo[3 * k + r] = f.b[r];
                for (int c = 0; c < 3; ++c) go[9 * k + 3 * r + c] = f.g(r, c);
              }
            }
          }
        }
        return py::make_tuple(b, g);
      },
      py::arg("magnets"), py::arg("points"), py::arg("out") = py::none(),
      "The field B [T] (N, 3) and its gradient G = ∂B/∂x [T/m] (N, 3, 3) of a magnets file's magnets at their poses, "
      "at points [m] (N, 3); into `out` = (B, G) when given (float64, C-contiguous), which it returns.");

  py::class_<SceneHandle>(m, "Scene",
                          "An experiment scene loaded once (a path, or a dict with the scene file's keys): give it to "
                          "Simulation, run or trials in place of the path to share its anatomy.")
      .def(py::init([](const py::object& scene) {
             return SceneHandle{std::make_shared<const sc::ExperimentScene>(experiment_scene(scene))};
           }),
           py::arg("scene"))
      .def_property_readonly("file", [](const SceneHandle& h) { return h.scene->file; })
      .def("__repr__", [](const SceneHandle& h) { return "magvine.Scene('" + h.scene->file + "')"; });

  py::class_<Simulation>(m, "Simulation",
                         "An experiment scene stepped from Python: step() advances it as `magvine run` does (or under "
                         "your pressure, tether and magnet poses), state gives numpy copies of the body, finish() "
                         "returns the metrics.")
      .def(py::init<const py::object&, const py::object&>(), py::arg("scene"), py::arg("seed") = py::none(),
           "scene: a path or a dict with the scene file's keys; seed: None for the scene as written, or an integer "
           "for the perturbed trial `magvine trials` runs with that seed.")
      .def("step", &Simulation::step, py::arg("dt") = py::none(), py::arg("pressure") = py::none(),
           py::arg("tether") = py::none(), py::arg("magnet_pose") = py::none(),
           "One step: dt [s] (None: to the next multiple of the scene's dt, as `magvine run`), pressure [Pa], tether "
           "(released length [m]), magnet_pose ((position [m], axis) of magnet 0, or {index: (position, axis)}). "
           "Each setting holds until replaced. Raises SimulationError when the step finds no equilibrium.")
      .def_property_readonly(
          "state", &Simulation::state,
          "The state now (numpy copies, SI units): time, steps, everted_length, pressure, nodes, "
          "tangents (each node's edge towards the tip), wall_normal and wall_shear (the force on the tissue per node), "
          "contact_pressure, max_wall_normal, field (B at the nodes), tip_position, tip_frame "
          "(columns: tangent, image up, their cross product), magnet_positions, magnet_axes, "
          "success, burst (the film burst: the vine grows no more).")
      .def_property_readonly("progress", &Simulation::progress,
                             "How far along the path to the target the tip has got, 0–1 (metrics' path_progress); "
                             "None without a target and a graph.")
      .def_property_readonly("path", &Simulation::path, "The path to the target (K, 3) [m], or None.")
      .def_property_readonly(
          "done", [](const Simulation& s) { return s.read("done", [](const sc::Experiment& e) { return e.done(); }); },
          "Whether `magvine run` would stop here (duration, target with stop_at_target, a failed "
          "step, a biopsy's aiming done).")
      .def_property_readonly(
          "ended",
          [](const Simulation& s) { return s.read("ended", [](const sc::Experiment& e) { return e.ended(); }); },
          "Whether no step may follow (a failed step, a biopsy's aiming done, finish()).")
      .def_property_readonly(
          "time", [](const Simulation& s) { return s.read("time", [](const sc::Experiment& e) { return e.time(); }); },
          "[s]")
      .def_property_readonly(
          "steps",
          [](const Simulation& s) { return s.read("steps", [](const sc::Experiment& e) { return e.steps(); }); })
      .def_property_readonly(
          "dt", [](const Simulation& s) { return s.scene().dt; }, "the scene's step [s]")
      .def_property_readonly(
          "duration", [](const Simulation& s) { return s.scene().duration; }, "[s]")
      .def_property_readonly("magnets",
                             [](const Simulation& s) {
                               return s.read("magnets",
                                             [](const sc::Experiment& e) { return e.magnet_poses().size(); });
                             })
      .def_property_readonly(
          "target",
          [](const Simulation& s) { return s.scene().target ? py::object(vec(*s.scene().target)) : py::none(); },
          "[m], or None")
      .def_property_readonly(
          "target_tolerance", [](const Simulation& s) { return s.scene().target_tolerance; }, "[m]")
      .def_property_readonly(
          "steered", [](const Simulation& s) { return s.scene().navigator.has_value(); },
          "whether the scene's navigator steers a magnet")
      .def_property_readonly("step_seconds", &Simulation::step_seconds,
                             "computing time spent inside the core's steps so far [s]")
      .def("finish", &Simulation::finish, py::arg("out") = py::none(),
           "Ends the run (a biopsy's puncture) and returns its metrics (metrics.json as a dict), writing its files "
           "into `out` (None: none kept).")
      .def("render", &Simulation::render, py::arg("camera") = "tip", py::arg("width") = 160, py::arg("height") = 160,
           py::arg("fov") = 120.0, py::arg("fisheye") = true, py::arg("noise") = 0.0,
           "The tip camera's picture now as a (height, width, 3) uint8 RGB array (fov in degrees across the width). "
           "Needs the render module.");
}
