#pragma once
// Validating access to YAML nodes: every error names the file, the line and the key path, and unknown keys
// get a "did you mean" suggestion. Private to the scene module (yaml-cpp types stay here).

#include <yaml-cpp/yaml.h>

#include <array>
#include <filesystem>
#include <initializer_list>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "magvine/core/eigen_types.hpp"

namespace magvine::scene {

/// A quantity's unit in the file: one file unit is `si` SI units, named `name` in messages ("mm", "kPa", "T", "").
struct Unit {
  double si = 1.0;
  std::string name;
};

/// The plausible range of a quantity, SI (ranges.hpp lists them; docs/scenes.md: validation of inputs).
struct Range {
  double min = 0.0;
  double max = 0.0;
  bool open_min = false;  ///< min itself is excluded: (min, max]
  bool open_max = false;  ///< max itself is excluded: [min, max)
  bool contains(double v) const { return (open_min ? v > min : v >= min) && (open_max ? v < max : v <= max); }
};

/// "(0, 10000] mm": `r` in file units `u`.
std::string describe(const Range& r, const Unit& u);

class YamlMap {
 public:
  /// `node` must be a map (InputError otherwise). `path` is the key path used in messages ("magnets[0]").
  YamlMap(const YAML::Node& node, std::string file, std::string path);

  /// Throws for any key not in `allowed`, naming the closest allowed one.
  void allow_only(std::initializer_list<std::string_view> allowed) const;
  void allow_only(const std::vector<std::string_view>& allowed) const;
  bool has(const std::string& key) const;

  double number(const std::string& key) const;
  std::string text(const std::string& key) const;
  /// A 3-vector `[a, b, c]` of finite numbers.
  Vec3 vec3(const std::string& key) const;
  /// A 3-vector that must not be zero.
  Vec3 nonzero_vec3(const std::string& key) const;
  /// The number at `key` (in file units `u`) as SI, within `range`: InputError naming the key and the range in file
  /// units otherwise.
  double quantity(const std::string& key, const Unit& u, const Range& range) const;
  /// A 3-vector in file units `u` as SI, each component within `range`.
  Vec3 vec3_quantity(const std::string& key, const Unit& u, const Range& range) const;
  /// A direction: a 3-vector of finite numbers, not zero, of any magnitude, scaled to unit length without overflow
  /// or underflow.
  Vec3 direction(const std::string& key) const;
  /// A whole number within [min, max].
  long whole(const std::string& key, long min, long max) const;
  /// An image size `[width, height]`: whole numbers of pixels, 16 to 4096 each.
  std::array<int, 2> pixel_size(const std::string& key) const;
  /// `true` or `false`.
  bool flag(const std::string& key) const;
  /// One of two words at `key`, as its value: `first.second` for `first.first`, `second.second` for
  /// `second.first`; otherwise InputError "must be A or B (got 'x')".
  template <class T>
  T choice(const std::string& key, const std::pair<std::string_view, T>& first,
           const std::pair<std::string_view, T>& second) const {
    const std::string word = text(key);
    if (word == first.first) return first.second;
    if (word == second.first) return second.second;
    fail(key, "must be " + std::string(first.first) + " or " + std::string(second.first) + " (got '" + word + "')");
  }
  YamlMap map(const std::string& key) const;
  /// The node at `key`, which must exist.
  YAML::Node node(const std::string& key) const;

  /// Throws InputError at this map's (or `key`'s) line.
  [[noreturn]] void fail(const std::string& key, const std::string& what) const;
  /// Throws InputError at `node`'s line with the given key path.
  [[noreturn]] void fail_at(const YAML::Node& node, const std::string& path, const std::string& what) const;

  const std::string& file() const { return m_file; }
  const std::string& path() const { return m_path; }
  std::string key_path(const std::string& key) const { return m_path.empty() ? key : m_path + "." + key; }

 private:
  YAML::Node m_node;
  std::string m_file;
  std::string m_path;
};

/// The whole file as text; InputError "cannot open <what>" naming the file otherwise.
std::string read_text_file(const std::string& file, const std::string& what);

/// Parses YAML text; syntax errors become InputError with the file and line.
YAML::Node parse_yaml(const std::string& text, const std::string& file);
/// Whether `file` is YAML with a top-level map key `key` (a design file's `design:`); false for anything unreadable.
bool has_top_level_key(const std::filesystem::path& file, const char* key);
/// Line (1-based) of a node, 0 when unknown.
int line_of(const YAML::Node& node);

/// The finite number a scalar node holds; InputError at `node` (path `path`, file `file`) otherwise.
double checked_number(const YAML::Node& node, const std::string& file, const std::string& path);
/// A whole number within [min, max] at `node`.
long checked_whole(const YAML::Node& node, long min, long max, const std::string& file, const std::string& path);

/// `v` [file units] times u.si, checked against `range`; InputError at `node` (path `path`, file `file`) otherwise.
double checked_quantity(double v, const Unit& u, const Range& range, const std::string& file, const YAML::Node& node,
                        const std::string& path);

/// v / |v| for a finite non-zero v of any magnitude (scaled by its largest component first).
Vec3 unit_vector(const Vec3& v);

}  // namespace magvine::scene
