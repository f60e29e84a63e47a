#include "yaml_reader.hpp"

#include <cmath>
#include <fstream>
#include <sstream>

#include "magvine/core/error.hpp"
#include "magvine/core/text.hpp"

namespace magvine::scene {

bool has_top_level_key(const std::filesystem::path& file, const char* key) {
  try {
    const YAML::Node root = YAML::LoadFile(file.string());
    return root.IsMap() && root[key];
  } catch (const YAML::Exception&) {
    return false;
  }
}

int line_of(const YAML::Node& node) {
  const YAML::Mark mark = node.Mark();
  return mark.line >= 0 ? mark.line + 1 : 0;
}

std::string read_text_file(const std::string& file, const std::string& what) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file, 0, "", "cannot open " + what);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

YAML::Node parse_yaml(const std::string& text, const std::string& file) {
  try {
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw InputError(file, e.mark.line >= 0 ? e.mark.line + 1 : 0, "", "YAML syntax error: " + e.msg);
  }
}

YamlMap::YamlMap(const YAML::Node& node, std::string file, std::string path)
    : m_node(node), m_file(std::move(file)), m_path(std::move(path)) {
  if (!m_node.IsMap()) fail_at(m_node, m_path.empty() ? "(top level)" : m_path, "must be a mapping of key: value");
}

void YamlMap::allow_only(std::initializer_list<std::string_view> allowed) const {
  allow_only(std::vector<std::string_view>(allowed));
}

void YamlMap::allow_only(const std::vector<std::string_view>& allowed) const {
  for (const auto& kv : m_node) {
    const std::string key = kv.first.as<std::string>();
    bool ok = false;
    for (auto a : allowed) ok = ok || key == a;
    if (!ok) {
      std::string names;
      for (auto a : allowed) names += (names.empty() ? "" : ", ") + std::string(a);
      fail_at(kv.first, key_path(key),
              "unknown key (did you mean '" + closest_match(key, allowed) + "'? allowed: " + names + ")");
    }
  }
}

bool YamlMap::has(const std::string& key) const {
  return static_cast<bool>(m_node[key]);
}

YAML::Node YamlMap::node(const std::string& key) const {
  const YAML::Node n = m_node[key];
  if (!n) fail(key, "missing required key");
  return n;
}

double checked_number(const YAML::Node& n, const std::string& file, const std::string& path) {
  if (!n.IsScalar()) throw InputError(file, line_of(n), path, "must be a number");
  double v = 0.0;
  try {
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    throw InputError(file, line_of(n), path, "'" + n.Scalar() + "' is not a number");
  }
  if (!std::isfinite(v)) throw InputError(file, line_of(n), path, "must be finite (got " + n.Scalar() + ")");
  return v;
}

double YamlMap::number(const std::string& key) const {
  return checked_number(node(key), m_file, key_path(key));
}

std::string YamlMap::text(const std::string& key) const {
  const YAML::Node n = node(key);
  if (!n.IsScalar()) fail_at(n, key_path(key), "must be a single word");
  return n.Scalar();
}

Vec3 YamlMap::vec3(const std::string& key) const {
  const YAML::Node n = node(key);
  if (!n.IsSequence() || n.size() != 3) fail_at(n, key_path(key), "must be a list of 3 numbers [a, b, c]");
  Vec3 v;
  for (int i = 0; i < 3; ++i) v[i] = checked_number(n[i], m_file, key_path(key) + "[" + std::to_string(i) + "]");
  return v;
}

Vec3 YamlMap::nonzero_vec3(const std::string& key) const {
  const Vec3 v = vec3(key);
  if (v.cwiseAbs().maxCoeff() == 0.0) fail(key, "must not be the zero vector");
  return v;
}

std::string describe(const Range& r, const Unit& u) {
  std::string out =
      printf_string("%c%.6g, %.6g%c", r.open_min ? '(' : '[', r.min / u.si, r.max / u.si, r.open_max ? ')' : ']');
  if (!u.name.empty()) out.append(" ").append(u.name);
  return out;
}

double checked_quantity(double v, const Unit& u, const Range& range, const std::string& file, const YAML::Node& node,
                        const std::string& path) {
  const double si = v * u.si;
  if (!std::isfinite(v) || !std::isfinite(si) || !range.contains(si)) {
    throw InputError(file, line_of(node), path,
                     "must be in " + describe(range, u) + " (got " + printf_string("%.6g", v) + ")");
  }
  return si;
}

Vec3 unit_vector(const Vec3& v) {
  const double largest = v.cwiseAbs().maxCoeff();
  return (v / largest).normalized();
}

double YamlMap::quantity(const std::string& key, const Unit& u, const Range& range) const {
  return checked_quantity(number(key), u, range, m_file, node(key), key_path(key));
}

Vec3 YamlMap::vec3_quantity(const std::string& key, const Unit& u, const Range& range) const {
  const Vec3 v = vec3(key);
  const YAML::Node n = node(key);
  Vec3 out;
  for (int i = 0; i < 3; ++i) {
    out[i] = checked_quantity(v[i], u, range, m_file, n[i], key_path(key) + "[" + std::to_string(i) + "]");
  }
  return out;
}

Vec3 YamlMap::direction(const std::string& key) const {
  return unit_vector(nonzero_vec3(key));
}

long checked_whole(const YAML::Node& n, long min, long max, const std::string& file, const std::string& path) {
  const double v = checked_number(n, file, path);
  if (v != std::floor(v) || v < static_cast<double>(min) || v > static_cast<double>(max)) {
    throw InputError(file, line_of(n), path,
                     "must be a whole number from " + std::to_string(min) + " to " + std::to_string(max) + " (got " +
                         n.Scalar() + ")");
  }
  return static_cast<long>(v);
}

long YamlMap::whole(const std::string& key, long min, long max) const {
  return checked_whole(node(key), min, max, m_file, key_path(key));
}

std::array<int, 2> YamlMap::pixel_size(const std::string& key) const {
  const YAML::Node n = node(key);
  if (!n.IsSequence() || n.size() != 2) fail_at(n, key_path(key), "must be [width, height] in pixels");
  std::array<int, 2> size{};
  for (std::size_t i = 0; i < 2; ++i) {
    size[i] = static_cast<int>(checked_whole(n[i], 16, 4096, m_file, key_path(key) + "[" + std::to_string(i) + "]"));
  }
  return size;
}

bool YamlMap::flag(const std::string& key) const {
  const std::string t = text(key);
  if (t != "true" && t != "false") fail(key, "must be true or false (got '" + t + "')");
  return t == "true";
}

YamlMap YamlMap::map(const std::string& key) const {
  return YamlMap(node(key), m_file, key_path(key));
}

void YamlMap::fail(const std::string& key, const std::string& what) const {
  const YAML::Node n = m_node[key];
  fail_at(n ? n : m_node, key_path(key), what);
}

void YamlMap::fail_at(const YAML::Node& node, const std::string& path, const std::string& what) const {
  throw InputError(m_file, line_of(node), path, what);
}

}  // namespace magvine::scene
