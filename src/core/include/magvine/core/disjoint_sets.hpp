#pragma once
/// Disjoint sets (union–find with path halving): connected components of meshes and voxel sets.

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <vector>

namespace magvine {

class DisjointSets {
 public:
  explicit DisjointSets(std::size_t n) : m_parent(n) { std::iota(m_parent.begin(), m_parent.end(), 0u); }
  /// The representative of x's set: the smallest member united so far.
  std::uint32_t find(std::uint32_t x) {
    while (m_parent[x] != x) x = m_parent[x] = m_parent[m_parent[x]];
    return x;
  }
  void unite(std::uint32_t a, std::uint32_t b) {
    a = find(a);
    b = find(b);
    if (a != b) m_parent[std::max(a, b)] = std::min(a, b);
  }

 private:
  std::vector<std::uint32_t> m_parent;
};

}  // namespace magvine
