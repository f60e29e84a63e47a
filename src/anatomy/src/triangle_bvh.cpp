#include "triangle_bvh.hpp"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <string>

#include "magvine/core/check.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/multiversion.hpp"

namespace magvine::anatomy::detail {
namespace {

/// Largest triangle count a leaf's 27-bit slot field addresses.
constexpr std::size_t kMaxTriangles = std::size_t{1} << 27;
/// Boxes grow by this fraction of the mesh's bounding-box diagonal beyond the float rounding, so that double
/// tests against them (whose own rounding is relative to the coordinates, not the box) stay conservative for
/// triangles lying in a box face, at no measurable cost in visited triangles.
constexpr double kBoxPad = 1e-7;
/// The SAH's cost of a triangle test against a node's (traversalCost 1).
constexpr float kTriangleCost = 0.25F;

/// Nodes and leaves as Embree's builder makes them, in its thread-local memory; flattened afterwards.
struct BuildItem {
  bool leaf = false;
};
struct BuildNode : BuildItem {
  unsigned count = 0;
  std::array<BuildItem*, 4> children{};
  std::array<RTCBounds, 4> bounds{};
};
struct BuildLeaf : BuildItem {
  unsigned count = 0;
  std::array<std::uint32_t, TriangleBvh::kMaxLeafSize> triangles{};
};

void* create_node(RTCThreadLocalAllocator alloc, unsigned count, void* /*user*/) {
  void* memory = rtcThreadLocalAlloc(alloc, sizeof(BuildNode), alignof(BuildNode));
  auto* node = new (memory) BuildNode;
  node->count = count;
  return node;
}

void set_children(void* node, void** children, unsigned count, void* /*user*/) {
  for (unsigned k = 0; k < count; ++k)
    static_cast<BuildNode*>(node)->children[k] = static_cast<BuildItem*>(children[k]);
}

void set_bounds(void* node, const RTCBounds** bounds, unsigned count, void* /*user*/) {
  for (unsigned k = 0; k < count; ++k) static_cast<BuildNode*>(node)->bounds[k] = *bounds[k];
}

void* create_leaf(RTCThreadLocalAllocator alloc, const RTCBuildPrimitive* primitives, std::size_t count,
                  void* /*user*/) {
  void* memory = rtcThreadLocalAlloc(alloc, sizeof(BuildLeaf), alignof(BuildLeaf));
  auto* leaf = new (memory) BuildLeaf;
  leaf->leaf = true;
  // The builder keeps leaves within maxLeafSize; should it ever not, the excess is dropped here (never written past
  // the array, and no exception crosses Embree's C frames) and the constructor's count check reports it.
  leaf->count = static_cast<unsigned>(std::min<std::size_t>(count, TriangleBvh::kMaxLeafSize));
  for (std::size_t i = 0; i < leaf->count; ++i) leaf->triangles[i] = primitives[i].primID;
  return leaf;
}

struct DeviceDeleter {
  void operator()(RTCDevice d) const { rtcReleaseDevice(d); }
};
struct BvhDeleter {
  void operator()(RTCBVH b) const { rtcReleaseBVH(b); }
};

[[noreturn]] void fail(RTCDevice device, const std::string& what) {
  const RTCError code = device != nullptr ? rtcGetDeviceError(device) : RTC_ERROR_UNKNOWN;
  throw InputError("collision world BVH: " + what + " (Embree error " + std::to_string(static_cast<int>(code)) + ")");
}

/// Depth-first flattening: inner nodes get consecutive indices, leaves consecutive slot runs.
/// The box of the triangles' corners [mesh units].
std::pair<Vec3, Vec3> triangle_box(std::span<const Vec3> vertices, std::span<const Triangle> triangles) {
  Vec3 lo = vertices[triangles[0][0]];
  Vec3 hi = lo;
  for (const Triangle& t : triangles) {
    for (const std::uint32_t v : t) {
      lo = lo.cwiseMin(vertices[v]);
      hi = hi.cwiseMax(vertices[v]);
    }
  }
  return {lo, hi};
}

class Flattener {
 public:
  Flattener(std::vector<TriangleBvh::Node>& nodes, std::vector<std::uint32_t>& order)
      : m_nodes(nodes), m_order(order) {}

  std::uint32_t leaf(const BuildLeaf& l) {
    const auto first = static_cast<std::uint32_t>(m_order.size());
    m_order.insert(m_order.end(), l.triangles.begin(), l.triangles.begin() + l.count);
    return TriangleBvh::kLeafBit | (first << 4) | l.count;
  }

  /// Appends `n` (and its subtree) and returns its index.
  std::uint32_t node(const BuildNode& n) {
    const auto index = static_cast<std::uint32_t>(m_nodes.size());
    m_nodes.push_back(TriangleBvh::empty_node());
    for (unsigned k = 0; k < n.count; ++k) {
      const BuildItem* item = n.children[k];
      const std::uint32_t child =
          item->leaf ? leaf(*static_cast<const BuildLeaf*>(item)) : node(*static_cast<const BuildNode*>(item));
      set_child(m_nodes[index], k, child, n.bounds[k]);  // re-indexed: the recursion may have grown the vector
    }
    return index;
  }

