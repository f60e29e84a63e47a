#include "magvine/anatomy/mesh_clean.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "magvine/core/disjoint_sets.hpp"

namespace magvine::anatomy {
namespace {

constexpr std::uint32_t kEmpty = std::numeric_limits<std::uint32_t>::max();

using CellKey = std::array<std::int64_t, 3>;

// Open-addressing hash of quantised positions → welded vertex index. Faster than std::unordered_map by a wide
// margin on millions of STL corners. It stores only the index (4 bytes a slot): the key of a slot is recomputed
// from the welded vertex it names. It starts at a sixth of the corners (STL repeats each vertex about six times)
// and doubles at half load, so the table stays small enough to live in cache.
class CellTable {
 public:
  CellTable(std::size_t corners, const std::vector<Vec3>& welded, const Vec3& origin, double inv)
      : m_welded(welded), m_origin(origin), m_inv(inv) {
    std::size_t size = 1024;
    while (size < corners / 3) size *= 2;
    m_values.assign(size, kEmpty);
    m_mask = size - 1;
  }

  CellKey key(const Vec3& p) const {
    return {std::llround((p.x() - m_origin.x()) * m_inv), std::llround((p.y() - m_origin.y()) * m_inv),
            std::llround((p.z() - m_origin.z()) * m_inv)};
  }

  // Returns the index stored for `key`, or stores `value` and returns it.
  std::uint32_t find_or_insert(const CellKey& key, std::uint32_t value) {
    for (std::size_t i = hash(key) & m_mask;; i = (i + 1) & m_mask) {
      if (m_values[i] == kEmpty) {
        m_values[i] = value;
        if (2 * ++m_count > m_values.size()) grow();
        return value;
      }
      if (this->key(m_welded[m_values[i]]) == key) return m_values[i];
    }
  }

 private:
  static std::uint64_t hash(const CellKey& key) {
    std::uint64_t h = static_cast<std::uint64_t>(key[0]) * 0x9E3779B97F4A7C15ull;
    h ^= static_cast<std::uint64_t>(key[1]) * 0xC2B2AE3D27D4EB4Full + (h << 6) + (h >> 2);
    h ^= static_cast<std::uint64_t>(key[2]) * 0x165667B19E3779F9ull + (h << 6) + (h >> 2);
    return h;
  }

  void grow() {
    std::vector<std::uint32_t> old = std::move(m_values);
    m_values.assign(2 * old.size(), kEmpty);
    m_mask = m_values.size() - 1;
    for (const std::uint32_t v : old) {
      if (v == kEmpty) continue;
      std::size_t i = hash(key(m_welded[v])) & m_mask;
      while (m_values[i] != kEmpty) i = (i + 1) & m_mask;
      m_values[i] = v;
    }
  }

