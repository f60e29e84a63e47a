#include "magvine/anatomy/primitives.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "magvine/core/units.hpp"

namespace magvine::anatomy {

TriangleMesh make_tube(const TubeSpec& spec) {
  if (spec.segments < 3 || !(spec.radius > 0.0) || !(spec.length > 0.0) || spec.rings == 1 || spec.rings < 0) {
    throw std::invalid_argument("make_tube: needs radius > 0, length > 0, segments >= 3, rings = 0 or >= 2");
  }
  const auto n = static_cast<std::uint32_t>(spec.segments);
  const double arc = 2.0 * kPi * spec.radius / spec.segments;
  const auto rings = static_cast<std::uint32_t>(
      spec.rings > 0 ? spec.rings : std::max(2, static_cast<int>(std::ceil(spec.length / arc)) + 1));

  TriangleMesh mesh;
  mesh.vertices.reserve(n * rings + 2);
  for (std::uint32_t j = 0; j < rings; ++j) {
    const double z = spec.length * j / (rings - 1);
    for (std::uint32_t i = 0; i < n; ++i) {
      const double phi = 2.0 * kPi * i / n;
      mesh.vertices.emplace_back(spec.radius * std::cos(phi), spec.radius * std::sin(phi), z);
    }
  }
  // Wall: quads (i, j)–(i+1, j+1) split in two, counter-clockwise seen from outside.
  auto at = [n](std::uint32_t i, std::uint32_t j) { return j * n + i % n; };
  for (std::uint32_t j = 0; j + 1 < rings; ++j) {
    for (std::uint32_t i = 0; i < n; ++i) {
      mesh.triangles.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      mesh.triangles.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  }
  if (spec.capped) {
    // Fans to a centre vertex: the bottom cap faces −z, the top cap +z.
    const auto bottom = static_cast<std::uint32_t>(mesh.vertices.size());
    mesh.vertices.emplace_back(0.0, 0.0, 0.0);
    const auto top = bottom + 1;
    mesh.vertices.emplace_back(0.0, 0.0, spec.length);
    for (std::uint32_t i = 0; i < n; ++i) {
      mesh.triangles.push_back({bottom, at(i + 1, 0), at(i, 0)});
      mesh.triangles.push_back({top, at(i, rings - 1), at(i + 1, rings - 1)});
    }
  }
  return mesh;
}

}  // namespace magvine::anatomy
