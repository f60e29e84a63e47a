// Validation at the boundary (docs/scenes.md: validation of inputs): every bundled scene file (assets/scenes/*.yaml)
// and the bundled magnets file, with every numeric value in turn replaced by a value that is not finite, huge, zero,
// negative or of the wrong type. The loader must either accept the file, and then the run must start and take its
// first steps without a crash, or refuse it with one InputError line that names the file, the line and the key of the
// value — before any run starts. Where the value breaks a relation with another key (a base normal no longer
// perpendicular to its direction, a body no longer inside the MPM domain, a pressure script that now goes below 0),
// the error may point at the other key; it must then still name the value's key or the entry that holds it.

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "magvine/config.hpp"
#include "magvine/core/error.hpp"
#include "magvine/scene/calibrate_scene.hpp"
#include "magvine/scene/design_scene.hpp"
#include "magvine/scene/experiment.hpp"
#include "magvine/scene/free_space.hpp"
#include "magvine/scene/magnets_file.hpp"
#include "support/text_file.hpp"
#if MAGVINE_WITH_MPM
#include "magvine/scene/mpm_scene.hpp"
#endif

namespace magvine::scene {
namespace {

const std::filesystem::path kAssets = std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets";

/// The values every numeric key is tried with: not finite, huge, zero, negative and of the wrong type.
const std::vector<std::string> kBadValues = {".nan", ".inf", "-.inf", "1e300", "-1e300", "0", "-1", "abc", "[1, 2]"};

/// A numeric scalar of a YAML document: where it is in the text, its key path and the lines of its enclosing nodes.
struct NumericValue {
  std::size_t pos = 0;
  std::size_t length = 0;
  std::string path;     ///< e.g. robot.wall.thickness, control.pressure[0][1]
  std::string key;      ///< the path without trailing indices: the key that holds the value
  std::string entry;    ///< the map that holds that key (its path), e.g. robot.wall
  std::set<int> lines;  ///< 1-based lines of the value and of the nodes on its path (where an error may point)
};

using test::text_of;

bool is_number(const std::string& s) {
  std::istringstream in(s);
  double v = 0.0;
  in >> v;
  return !s.empty() && in && in.peek() == EOF;
}

void collect(const YAML::Node& node, const std::string& path, std::set<int> lines, const std::string& text,
             std::vector<NumericValue>& out) {
  const YAML::Mark mark = node.Mark();
  if (mark.line >= 0) lines.insert(mark.line + 1);
  if (node.IsMap()) {
    for (const auto& kv : node) {
      const std::string key = kv.first.as<std::string>();
      collect(kv.second, path.empty() ? key : path + "." + key, lines, text, out);
    }
  } else if (node.IsSequence()) {
    for (std::size_t i = 0; i < node.size(); ++i)
      collect(node[i], path + "[" + std::to_string(i) + "]", lines, text, out);
  } else if (node.IsScalar() && node.Tag() != "!" && is_number(node.Scalar()) && mark.pos >= 0) {
    const auto pos = static_cast<std::size_t>(mark.pos);
    if (text.compare(pos, node.Scalar().size(), node.Scalar()) != 0) return;  // quoted or tagged: not a plain number
    std::string key = path;
    while (!key.empty() && key.back() == ']') key.erase(key.rfind('['));
    const std::size_t dot = key.rfind('.');
    out.push_back({pos, node.Scalar().size(), path, key, dot == std::string::npos ? key : key.substr(0, dot), lines});
  }
}

std::vector<NumericValue> numeric_values(const std::string& text) {
  std::vector<NumericValue> out;
  collect(YAML::Load(text), "", {}, text, out);
  return out;
}

/// Loads (and, when valid, starts) a scene of any kind from text; throws what the loader throws.
using Check = std::function<void(const std::string& text, const std::string& label)>;

/// The loader of `file`'s kind, with a short run after a successful load.
Check check_for(const std::filesystem::path& file, AnatomyCache& cache) {
  const YAML::Node root = YAML::Load(text_of(file));
  const std::filesystem::path dir = file.parent_path();
  if (root["magnets"] && !root["robot"] && !root["mpm"]) {  // a magnets file
    return [](const std::string& t, const std::string& label) { (void)parse_magnets(t, label); };
  }
#if MAGVINE_WITH_MPM
  if (is_mpm_scene(file)) {
    return [dir](const std::string& t, const std::string& label) {
      MpmScene s = parse_mpm_scene(t, label, dir);
      s.duration = 3.0 * s.time_step;  // the first steps: no crash, no exception
      s.settle_window = 0.0;
      (void)run_mpm_scene(s);
    };
  }
#endif
  if (is_calibrate_scene(file)) {
    return [dir](const std::string& t, const std::string& label) {
      const CalibrateScene s = parse_calibrate_scene(t, label, dir);
      design::CalibrationOptions one;
      one.max_iterations = 1;  // a short fit: no crash, no exception
      (void)design::calibrate(s.problem, one);
    };
  }
  if (is_design_scene(file)) {
    return [&cache](const std::string& t, const std::string& label) {
      DesignScene s = parse_design_scene(t, label, &cache);
      s.max_iterations = 2;  // a short design: no crash, no exception
      (void)run_design(s);
    };
  }
  if (is_experiment_scene(file)) {
    return [dir, &cache](const std::string& t, const std::string& label) {
      ExperimentScene s = parse_experiment_scene(t, label, dir, &cache);
      s.duration = std::min(s.duration, 2.0 * s.dt);
      s.videos.clear();  // the renderer is tested on its own (test_video_outputs)
      (void)run_experiment(s);
    };
  }
  return
      [](const std::string& t, const std::string& label) { (void)solve_free_space(parse_free_space_scene(t, label)); };
}

/// Every numeric value of `file` replaced in turn by each bad value.
void expect_every_value_checked(const std::filesystem::path& file) {
  const std::string text = text_of(file);
  AnatomyCache cache;
  const Check check = check_for(file, cache);
  const std::string label = file.string();
  ASSERT_NO_THROW(check(text, label)) << "the bundled file itself must load";
  const std::vector<NumericValue> values = numeric_values(text);
  ASSERT_FALSE(values.empty());
  int refused = 0;
  int accepted = 0;
  for (const NumericValue& v : values) {
    for (const std::string& bad : kBadValues) {
      const std::string mutated = text.substr(0, v.pos) + bad + text.substr(v.pos + v.length);
      try {
        check(mutated, label);
        ++accepted;
      } catch (const InputError& e) {
        ++refused;
        const std::string what = e.what();
        EXPECT_EQ(what.find('\n'), std::string::npos) << v.path << " = " << bad << ": more than one line: " << what;
        EXPECT_EQ(what.rfind(label + ":", 0), 0u)
            << v.path << " = " << bad << ": does not start with the file: " << what;
        EXPECT_NE(what.find(v.entry), std::string::npos)
            << v.path << " = " << bad << ": does not name the key: " << what;
        // The line: "FILE:LINE: KEY: what". Where KEY is the value's key, LINE is the value's or that of a node on its
        // path (an error about the whole list, say); where it is another key (a relation), that key's line.
        const std::size_t colon = what.find(':', label.size() + 1);
        ASSERT_NE(colon, std::string::npos) << what;
        const std::string line_text = what.substr(label.size() + 1, colon - label.size() - 1);
        ASSERT_FALSE(line_text.empty()) << v.path << " = " << bad << ": no line: " << what;
        ASSERT_TRUE(std::all_of(line_text.begin(), line_text.end(), ::isdigit)) << what;
        if (what.compare(colon + 2, v.key.size() + 1, v.key + ":") == 0 ||
            what.compare(colon + 2, v.key.size() + 1, v.key + "[") == 0) {
          EXPECT_TRUE(v.lines.count(std::stoi(line_text)) == 1)
              << v.path << " = " << bad << ": does not name its line: " << what;
        }
      } catch (const std::exception& e) {
        ADD_FAILURE() << v.path << " = " << bad << ": not an input error: " << e.what();
      }
    }
  }
  std::printf("  %s: %zu numeric values x %zu bad values: %d refused, %d accepted\n", file.filename().string().c_str(),
              values.size(), kBadValues.size(), refused, accepted);
}

class BundledFile : public ::testing::TestWithParam<std::string> {};

TEST_P(BundledFile, EveryNumericValueIsCheckedWhenTheFileLoads) {
  expect_every_value_checked(kAssets / GetParam());
}

std::vector<std::string> bundled_files() {
  std::vector<std::string> out = {"magnets/epm_n52.yaml"};
  for (const auto& e : std::filesystem::directory_iterator(kAssets / "scenes")) {
    if (e.path().extension() != ".yaml") continue;
    const std::string name = e.path().filename().string();
    if (!config::kWithMpm && name.rfind("mpm_", 0) == 0) continue;
    if (!config::kWithCt && text_of(e.path()).find("segmentation:") != std::string::npos) continue;
    if (!config::kWithRender && text_of(e.path()).find("mode: camera") != std::string::npos) continue;
    // The CT scenes read ../shared/airways (absent on some machines: their own tests skip).
    if (text_of(e.path()).find("shared/airways") != std::string::npos &&
        !std::filesystem::exists(std::filesystem::path(MAGVINE_SOURCE_DIR) / "../shared/airways")) {
      continue;
    }
    out.push_back("scenes/" + name);
  }
  std::sort(out.begin(), out.end());
  return out;
}

INSTANTIATE_TEST_SUITE_P(Assets, BundledFile, ::testing::ValuesIn(bundled_files()),
                         [](const ::testing::TestParamInfo<std::string>& param) {
                           std::string name = param.param;
                           for (char& c : name) {
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           }
                           return name;
                         });

}  // namespace
}  // namespace magvine::scene