  const std::vector<Vec3>& m_welded;
  Vec3 m_origin;
  double m_inv;
  std::vector<std::uint32_t> m_values;
  std::size_t m_mask = 0;
  std::size_t m_count = 0;
};

}  // namespace

CleanStats weld_and_clean(TriangleMesh& mesh, double tolerance) {
  CleanStats stats;
  if (mesh.triangles.empty()) {
    stats.unused_removed = mesh.vertices.size();
    mesh.vertices.clear();
    return stats;
  }
  const Aabb box = bounding_box(mesh);
  if (!(tolerance > 0.0)) tolerance = kWeldRelativeTolerance * std::max((box.max - box.min).norm(), 1e-300);
  const double inv = 1.0 / tolerance;

  // Weld: visit corners in triangle order, so new vertex ids follow first use and unused vertices vanish.
  std::vector<std::uint32_t> remap(mesh.vertices.size(), kEmpty);
  std::vector<Vec3> welded;
  welded.reserve(mesh.vertices.size());  // no reallocation while welding (speed only)
  CellTable table(mesh.vertices.size(), welded, box.min, inv);
  for (Triangle& tri : mesh.triangles) {
    for (std::uint32_t& v : tri) {
      if (remap[v] == kEmpty) {
        const Vec3& p = mesh.vertices[v];
        const auto next = static_cast<std::uint32_t>(welded.size());
        welded.push_back(p);  // provisional: the table compares against it
        remap[v] = table.find_or_insert(table.key(p), next);
        if (remap[v] != next) welded.pop_back();
      }
      v = remap[v];
    }
  }
  std::size_t used = 0;
  for (const std::uint32_t r : remap) used += r != kEmpty ? 1 : 0;
  stats.unused_removed = mesh.vertices.size() - used;
  stats.vertices_welded = used - welded.size();
  mesh.vertices = std::move(welded);

  // Degenerate triangles: a repeated vertex, or exactly zero area (collinear corners).
  std::vector<Triangle> kept;
  kept.reserve(mesh.triangles.size());
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const Triangle& tri = mesh.triangles[t];
    const bool repeated = tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2];
    if (repeated || area_vector(mesh, t).squaredNorm() == 0.0) {
      ++stats.degenerate_removed;
    } else {
      kept.push_back(tri);
    }
  }

  // Duplicates: the same vertex set as an earlier triangle, whatever the winding. Sort (sorted triple, index)
  // and keep the first of each run.
  std::vector<std::pair<Triangle, std::uint32_t>> keys(kept.size());
  for (std::size_t t = 0; t < kept.size(); ++t) {
    Triangle s = kept[t];
    std::sort(s.begin(), s.end());
    keys[t] = {s, static_cast<std::uint32_t>(t)};
  }
  std::sort(keys.begin(), keys.end());
  std::vector<char> drop(kept.size(), 0);
  for (std::size_t i = 1; i < keys.size(); ++i) {
    if (keys[i].first == keys[i - 1].first) {
      drop[keys[i].second] = 1;
      ++stats.duplicate_removed;
    }
  }
  mesh.triangles.clear();
  for (std::size_t t = 0; t < kept.size(); ++t) {
    if (drop[t] == 0) mesh.triangles.push_back(kept[t]);
  }

  // Removing triangles can orphan vertices: compact once more.
  std::vector<std::uint32_t> compact(mesh.vertices.size(), kEmpty);
  std::vector<Vec3> vertices;
  vertices.reserve(mesh.vertices.size());
  for (Triangle& tri : mesh.triangles) {
    for (std::uint32_t& v : tri) {
      if (compact[v] == kEmpty) {
        compact[v] = static_cast<std::uint32_t>(vertices.size());
        vertices.push_back(mesh.vertices[v]);
      }
      v = compact[v];
    }
  }
  stats.unused_removed += mesh.vertices.size() - vertices.size();
  mesh.vertices = std::move(vertices);
  return stats;
}

DroppedParts keep_largest_component(TriangleMesh& mesh) {
  DroppedParts dropped;
  const std::size_t n = mesh.triangles.size();
  if (n == 0) return dropped;
  // Triangles sharing a vertex are joined (a manifold mesh's parts share no vertex).
  DisjointSets sets(n);
  std::vector<std::uint32_t> first_user(mesh.vertices.size(), kEmpty);
  for (std::uint32_t t = 0; t < n; ++t) {
    for (const std::uint32_t v : mesh.triangles[t]) {
      if (first_user[v] == kEmpty) {
        first_user[v] = t;
      } else {
        sets.unite(first_user[v], t);
      }
    }
  }
  std::vector<double> six_volume(n, 0.0);
  for (std::uint32_t t = 0; t < n; ++t) {
    six_volume[sets.find(t)] += corner(mesh, t, 0).dot(corner(mesh, t, 1).cross(corner(mesh, t, 2)));
  }
  std::uint32_t keep = 0;
  for (std::uint32_t t = 0; t < n; ++t) {
    if (sets.find(t) == t && std::abs(six_volume[t]) > std::abs(six_volume[keep])) keep = t;
  }
  const double sign = six_volume[keep] < 0.0 ? -1.0 : 1.0;
  for (std::uint32_t t = 0; t < n; ++t) {
    if (sets.find(t) != t || t == keep) continue;
    if (sign * six_volume[t] < 0.0) {
      ++dropped.cavities;
      dropped.cavity_volume += std::abs(six_volume[t]) / 6.0;
    } else {
      ++dropped.fragments;
      dropped.fragment_volume += std::abs(six_volume[t]) / 6.0;
    }
  }
  if (dropped.cavities + dropped.fragments == 0) return dropped;
  std::erase_if(mesh.triangles, [&](const Triangle& tri) { return sets.find(first_user[tri[0]]) != keep; });
  weld_and_clean(mesh);  // drops the vertices only the removed parts used
  return dropped;
}

}  // namespace magvine::anatomy
