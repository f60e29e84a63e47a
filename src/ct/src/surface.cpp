// The lumen surface of a label map: OpenVDB does the surface work (segmentation.hpp lists the pipeline).
#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetFilter.h>
#include <openvdb/tools/LevelSetRebuild.h>
#include <openvdb/tools/LevelSetUtil.h>
#include <openvdb/tools/VolumeToMesh.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <sstream>

#include "magvine/anatomy/mesh_clean.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/stopwatch.hpp"
#include "magvine/core/text.hpp"
#include "magvine/ct/segmentation.hpp"

namespace magvine::ct {

namespace {

/// A length [m] in mm for messages, 3 significant digits.
std::string mm(double metres) {
  return printf_string("%.3g", 1e3 * metres);
}

/// OpenVDB's transform (row-vector convention, mm) of a voxel → world map given in metres.
openvdb::math::Transform::Ptr vdb_transform(const Eigen::Affine3d& index_to_world) {
  openvdb::math::Mat4d m = openvdb::math::Mat4d::identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) m[c][r] = 1e3 * index_to_world.matrix()(r, c);
  }
  return openvdb::math::Transform::createLinearTransform(m);
}

/// Largest angle between a grid axis and the nearest world axis [°].
double obliquity_deg(const Eigen::Matrix3d& linear) {
  double worst = 0.0;
  for (int c = 0; c < 3; ++c) {
    const Eigen::Vector3d axis = linear.col(c).normalized();
    worst = std::max(worst, std::acos(std::clamp(axis.cwiseAbs().maxCoeff(), 0.0, 1.0)) * 180.0 / std::numbers::pi);
  }
  return worst;
}

/// The labels present and their counts, for the message when the asked one is missing.
std::string labels_present(const std::vector<std::int32_t>& labels) {
  std::map<std::int32_t, std::size_t> counts;
  for (const std::int32_t l : labels) ++counts[l];
  std::ostringstream s;
  int shown = 0;
  for (const auto& [label, n] : counts) {
    if (shown++ == 10) {
      s << ", ...";
      break;
    }
    s << (shown > 1 ? ", " : "") << label << " (" << n << " voxels)";
  }
  return s.str();
}

/// Taubin's λ|μ smoothing (Taubin, "A signal processing approach to fair surface design", SIGGRAPH 1995) applied to
/// the signed distance instead of mesh vertices: each pass moves φ by λ = 0.5 towards its 3×3×3 box mean, then by
/// μ = −0.53 (away from it). The pair is a low-pass filter, (1 − λk)(1 − μk) for a component of frequency k: the
/// voxel staircase (the highest frequencies) is damped, while the slow curvature of a tube — which a plain filter
/// turns into mean-curvature shrinkage, 5 % of the volume a pass and the last generations gone — passes
/// unchanged. Afterwards φ is clamped to within `band` of the voxel surface's distance, so no feature moves by
/// more than half a voxel whatever the passes.
void smooth_without_shrinking(openvdb::FloatGrid& sdf, int passes, float band) {
  const openvdb::FloatGrid::ConstPtr voxel_surface = sdf.deepCopy();
  for (int pass = 0; pass < passes; ++pass) {
    for (const float factor : {0.5f, -0.53f}) {
      const openvdb::FloatGrid::Ptr mean = sdf.deepCopy();
      openvdb::tools::LevelSetFilter<openvdb::FloatGrid> filter(*mean);
      filter.mean(1);
      openvdb::FloatGrid::ConstAccessor m = mean->getConstAccessor();
      for (auto v = sdf.beginValueOn(); v; ++v) v.setValue(*v + factor * (m.getValue(v.getCoord()) - *v));
    }
  }
  openvdb::FloatGrid::ConstAccessor original = voxel_surface->getConstAccessor();
  for (auto v = sdf.beginValueOn(); v; ++v) {
    const float phi0 = original.getValue(v.getCoord());
    v.setValue(std::clamp(*v, phi0 - band, phi0 + band));
  }
}

}  // namespace

