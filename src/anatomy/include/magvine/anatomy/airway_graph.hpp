#pragma once
/// The airway tree as a graph: centreline nodes (position, lumen radius) and branches between bifurcations. It is
/// the ground truth of generated phantoms and what targets ("branch 0-1-0"), planning and metrics refer to.
///
/// Conventions:
/// - A branch's polyline runs from its start to its end. The start of a child branch is the end node of its parent
///   (the bifurcation node is shared); a root branch starts at its own first node.
/// - Branch names are paths of child indices from the root: the first root is "0", its children "0-0" and "0-1",
///   then "0-1-0", ... A second root (rare: a forest) would be "1".
/// - Everything is SI inside: positions and radii in metres, world frame. Files use mm ("units": "mm").

#include <cstdint>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "magvine/core/eigen_types.hpp"

namespace magvine::anatomy {

/// One centreline sample.
struct AirwayNode {
  Vec3 position = Vec3::Zero();  ///< world frame [m]
  double radius = 0.0;           ///< lumen radius at the node (largest inscribed sphere) [m]
};

/// One airway segment between two bifurcations (or a bifurcation and a blind end).
struct AirwayBranch {
  int id = 0;                        ///< index into AirwayGraph::branches
  int parent = -1;                   ///< parent branch id, −1 for a root
  int generation = 0;                ///< 0 for a root (trachea), parent's + 1 otherwise
  std::string name;                  ///< path of child indices from the root: "0", "0-1", "0-1-0"
  std::vector<std::uint32_t> nodes;  ///< polyline, ≥ 2 node indices from start to end
  std::vector<int> children;         ///< child branch ids, in child-index order (child k is named "<name>-k")
};

/// Nodes and branches of an airway tree. Build it with add_branch() so ids, names, generations and children stay
/// consistent; validate_graph() checks a graph built by other means (files).
struct AirwayGraph {
  std::vector<AirwayNode> nodes;
  std::vector<AirwayBranch> branches;
};

/// Appends a node and returns its index.
std::uint32_t add_node(AirwayGraph& graph, const Vec3& position, double radius);

/// Appends a branch with `parent` (−1 for a root) and polyline `nodes` (≥ 2; for a child the first node must be
/// the parent's last node). Sets id, generation and name and registers it as the parent's next child. Returns the
/// id. Throws std::invalid_argument on a programming error (bad parent, bad node index, unconnected polyline).
int add_branch(AirwayGraph& graph, int parent, std::vector<std::uint32_t> nodes);

/// Branches without children (blind ends / targets), in id order.
std::vector<int> leaves(const AirwayGraph& graph);

/// The branch called `name` ("0-1-0"), or nullopt.
std::optional<int> find_branch(const AirwayGraph& graph, const std::string& name);

/// Branch ids from the root down to `branch` (inclusive), root first.
std::vector<int> path_from_root(const AirwayGraph& graph, int branch);

/// The nearest point of a graph's centrelines to a point.
struct CentrelinePoint {
  int branch = -1;                ///< its branch (−1: an empty graph)
  Vec3 position = Vec3::Zero();   ///< [m]
  double radius = 0.0;            ///< interpolated between the segment's nodes [m]
  double distance = std::numeric_limits<double>::infinity();  ///< from the query point [m]
  double along = 0.0;             ///< arc length from the branch's start [m]
};

/// The point of `graph`'s branch polylines nearest to x (ties: the lower branch id and segment).
CentrelinePoint nearest_centreline_point(const AirwayGraph& graph, const Vec3& x);

/// Length of the branch's polyline [m].
double branch_length(const AirwayGraph& graph, int branch);

/// Length of the centreline from the root's start to the end of `branch` [m].
double path_length(const AirwayGraph& graph, int branch);

/// Checks ids, parents/children, generations, names, node indices, connectivity (a child starts at its parent's
/// end), acyclicity and finite positions / positive radii. Throws InputError("<source>", "<field>", ...) naming
/// the first problem, e.g. `tree.graph.json: branches[3].parent: ...`.
void validate_graph(const AirwayGraph& graph, const std::string& source);

/// The graph as JSON text: {"format": "magvine-airway-graph", "version": 1, "units": "mm", "nodes": [{"position":
/// [x, y, z], "radius": r}, ...], "branches": [{"id", "name", "parent", "generation", "nodes", "children"}, ...]}.
/// Lengths in mm.
std::string graph_to_json(const AirwayGraph& graph);

/// Parses graph_to_json()'s format ("units" may be "mm", "cm" or "m") and validates it. `source` names the input in
/// errors. Throws InputError naming the source and the field on malformed input.
AirwayGraph graph_from_json(const std::string& text, const std::string& source);

/// Writes graph_to_json() to `path` atomically (a temporary file renamed into place). InputError on I/O failure.
void write_graph(const std::filesystem::path& path, const AirwayGraph& graph);

/// Reads and validates a graph file. InputError naming the file and field on a missing file or malformed content.
AirwayGraph read_graph(const std::filesystem::path& path);

}  // namespace magvine::anatomy