  /// A root holding a single leaf (a mesh of at most kMaxLeafSize triangles) with its box.
  void root_leaf(const BuildLeaf& l, const RTCBounds& b) {
    m_nodes.push_back(TriangleBvh::empty_node());
    set_child(m_nodes.back(), 0, leaf(l), b);
  }

 private:
  static void set_child(TriangleBvh::Node& out, unsigned k, std::uint32_t child, const RTCBounds& b) {
    out.child[k] = child;
    out.lo_x[k] = b.lower_x;
    out.lo_y[k] = b.lower_y;
    out.lo_z[k] = b.lower_z;
    out.hi_x[k] = b.upper_x;
    out.hi_y[k] = b.upper_y;
    out.hi_z[k] = b.upper_z;
  }

  std::vector<TriangleBvh::Node>& m_nodes;
  std::vector<std::uint32_t>& m_order;
};

}  // namespace

TriangleBvh::Node TriangleBvh::empty_node() {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  Node n{};
  n.lo_x.fill(kInf);
  n.lo_y.fill(kInf);
  n.lo_z.fill(kInf);
  n.hi_x.fill(-kInf);
  n.hi_y.fill(-kInf);
  n.hi_z.fill(-kInf);
  n.child.fill(kLeafBit);  // an empty leaf: harmless even if a test accepted the empty box
  return n;
}

TriangleBvh::TriangleBvh(std::span<const Vec3> vertices, std::span<const Triangle> triangles) {
  if (triangles.empty()) throw InputError("collision world BVH: the mesh has no triangles");
  if (triangles.size() > kMaxTriangles) {
    throw InputError("collision world BVH: " + std::to_string(triangles.size()) + " triangles, more than the " +
                     std::to_string(kMaxTriangles) + " supported");
  }
  const auto [lo, hi] = triangle_box(vertices, triangles);
  const double pad = kBoxPad * (hi - lo).norm();

  std::vector<RTCBuildPrimitive> primitives(triangles.size());
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    const Triangle& t = triangles[i];
    const Vec3 a = vertices[t[0]].cwiseMin(vertices[t[1]]).cwiseMin(vertices[t[2]]).array() - pad;
    const Vec3 b = vertices[t[0]].cwiseMax(vertices[t[1]]).cwiseMax(vertices[t[2]]).array() + pad;
    RTCBuildPrimitive& p = primitives[i];
    p.lower_x = float_down(a.x());
    p.lower_y = float_down(a.y());
    p.lower_z = float_down(a.z());
    p.upper_x = float_up(b.x());
    p.upper_y = float_up(b.y());
    p.upper_z = float_up(b.z());
    p.geomID = 0;
    p.primID = static_cast<unsigned>(i);
  }

  // One build thread: the build is deterministic and the benchmarks measure one core.
  const std::unique_ptr<RTCDeviceTy, DeviceDeleter> device(rtcNewDevice("threads=1"));
  if (!device) fail(nullptr, "cannot create an Embree device");
  const std::unique_ptr<RTCBVHTy, BvhDeleter> bvh(rtcNewBVH(device.get()));
  if (!bvh) fail(device.get(), "cannot create an Embree BVH");

  RTCBuildArguments args = rtcDefaultBuildArguments();
  args.buildQuality = RTC_BUILD_QUALITY_MEDIUM;
  args.maxBranchingFactor = 4;
  args.maxLeafSize = kMaxLeafSize;
  // A triangle's test costs a quarter of a node's in the SAH (Embree's default: the same), so leaves hold a few
  // triangles rather than one: on the 195 k-triangle airway 52.8 k leaves in 17.6 k nodes instead of about 150 k in
  // 51 k. In bench_contacts the barrier's triangles_within took 0.41–0.61 and sphere contacts 0.62–0.90 of the time,
  // rays 1.3–1.6 and the inside test 1.3 times it, the build 0.86 and the refit 0.6 (2026-12-06,
  // docs/benchmarks.md); growth runs, dominated by triangles_within, gain.
  args.intersectionCost = kTriangleCost;
  args.bvh = bvh.get();
  args.primitives = primitives.data();
  args.primitiveCount = primitives.size();
  args.primitiveArrayCapacity = primitives.size();
  args.createNode = create_node;
  args.setNodeChildren = set_children;
  args.setNodeBounds = set_bounds;
  args.createLeaf = create_leaf;
  void* root = rtcBuildBVH(&args);
  if (root == nullptr) fail(device.get(), "Embree's BVH build failed");

  m_nodes.reserve(triangles.size() / 2);
  m_order.reserve(triangles.size());
  Flattener flatten(m_nodes, m_order);
  if (static_cast<const BuildItem*>(root)->leaf) {
    RTCBounds all{};
    all.lower_x = float_down(lo.x() - pad);
    all.lower_y = float_down(lo.y() - pad);
    all.lower_z = float_down(lo.z() - pad);
    all.upper_x = float_up(hi.x() + pad);
    all.upper_y = float_up(hi.y() + pad);
    all.upper_z = float_up(hi.z() + pad);
    flatten.root_leaf(*static_cast<const BuildLeaf*>(root), all);
  } else {
    flatten.node(*static_cast<const BuildNode*>(root));
  }
  m_nodes.shrink_to_fit();
  if (m_order.size() != triangles.size()) fail(device.get(), "the BVH lost triangles");
}