anatomy::TriangleMesh segmentation_surface(const LabelVolume& volume, const SurfaceOptions& options,
                                           const std::string& file, SurfaceReport* report) {
  const Stopwatch clock;
  SurfaceReport local;
  SurfaceReport& r = report != nullptr ? *report : local;
  r.dims = volume.dims;
  r.spacing = volume.spacing();
  r.frame_source = volume.frame_source;
  r.obliquity_deg = obliquity_deg(volume.index_to_world.linear());
  if (!(options.adaptivity >= 0.0 && options.adaptivity <= 1.0)) {
    throw InputError(file, 0, "adaptivity", "must lie in [0, 1]");
  }
  if (options.smoothing < 0 || options.smoothing > 20) throw InputError(file, 0, "smoothing", "must lie in 0..20");
  const double finest = std::min({r.spacing[0], r.spacing[1], r.spacing[2]});
  const double coarsest = std::max({r.spacing[0], r.spacing[1], r.spacing[2]});
  r.voxel = options.voxel > 0.0 ? options.voxel : finest;
  if (!(r.voxel >= 0.25 * finest && r.voxel <= 20.0 * coarsest)) {
    throw InputError(file, 0, "voxel",
                     "level-set voxel " + mm(r.voxel) + " mm is outside 0.25-20 times the map's " + mm(finest) + "-" +
                         mm(coarsest) + " mm voxels");
  }
  if (volume.frame_source == "pixdim") {
    r.notes.push_back("no qform or sform: voxel sizes only, axes taken as the world's (orientation unknown)");
  }
  if (coarsest > 1.01 * finest) {
    r.notes.push_back("anisotropic voxels " + mm(r.spacing[0]) + " x " + mm(r.spacing[1]) + " x " + mm(r.spacing[2]) +
                      " mm: surfaced through an isotropic " + mm(r.voxel) + " mm level set");
  }
  if (r.obliquity_deg > 0.01) {
    std::ostringstream s;
    s.precision(3);
    s << "oblique grid (axes up to " << r.obliquity_deg << " deg from the world's): surfaced in the world frame";
    r.notes.push_back(s.str());
  }

  // The label's voxels, inside −½ and outside +½ (the background): the zero crossing lies half way between an
  // inside and an outside voxel centre, where a marching-cubes surface of the binary map lies.
  openvdb::initialize();
  const openvdb::FloatGrid::Ptr mask = openvdb::FloatGrid::create(0.5f);
  mask->setTransform(vdb_transform(volume.index_to_world));
  {
    openvdb::FloatGrid::Accessor acc = mask->getAccessor();
    const auto [nx, ny, nz] = volume.dims;
    std::size_t n = 0;
    for (int k = 0; k < nz; ++k) {
      for (int j = 0; j < ny; ++j) {
        for (int i = 0; i < nx; ++i, ++n) {
          if (volume.labels[n] == options.label) acc.setValueOn(openvdb::Coord(i, j, k), -0.5f);
        }
      }
    }
  }
  r.label_voxels = mask->activeVoxelCount();
  if (r.label_voxels == 0) {
    throw InputError(
        file, 0, "label",
        "no voxel carries label " + std::to_string(options.label) + "; the map holds " + labels_present(volume.labels));
  }
  std::vector<openvdb::FloatGrid::Ptr> segments;
  openvdb::tools::segmentActiveVoxels(*mask, segments);
  for (const auto& s : segments) r.components.push_back(s->activeVoxelCount());
  if (segments.size() > 1) {
    std::ostringstream s;
    s << segments.size() << " disconnected airway parts (6-connected voxels): kept the largest, " << r.components[0]
      << " of " << r.label_voxels << " voxels; dropped " << segments.size() - 1 << " with "
      << r.label_voxels - r.components[0] << " voxels (largest dropped " << r.components[1] << ")";
    r.warnings.push_back(s.str());
  }

  // Rebuilt as a signed distance on an isotropic grid aligned with the world axes, smoothed, meshed.
  const openvdb::math::Transform::Ptr iso = openvdb::math::Transform::createLinearTransform(1e3 * r.voxel);
  const openvdb::FloatGrid::Ptr sdf = openvdb::tools::levelSetRebuild(*segments.front(), 0.0f, 3.0f, iso.get());
  if (options.smoothing > 0)
    smooth_without_shrinking(*sdf, options.smoothing, 0.5f * static_cast<float>(1e3 * r.voxel));
  std::vector<openvdb::Vec3s> points;
  std::vector<openvdb::Vec3I> tris;
  std::vector<openvdb::Vec4I> quads;
  openvdb::tools::volumeToMesh(*sdf, points, tris, quads, 0.0, options.adaptivity);

  anatomy::TriangleMesh mesh;
  mesh.vertices.reserve(points.size());
  const double flip = options.frame == Frame::kLps ? -1.0 : 1.0;  // RAS → LPS: x, y negated (a rotation)
  for (const openvdb::Vec3s& p : points) {
    mesh.vertices.emplace_back(1e-3 * flip * double(p[0]), 1e-3 * flip * double(p[1]), 1e-3 * double(p[2]));
  }
  mesh.triangles.reserve(tris.size() + 2 * quads.size());
  for (const openvdb::Vec3I& t : tris) mesh.triangles.push_back({t[0], t[1], t[2]});
  for (const openvdb::Vec4I& q : quads) {
    // Split along the shorter diagonal: the better-shaped pair of triangles.
    const double d02 = (mesh.vertices[q[0]] - mesh.vertices[q[2]]).squaredNorm();
    const double d13 = (mesh.vertices[q[1]] - mesh.vertices[q[3]]).squaredNorm();
    if (d02 <= d13) {
      mesh.triangles.push_back({q[0], q[1], q[2]});
      mesh.triangles.push_back({q[0], q[2], q[3]});
    } else {
      mesh.triangles.push_back({q[0], q[1], q[3]});
      mesh.triangles.push_back({q[1], q[2], q[3]});
    }
  }
  anatomy::weld_and_clean(mesh);
  const anatomy::DroppedParts dropped = anatomy::keep_largest_component(mesh);
  if (dropped.cavities + dropped.fragments > 0) {
    std::ostringstream s;
    s.precision(3);
    s << "removed " << dropped.cavities << " cavities (" << 1e9 * dropped.cavity_volume
      << " mm^3: unlabelled voxels enclosed by the lumen) and " << dropped.fragments << " fragments ("
      << 1e9 * dropped.fragment_volume
      << " mm^3: pieces joined to the tree only by a neck thinner than a voxel) from the surface";
    r.notes.push_back(s.str());
  }
  if (anatomy::signed_volume(mesh) < 0.0) anatomy::flip_orientation(mesh);
  r.seconds_surface = clock.seconds();
  return mesh;
}

anatomy::TriangleMesh import_segmentation(const std::filesystem::path& path, const SurfaceOptions& options,
                                          SurfaceReport* report) {
  const Stopwatch clock;
  SurfaceReport local;
  SurfaceReport& r = report != nullptr ? *report : local;
  const LabelVolume volume = read_nifti_labels(path);
  const double read = clock.seconds();
  anatomy::TriangleMesh mesh = segmentation_surface(volume, options, path.string(), &r);
  r.seconds_read = read;
  return mesh;
}

}  // namespace magvine::ct
