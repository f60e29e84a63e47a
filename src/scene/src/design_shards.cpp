// A design sweep's starts split over machines (`magvine design --shard I/N`, `magvine design merge`; docs/cluster.md).

#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>

#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/text.hpp"
#include "magvine/scene/design_scene.hpp"
#include "shard_files.hpp"

namespace magvine::scene {

std::vector<std::pair<int, design::DesignResult>> run_design_shard(const DesignScene& scene, const Shard& shard,
                                                                   const std::function<void(int, int)>& progress) {
  if (scene.method == DesignMethod::bayesian) {
    throw InputError(scene.file, 0, "design.method",
                     "the Bayesian baseline is one run with its own initial designs: it has no starts to shard");
  }
  const std::vector<int> mine = shard_items(static_cast<std::size_t>(std::max(1, scene.starts)), shard);
  design::DesignOptions options;
  options.max_iterations = scene.max_iterations;
  options.starts = scene.starts;
  options.seed = scene.seed;
  options.field_stages = scene.field_stages;
  std::vector<std::pair<int, design::DesignResult>> out;
  for (const int start : mine) {
    out.emplace_back(start, design::design_start(scene.problem, scene.method, options, start));
    if (progress) progress(static_cast<int>(out.size()), static_cast<int>(mine.size()));
  }
  return out;
}

namespace {

const detail::ShardKind& design_shards() {
  static const detail::ShardKind kind{
      "magvine_design_shard",       "design merge", "magvine design --shard I/N", "results", "start",
      {{"starts", "design.starts"}}};
  return kind;
}

/// JSON has no infinity: a failed equilibrium's RMS is written as null and read back as infinity.
nlohmann::json number_json(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}
double number_of(const nlohmann::json& v) {
  return v.is_null() ? std::numeric_limits<double>::infinity() : v.get<double>();
}

nlohmann::json vec_json(const Vec3& v) {
  return nlohmann::json::array({v.x(), v.y(), v.z()});
}
Vec3 vec_of(const nlohmann::json& j) {
  if (j.size() != 3) throw InputError("a vector of 3 numbers expected");
  return {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()};
}

nlohmann::json state_json(const robot::RodState& s) {
  nlohmann::json x = nlohmann::json::array();
  for (const Vec3& p : s.x) x.push_back(vec_json(p));
  nlohmann::json frames = nlohmann::json::array();
  for (const Mat3& f : s.frames) frames.push_back(std::vector<double>(f.data(), f.data() + 9));  // column-major
  return {{"x", x}, {"frames", frames}};
}

robot::RodState state_of(const nlohmann::json& j) {
  robot::RodState s;
  for (const nlohmann::json& p : j.at("x")) s.x.push_back(vec_of(p));
  for (const nlohmann::json& f : j.at("frames")) {
    const auto v = f.get<std::vector<double>>();
    if (v.size() != 9) throw InputError("a frame of 9 numbers expected");
    s.frames.emplace_back(Eigen::Map<const Mat3>(v.data()));
  }
  return s;
}

/// One start's whole result, every double at full precision (nlohmann writes the shortest text that reads back to the
/// same double).
nlohmann::json result_json(int start, const design::DesignResult& r) {
  nlohmann::json design;
  nlohmann::json directions = nlohmann::json::array();
  for (const Vec3& d : r.design.directions) directions.push_back(vec_json(d));
  nlohmann::json fields = nlohmann::json::array();
  for (const Vec3& f : r.design.fields) fields.push_back(vec_json(f));
  design["directions"] = directions;
  design["remanences"] = r.design.remanences;
  design["fields"] = fields;
  if (r.design.magnet_position) design["magnet_position"] = vec_json(*r.design.magnet_position);
  if (r.design.magnet_axis) design["magnet_axis"] = vec_json(*r.design.magnet_axis);
  nlohmann::json states = nlohmann::json::array();
  for (const robot::RodState& s : r.states) states.push_back(state_json(s));
  nlohmann::json history = nlohmann::json::array();
  for (const design::DesignResult::Step& s : r.history) {
    history.push_back(
        nlohmann::json::array({s.iteration, s.evaluation, number_json(s.rms), number_json(s.best_rms), s.time_s}));
  }
  return {{"index", start},
          {"design", design},
          {"state", state_json(r.state)},
          {"states", states},
          {"rms_m", number_json(r.rms)},
          {"max_error_m", number_json(r.max_error)},
          {"iterations", r.iterations},
          {"evaluations", r.evaluations},
          {"runtime_s", r.runtime_s},
          {"converged", r.converged},
          {"message", r.message},
          {"history", history}};
}

design::DesignResult result_of(const nlohmann::json& j) {
  design::DesignResult r;
  const nlohmann::json& d = j.at("design");
  for (const nlohmann::json& v : d.at("directions")) r.design.directions.push_back(vec_of(v));
  r.design.remanences = d.at("remanences").get<std::vector<double>>();
  for (const nlohmann::json& v : d.at("fields")) r.design.fields.push_back(vec_of(v));
  if (d.contains("magnet_position")) r.design.magnet_position = vec_of(d.at("magnet_position"));
  if (d.contains("magnet_axis")) r.design.magnet_axis = vec_of(d.at("magnet_axis"));
  r.state = state_of(j.at("state"));
  for (const nlohmann::json& s : j.at("states")) r.states.push_back(state_of(s));
  r.rms = number_of(j.at("rms_m"));
  r.max_error = number_of(j.at("max_error_m"));
  r.iterations = j.at("iterations").get<int>();
  r.evaluations = j.at("evaluations").get<int>();
  r.runtime_s = j.at("runtime_s").get<double>();
  r.converged = j.at("converged").get<bool>();
  r.message = j.at("message").get<std::string>();
  for (const nlohmann::json& h : j.at("history")) {
    r.history.push_back(
        {h.at(0).get<int>(), h.at(1).get<int>(), number_of(h.at(2)), number_of(h.at(3)), h.at(4).get<double>()});
  }
  return r;
}

}  // namespace

void write_design_shard(const std::filesystem::path& scene_file, std::uint64_t fingerprint, const DesignScene& scene,
                        const Shard& shard, const std::vector<std::pair<int, design::DesignResult>>& starts,
                        const std::filesystem::path& dir) {
  nlohmann::json j = detail::shard_header(design_shards(), scene_file.string(), fingerprint, shard);
  j["scene_path"] = std::filesystem::absolute(scene_file).string();
  j["starts"] = std::max(1, scene.starts);
  nlohmann::json items = nlohmann::json::array();
  for (const auto& [start, result] : starts) items.push_back(result_json(start, result));
  j["results"] = items;
  create_output_directory(dir);
  write_file_atomically(dir / "shard.json", j.dump(1) + "\n");
}

MergedDesign merge_design_shards(const std::vector<std::filesystem::path>& dirs,
                                 const std::filesystem::path& scene_file) {
  nlohmann::json first;
  const std::vector<detail::ShardItem> items = detail::read_shards(
      dirs, design_shards(), [](const nlohmann::json& head) { return head.at("starts").get<std::size_t>(); }, first);
  std::vector<design::DesignResult> starts;
  for (const detail::ShardItem& item : items) {
    try {
      starts.push_back(result_of(item.json));
    } catch (const nlohmann::json::exception& e) {
      throw InputError(item.file, 0, "results", std::string("not a design shard: ") + e.what());
    } catch (const InputError& e) {
      throw InputError(item.file, 0, "results", std::string("not a design shard: ") + e.what());
    }
  }
  const auto text = [&](const char* key) {
    return first.contains(key) && first.at(key).is_string() ? first.at(key).get<std::string>() : std::string();
  };
  const std::string given = text("scene");
  const std::filesystem::path file = scene_file.empty() ? std::filesystem::path(text("scene_path")) : scene_file;
  if (given.empty() || file.empty()) {
    throw InputError("design merge", 0, "", "the shards do not name their design file (scene, scene_path)");
  }
  if (printf_string("%016llx", static_cast<unsigned long long>(scene_fingerprint(file))) != text("scene_fnv1a")) {
    throw InputError(file.string(), 0, "",
                     "has changed since the shards ran it (or this magvine is another version): its bytes are not "
                     "theirs");
  }
  MergedDesign merged{load_design_scene(file), design::join_starts(std::move(starts))};
  merged.scene.file = given;
  return merged;
}

}  // namespace magvine::scene
