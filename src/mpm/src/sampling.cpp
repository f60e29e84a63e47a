#include "magvine/mpm/sampling.hpp"

#include <algorithm>
#include <cmath>
#include <array>
#include <random>
#include <string>

#include "magvine/core/error.hpp"

namespace magvine::mpm {
namespace {

void check_spacing(const LatticeOptions& o) {
  if (!(o.spacing > 0.0 && std::isfinite(o.spacing))) {
    throw InputError("particle sampling: spacing must be a positive length");
  }
}

/// Moves each point within its cell (uniform, seeded; the same points for the same seed).
void jitter(std::vector<Vec3>& points, const LatticeOptions& o, int dimension) {
  if (!o.jitter) return;
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  for (Vec3& p : points) {
    for (int a = 0; a < dimension; ++a) p[a] += u(rng) * o.spacing;
  }
}

}  // namespace

std::vector<Vec3> sample_box(const Vec3& min, const Vec3& max, const LatticeOptions& o, int dimension) {
  check_spacing(o);
  std::array<long, 3> count{1, 1, 1};
  for (int a = 0; a < dimension; ++a) {
    count[static_cast<std::size_t>(a)] = std::max(1L, std::lround((max[a] - min[a]) / o.spacing));
  }
  std::vector<Vec3> out;
  out.reserve(static_cast<std::size_t>(count[0] * count[1] * count[2]));
  for (long i = 0; i < count[0]; ++i)
    for (long j = 0; j < count[1]; ++j)
      for (long k = 0; k < count[2]; ++k) {
        Vec3 p = min + o.spacing * Vec3(static_cast<double>(i) + 0.5, static_cast<double>(j) + 0.5,
                                        static_cast<double>(k) + 0.5);
        if (dimension == 2) p.z() = min.z();
        out.push_back(p);
      }
  jitter(out, o, dimension);
  return out;
}

std::vector<Vec3> sample_cylinder(const Vec3& a, const Vec3& b, double radius, const LatticeOptions& o) {
  check_spacing(o);
  const Vec3 axis = b - a;
  const double len = axis.norm();
  if (!(len > 0.0) || !(radius > 0.0)) throw InputError("particle sampling: a cylinder needs a length and a radius");
  const Vec3 t = axis / len;
  const Vec3 u = t.unitOrthogonal();
  const Vec3 w = t.cross(u);
  // Lattice in the cylinder's own frame: the cross-section's lattice is centred on the axis.
  const long nr = static_cast<long>(std::ceil(radius / o.spacing));
  const long nl = std::max(1L, std::lround(len / o.spacing));
  std::vector<Vec3> out;
  for (long k = 0; k < nl; ++k)
    for (long i = -nr; i < nr; ++i)
      for (long j = -nr; j < nr; ++j) {
        const double x = (static_cast<double>(i) + 0.5) * o.spacing;
        const double y = (static_cast<double>(j) + 0.5) * o.spacing;
        if (x * x + y * y > radius * radius) continue;
        out.push_back(a + (static_cast<double>(k) + 0.5) * o.spacing * t + x * u + y * w);
      }
  jitter(out, o, 3);
  return out;
}

std::vector<Vec3> sample_mesh(const anatomy::TriangleMesh& mesh, const LatticeOptions& o, const std::string& who) {
  check_spacing(o);
  anatomy::validate_mesh(mesh, who);
  const anatomy::Aabb box = anatomy::bounding_box(mesh);
  const double h = o.spacing;
  const long ny = std::max(1L, static_cast<long>(std::ceil((box.max.y() - box.min.y()) / h)));
  const long nz = std::max(1L, static_cast<long>(std::ceil((box.max.z() - box.min.z()) / h)));
  const long nx = std::max(1L, static_cast<long>(std::ceil((box.max.x() - box.min.x()) / h)));
  // Columns along x through (y_j, z_k) = cell centres; each triangle adds its crossing to the columns its y–z
  // shadow covers. Crossings of one column sorted, then parity decides which cell centres lie inside.
  std::vector<std::vector<double>> hits(static_cast<std::size_t>(ny * nz));
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const Vec3& p0 = anatomy::corner(mesh, t, 0);
    const Vec3& p1 = anatomy::corner(mesh, t, 1);
    const Vec3& p2 = anatomy::corner(mesh, t, 2);
    const double ylo = std::min({p0.y(), p1.y(), p2.y()}), yhi = std::max({p0.y(), p1.y(), p2.y()});
    const double zlo = std::min({p0.z(), p1.z(), p2.z()}), zhi = std::max({p0.z(), p1.z(), p2.z()});
    const long j0 = std::max(0L, static_cast<long>(std::ceil((ylo - box.min.y()) / h - 0.5)));
    const long j1 = std::min(ny - 1, static_cast<long>(std::floor((yhi - box.min.y()) / h - 0.5)));
    const long k0 = std::max(0L, static_cast<long>(std::ceil((zlo - box.min.z()) / h - 0.5)));
    const long k1 = std::min(nz - 1, static_cast<long>(std::floor((zhi - box.min.z()) / h - 0.5)));
    for (long j = j0; j <= j1; ++j)
      for (long k = k0; k <= k1; ++k) {
        // A tiny fixed offset keeps columns off the lattice-aligned edges of CAD meshes (parity ambiguity).
        const double y = box.min.y() + (static_cast<double>(j) + 0.5) * h + 1.3e-7 * h;
        const double z = box.min.z() + (static_cast<double>(k) + 0.5) * h + 0.7e-7 * h;
        // Barycentric test of (y, z) in the triangle's y–z projection.
        const double d = (p1.y() - p0.y()) * (p2.z() - p0.z()) - (p2.y() - p0.y()) * (p1.z() - p0.z());
        if (d == 0.0) continue;
        const double b1 = ((y - p0.y()) * (p2.z() - p0.z()) - (p2.y() - p0.y()) * (z - p0.z())) / d;
        const double b2 = ((p1.y() - p0.y()) * (z - p0.z()) - (y - p0.y()) * (p1.z() - p0.z())) / d;
        if (b1 < 0.0 || b2 < 0.0 || b1 + b2 > 1.0) continue;
        hits[static_cast<std::size_t>(j * nz + k)].push_back(p0.x() + b1 * (p1.x() - p0.x()) +
                                                              b2 * (p2.x() - p0.x()));
      }
  }
  std::vector<Vec3> out;
  for (long j = 0; j < ny; ++j)
    for (long k = 0; k < nz; ++k) {
      std::vector<double>& c = hits[static_cast<std::size_t>(j * nz + k)];
      std::sort(c.begin(), c.end());
      std::size_t next = 0;
      bool inside = false;
      for (long i = 0; i < nx; ++i) {
        const double x = box.min.x() + (static_cast<double>(i) + 0.5) * h;
        while (next < c.size() && c[next] < x) {
          inside = !inside;
          ++next;
        }
        if (inside) {
          out.emplace_back(x, box.min.y() + (static_cast<double>(j) + 0.5) * h,
                           box.min.z() + (static_cast<double>(k) + 0.5) * h);
        }
      }
    }
  if (out.empty()) {
    throw InputError(who + ": no particle lies inside the mesh (is it closed, and the spacing smaller than the part?)");
  }
  jitter(out, o, 3);
  return out;
}

}  // namespace magvine::mpm