void TriangleBvh::prepare_refit(std::span<const std::array<std::uint32_t, 3>> corners) {
  if (!m_parent_slot.empty()) return;  // prepared (set last, so that a failed allocation leaves it unprepared)
  // Each leaf child's distinct corners, once (the tree and the corners' indices never change), and its place.
  std::vector<std::uint32_t> points;
  std::vector<RefitLeaf> leaves;
  for (std::size_t i = 0; i < m_nodes.size(); ++i) {
    for (std::size_t k = 0; k < 4; ++k) {
      const std::uint32_t c = m_nodes[i].child[k];
      if ((c & kLeafBit) == 0) continue;
      const std::uint32_t first = (c & ~kLeafBit) >> 4;
      const auto begin = static_cast<std::uint32_t>(points.size());
      for (std::uint32_t slot = first; slot < first + (c & 0xFu); ++slot) {
        for (const std::uint32_t v : corners[slot]) {
          if (std::find(points.begin() + begin, points.end(), v) == points.end()) points.push_back(v);
        }
      }
      if (points.size() == begin) continue;  // an empty leaf keeps its empty box
      leaves.push_back({static_cast<std::uint32_t>(4 * i + k), begin, static_cast<std::uint32_t>(points.size())});
    }
  }
  std::vector<std::uint32_t> parent(m_nodes.size(), 0);
  for (std::size_t i = 0; i < m_nodes.size(); ++i) {
    for (std::size_t k = 0; k < 4; ++k) {
      const std::uint32_t c = m_nodes[i].child[k];
      if ((c & kLeafBit) == 0) parent[c] = static_cast<std::uint32_t>(4 * i + k);
    }
  }
  m_leaf_points = std::move(points);
  m_refit_leaves = std::move(leaves);
  m_parent_slot = std::move(parent);
}

MAGVINE_HOT_KERNEL void TriangleBvh::refit(std::span<const Vec3> points, const Vec3& lo, const Vec3& hi) {
  MAGVINE_ASSERT(m_parent_slot.size() == m_nodes.size());
  // The build's pad, and the outward rounding folded into it: a float nearest to y is within half an ulp of y,
  // at most 2^-24·|y| ≤ 2^-22·m for every |y| ≤ m + out with out ≤ 3m (m the largest corner coordinate), or 2^-150
  // where the float is subnormal; so rounding x − out to the nearest float lands at or below x − pad (and x + out at
  // or above x + pad) with no test per face.
  const double pad = kBoxPad * (hi - lo).norm();
  const double out = pad + 0x1p-22 * std::max(lo.cwiseAbs().maxCoeff(), hi.cwiseAbs().maxCoeff()) + 0x1p-149;
  // The leaves' boxes from their corners (branch-free minima over each leaf's few distinct points).
  for (const RefitLeaf& leaf : m_refit_leaves) {
    ScalarBox b;
    for (std::uint32_t j = leaf.begin; j < leaf.end; ++j) b.add(points[m_leaf_points[j]]);
    Node& n = m_nodes[leaf.child >> 2];
    const std::size_t k = leaf.child & 3u;
    n.lo_x[k] = static_cast<float>(b.lo_x - out);
    n.lo_y[k] = static_cast<float>(b.lo_y - out);
    n.lo_z[k] = static_cast<float>(b.lo_z - out);
    n.hi_x[k] = static_cast<float>(b.hi_x + out);
    n.hi_y[k] = static_cast<float>(b.hi_y + out);
    n.hi_z[k] = static_cast<float>(b.hi_z + out);
  }
  // Children come after their parents (the flattening appends a node before its subtree): from the last node back,
  // each node's four boxes are final when it is reached, and their union is its box in its parent (empty children's
  // boxes are empty).
  const auto lowest = [](const std::array<float, 4>& v) {
    return std::min(std::min(v[0], v[1]), std::min(v[2], v[3]));
  };
  const auto highest = [](const std::array<float, 4>& v) {
    return std::max(std::max(v[0], v[1]), std::max(v[2], v[3]));
  };
  for (std::size_t i = m_nodes.size(); i-- > 1;) {
    const Node& m = m_nodes[i];
    Node& n = m_nodes[m_parent_slot[i] >> 2];
    const std::size_t k = m_parent_slot[i] & 3u;
    n.lo_x[k] = lowest(m.lo_x);
    n.lo_y[k] = lowest(m.lo_y);
    n.lo_z[k] = lowest(m.lo_z);
    n.hi_x[k] = highest(m.hi_x);
    n.hi_y[k] = highest(m.hi_y);
    n.hi_z[k] = highest(m.hi_z);
  }
}
}  // namespace magvine::anatomy::detail
