#include "magvine/anatomy/airway_graph.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"

namespace magvine::anatomy {

namespace {

using nlohmann::json;

constexpr const char* kFormat = "magvine-airway-graph";
constexpr int kVersion = 1;

std::string branch_field(int b, const char* field) {
  return "branches[" + std::to_string(b) + "]." + field;
}

// Name of child `index` of `parent` (or of root number `index` when parent < 0).
std::string child_name(const AirwayGraph& graph, int parent, std::size_t index) {
  if (parent < 0) return std::to_string(index);
  return graph.branches[static_cast<std::size_t>(parent)].name + "-" + std::to_string(index);
}

std::size_t root_count_before(const AirwayGraph& graph, int id) {
  std::size_t roots = 0;
  for (int b = 0; b < id; ++b) {
    if (graph.branches[static_cast<std::size_t>(b)].parent < 0) ++roots;
  }
  return roots;
}

}  // namespace

std::uint32_t add_node(AirwayGraph& graph, const Vec3& position, double radius) {
  graph.nodes.push_back({position, radius});
  return static_cast<std::uint32_t>(graph.nodes.size() - 1);
}

int add_branch(AirwayGraph& graph, int parent, std::vector<std::uint32_t> nodes) {
  const int id = static_cast<int>(graph.branches.size());
  if (parent < -1 || parent >= id) throw std::invalid_argument("add_branch: parent id out of range");
  if (nodes.size() < 2) throw std::invalid_argument("add_branch: a branch needs at least 2 nodes");
  for (const std::uint32_t n : nodes) {
    if (n >= graph.nodes.size()) throw std::invalid_argument("add_branch: node index out of range");
  }
  AirwayBranch branch;
  branch.id = id;
  branch.parent = parent;
  if (parent >= 0) {
    AirwayBranch& p = graph.branches[static_cast<std::size_t>(parent)];
    if (nodes.front() != p.nodes.back()) {
      throw std::invalid_argument("add_branch: a child must start at its parent's last node");
    }
    branch.generation = p.generation + 1;
    branch.name = child_name(graph, parent, p.children.size());
    p.children.push_back(id);
  } else {
    branch.generation = 0;
    branch.name = child_name(graph, -1, root_count_before(graph, id));
  }
  branch.nodes = std::move(nodes);
  graph.branches.push_back(std::move(branch));
  return id;
}

std::vector<int> leaves(const AirwayGraph& graph) {
  std::vector<int> out;
  for (const AirwayBranch& b : graph.branches) {
    if (b.children.empty()) out.push_back(b.id);
  }
  return out;
}

std::optional<int> find_branch(const AirwayGraph& graph, const std::string& name) {
  for (const AirwayBranch& b : graph.branches) {
    if (b.name == name) return b.id;
  }
  return std::nullopt;
}

std::vector<int> path_from_root(const AirwayGraph& graph, int branch) {
  std::vector<int> path;
  // The step limit guards against a cyclic parent chain in an unvalidated graph.
  for (int b = branch; b >= 0 && path.size() <= graph.branches.size(); b = graph.branches.at(static_cast<std::size_t>(b)).parent) {
    path.push_back(b);
  }
  return {path.rbegin(), path.rend()};
}

CentrelinePoint nearest_centreline_point(const AirwayGraph& graph, const Vec3& x) {
  CentrelinePoint best;
  for (const AirwayBranch& b : graph.branches) {
    double along = 0.0;
    for (std::size_t k = 0; k + 1 < b.nodes.size(); ++k) {
      const AirwayNode& p = graph.nodes[b.nodes[k]];
      const AirwayNode& q = graph.nodes[b.nodes[k + 1]];
      const Vec3 d = q.position - p.position;
      const double t = std::clamp((x - p.position).dot(d) / std::max(d.squaredNorm(), 1e-30), 0.0, 1.0);
      const Vec3 at = p.position + t * d;
      const double dist = (at - x).norm();
      if (dist < best.distance) best = {b.id, at, (1.0 - t) * p.radius + t * q.radius, dist, along + t * d.norm()};
      along += d.norm();
    }
  }
  return best;
}

double branch_length(const AirwayGraph& graph, int branch) {
  const AirwayBranch& b = graph.branches.at(static_cast<std::size_t>(branch));
  double length = 0.0;
  for (std::size_t i = 1; i < b.nodes.size(); ++i) {
    length += (graph.nodes[b.nodes[i]].position - graph.nodes[b.nodes[i - 1]].position).norm();
  }
  return length;
}

double path_length(const AirwayGraph& graph, int branch) {
  double length = 0.0;
  for (const int b : path_from_root(graph, branch)) length += branch_length(graph, b);
  return length;
}

void validate_graph(const AirwayGraph& graph, const std::string& source) {
  const auto fail = [&source](const std::string& where, const std::string& what) {
    throw InputError(source, 0, where, what);
  };
  for (std::size_t i = 0; i < graph.nodes.size(); ++i) {
    const AirwayNode& n = graph.nodes[i];
    const std::string where = "nodes[" + std::to_string(i) + "]";
    if (!n.position.allFinite()) fail(where + ".position", "must be finite");
    if (!std::isfinite(n.radius) || !(n.radius > 0.0)) {
      fail(where + ".radius", "must be > 0 (got " + std::to_string(n.radius / kMmToM) + " mm)");
    }
  }
  if (graph.branches.empty()) fail("branches", "must not be empty");
  const int count = static_cast<int>(graph.branches.size());
  for (int i = 0; i < count; ++i) {
    const AirwayBranch& b = graph.branches[static_cast<std::size_t>(i)];
    if (b.id != i) fail(branch_field(i, "id"), "must equal the position in the list (" + std::to_string(i) + ")");
    if (b.parent < -1 || b.parent >= count || b.parent == i) {
      fail(branch_field(i, "parent"), "must be -1 or another branch's id in [0, " + std::to_string(count) +
                                          ") (got " + std::to_string(b.parent) + ")");
    }
    if (b.nodes.size() < 2) fail(branch_field(i, "nodes"), "needs at least 2 node indices");
    for (const std::uint32_t n : b.nodes) {
      if (n >= graph.nodes.size()) {
        fail(branch_field(i, "nodes"), "node index " + std::to_string(n) + " out of range [0, " +
                                           std::to_string(graph.nodes.size()) + ")");
      }
    }
    for (std::size_t k = 1; k < b.nodes.size(); ++k) {
      if (graph.nodes[b.nodes[k]].position == graph.nodes[b.nodes[k - 1]].position) {
        fail(branch_field(i, "nodes"), "zero-length segment between nodes " + std::to_string(b.nodes[k - 1]) +
                                           " and " + std::to_string(b.nodes[k]));
      }
    }
  }
  // Parent chains must end at a root (no cycles).
  for (int i = 0; i < count; ++i) {
    int b = i;
    int steps = 0;
    while (b >= 0 && steps <= count) {
      b = graph.branches[static_cast<std::size_t>(b)].parent;
      ++steps;
    }
    if (b >= 0) fail(branch_field(i, "parent"), "parent chain has a cycle");
  }
  // Children lists mirror the parents, and names/generations follow from them.
  std::size_t root_index = 0;
  for (int i = 0; i < count; ++i) {
    const AirwayBranch& b = graph.branches[static_cast<std::size_t>(i)];
    std::string expected_name;
    int expected_generation = 0;
    if (b.parent < 0) {
      expected_name = std::to_string(root_index++);
    } else {
      const AirwayBranch& p = graph.branches[static_cast<std::size_t>(b.parent)];
      std::size_t k = 0;
      while (k < p.children.size() && p.children[k] != i) ++k;
      if (k == p.children.size()) {
        fail(branch_field(b.parent, "children"), "does not list branch " + std::to_string(i) + " whose parent it is");
      }
      expected_name = p.name + "-" + std::to_string(k);
      expected_generation = p.generation + 1;
      if (b.nodes.front() != p.nodes.back()) {
        fail(branch_field(i, "nodes"), "must start at the parent's last node " + std::to_string(p.nodes.back()) +
                                           " (got " + std::to_string(b.nodes.front()) + ")");
      }
    }
    if (b.generation != expected_generation) {
      fail(branch_field(i, "generation"), "must be " + std::to_string(expected_generation) + " (got " +
                                              std::to_string(b.generation) + ")");
    }
    if (b.name != expected_name) {
      fail(branch_field(i, "name"), "must be \"" + expected_name + "\" (got \"" + b.name + "\")");
    }
    for (const int c : b.children) {
      if (c < 0 || c >= count || graph.branches[static_cast<std::size_t>(c)].parent != i) {
        fail(branch_field(i, "children"), "lists " + std::to_string(c) + ", which is not a child of branch " +
                                              std::to_string(i));
      }
    }
  }
}

std::string graph_to_json(const AirwayGraph& graph) {
  json doc;
  doc["format"] = kFormat;
  doc["version"] = kVersion;
  doc["units"] = "mm";
  json nodes = json::array();
  for (const AirwayNode& n : graph.nodes) {
    const Vec3 p = n.position / kMmToM;
    nodes.push_back({{"position", {p.x(), p.y(), p.z()}}, {"radius", n.radius / kMmToM}});
  }
  doc["nodes"] = std::move(nodes);
  json branches = json::array();
  for (const AirwayBranch& b : graph.branches) {
    branches.push_back({{"id", b.id},
                        {"name", b.name},
                        {"parent", b.parent},
                        {"generation", b.generation},
                        {"nodes", b.nodes},
                        {"children", b.children}});
  }
  doc["branches"] = std::move(branches);
  return doc.dump(1) + "\n";
}

AirwayGraph graph_from_json(const std::string& text, const std::string& source) {
  json doc;
  try {
    doc = json::parse(text);
  } catch (const json::parse_error& e) {
    throw InputError(source, 0, "", std::string("not valid JSON: ") + e.what());
  }
  const auto fail = [&source](const std::string& where, const std::string& what) {
    throw InputError(source, 0, where, what);
  };
  if (!doc.is_object()) fail("", "must be a JSON object");
  const auto member = [&](const json& obj, const char* key, const std::string& where) -> const json& {
    const auto it = obj.find(key);
    if (it == obj.end()) fail(where.empty() ? key : where + "." + key, "missing");
    return *it;
  };
  const auto number = [&](const json& v, const std::string& where) {
    if (!v.is_number()) fail(where, "must be a number");
    const double x = v.get<double>();
    if (!std::isfinite(x)) fail(where, "must be finite");
    return x;
  };
  const auto integer = [&](const json& v, const std::string& where) {
    if (!v.is_number_integer()) fail(where, "must be an integer");
    return v.get<long long>();
  };

  if (const auto it = doc.find("format"); it != doc.end() && (!it->is_string() || it->get<std::string>() != kFormat)) {
    fail("format", std::string("must be \"") + kFormat + "\"");
  }
  const json& units_json = member(doc, "units", "");
  if (!units_json.is_string()) fail("units", "must be a string: \"mm\", \"cm\" or \"m\"");
  const auto units = parse_length_unit(units_json.get<std::string>());
  if (!units) fail("units", "must be \"mm\", \"cm\" or \"m\" (got \"" + units_json.get<std::string>() + "\")");
  const double scale = metres_per(*units);

  AirwayGraph graph;
  const json& nodes = member(doc, "nodes", "");
  if (!nodes.is_array()) fail("nodes", "must be an array");
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    const std::string where = "nodes[" + std::to_string(i) + "]";
    const json& n = nodes[i];
    if (!n.is_object()) fail(where, "must be an object {\"position\": [x, y, z], \"radius\": r}");
    const json& pos = member(n, "position", where);
    if (!pos.is_array() || pos.size() != 3) fail(where + ".position", "must be an array of 3 numbers");
    Vec3 p;
    for (int k = 0; k < 3; ++k) p[k] = number(pos[static_cast<std::size_t>(k)], where + ".position") * scale;
    const double r = number(member(n, "radius", where), where + ".radius") * scale;
    graph.nodes.push_back({p, r});
  }
  const json& branches = member(doc, "branches", "");
  if (!branches.is_array()) fail("branches", "must be an array");
  for (std::size_t i = 0; i < branches.size(); ++i) {
    const std::string where = "branches[" + std::to_string(i) + "]";
    const json& b = branches[i];
    if (!b.is_object()) fail(where, "must be an object");
    AirwayBranch branch;
    branch.id = static_cast<int>(integer(member(b, "id", where), where + ".id"));
    branch.parent = static_cast<int>(integer(member(b, "parent", where), where + ".parent"));
    branch.generation = static_cast<int>(integer(member(b, "generation", where), where + ".generation"));
    const json& name = member(b, "name", where);
    if (!name.is_string()) fail(where + ".name", "must be a string");
    branch.name = name.get<std::string>();
    const json& node_list = member(b, "nodes", where);
    if (!node_list.is_array()) fail(where + ".nodes", "must be an array of node indices");
    for (const json& n : node_list) {
      const long long v = integer(n, where + ".nodes");
      if (v < 0 || v > static_cast<long long>(UINT32_MAX)) fail(where + ".nodes", "node index out of range");
      branch.nodes.push_back(static_cast<std::uint32_t>(v));
    }
    const json& children = member(b, "children", where);
    if (!children.is_array()) fail(where + ".children", "must be an array of branch ids");
    for (const json& c : children) branch.children.push_back(static_cast<int>(integer(c, where + ".children")));
    graph.branches.push_back(std::move(branch));
  }
  validate_graph(graph, source);
  return graph;
}

void write_graph(const std::filesystem::path& path, const AirwayGraph& graph) {
  write_file_atomically(path, graph_to_json(graph));
}

AirwayGraph read_graph(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string(), 0, "", "cannot open airway graph file");
  std::ostringstream text;
  text << in.rdbuf();
  return graph_from_json(text.str(), path.string());
}

}  // namespace magvine::anatomy
