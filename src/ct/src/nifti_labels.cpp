// Reading a NIfTI label map with libnifti2 (public domain; NIfTI-1 and -2, gzip through znzlib).
#include <nifti2_io.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>

#include "magvine/core/error.hpp"
#include "magvine/ct/segmentation.hpp"

namespace magvine::ct {

namespace {

struct NiftiFree {
  void operator()(nifti_image* image) const { nifti_image_free(image); }
};

/// The voxel → world map in mm from a 4×4 NIfTI matrix (row-major, column vector convention).
Eigen::Affine3d affine_from(const nifti_dmat44& m) {
  Eigen::Affine3d a = Eigen::Affine3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) a.matrix()(r, c) = m.m[r][c];
  }
  return a;
}

/// Copies the voxels of type T into int32 labels; false when a value is not a whole number in int32's range.
template <typename T>
bool copy_labels(const void* data, std::size_t count, std::vector<std::int32_t>& out) {
  out.resize(count);
  const T* v = static_cast<const T*>(data);
  for (std::size_t n = 0; n < count; ++n) {
    const double x = static_cast<double>(v[n]);
    if (!(x == std::floor(x) && x >= -2147483648.0 && x <= 2147483647.0)) return false;
    out[n] = static_cast<std::int32_t>(x);
  }
  return true;
}

}  // namespace

std::array<double, 3> LabelVolume::spacing() const {
  const Eigen::Matrix3d l = index_to_world.linear();
  return {l.col(0).norm(), l.col(1).norm(), l.col(2).norm()};
}

LabelVolume read_nifti_labels(const std::filesystem::path& path) {
  const std::string file = path.string();
  if (!std::filesystem::is_regular_file(path)) throw InputError(file, 0, "", "no such file");
  nifti_set_debug_level(0);  // libnifti's own messages go to stderr; ours name the file
  if (is_nifti_file(file.c_str()) <= 0) {
    throw InputError(file, 0, "", "not a NIfTI file (expected a .nii or .nii.gz label map with a NIfTI-1/2 header)");
  }
  const std::unique_ptr<nifti_image, NiftiFree> image(nifti_image_read(file.c_str(), 1));
  if (image == nullptr || image->data == nullptr) {
    throw InputError(file, 0, "", "unreadable NIfTI file (truncated or corrupt image data)");
  }
  const nifti_image& im = *image;
  if (im.ndim < 3 || im.nx < 2 || im.ny < 2 || im.nz < 2) {
    throw InputError(file, 0, "dim",
                     "a label map needs 3 dimensions of at least 2 voxels (got " + std::to_string(im.nx) + " x " +
                         std::to_string(im.ny) + " x " + std::to_string(im.nz) + ")");
  }
  for (int d = 4; d <= im.ndim && d < 8; ++d) {
    if (im.dim[d] > 1) throw InputError(file, 0, "dim", "a 4-D image; give a 3-D label map");
  }
  LabelVolume v;
  v.dims = {static_cast<int>(im.nx), static_cast<int>(im.ny), static_cast<int>(im.nz)};
  const std::size_t count =
      static_cast<std::size_t>(im.nx) * static_cast<std::size_t>(im.ny) * static_cast<std::size_t>(im.nz);
  Eigen::Affine3d mm;
  if (im.qform_code > 0) {
    mm = affine_from(im.qto_xyz);
    v.frame_source = "qform";
  } else if (im.sform_code > 0) {
    mm = affine_from(im.sto_xyz);
    v.frame_source = "sform";
  } else {
    mm = Eigen::Affine3d::Identity();
    mm.linear() = Eigen::Vector3d(std::abs(im.dx), std::abs(im.dy), std::abs(im.dz)).asDiagonal();
    v.frame_source = "pixdim";
  }
  const double det = mm.linear().determinant();
  if (!std::isfinite(det) || std::abs(det) < 1e-12 || !mm.matrix().allFinite()) {
    throw InputError(file, 0, v.frame_source, "the voxel-to-world map is singular or not finite");
  }
  v.index_to_world = mm;
  v.index_to_world.matrix().topRows<3>() *= 1e-3;  // mm → m (rotation part and translation)
  bool whole = false;
  switch (im.datatype) {
    case DT_UINT8:
      whole = copy_labels<std::uint8_t>(im.data, count, v.labels);
      break;
    case DT_INT8:
      whole = copy_labels<std::int8_t>(im.data, count, v.labels);
      break;
    case DT_INT16:
      whole = copy_labels<std::int16_t>(im.data, count, v.labels);
      break;
    case DT_UINT16:
      whole = copy_labels<std::uint16_t>(im.data, count, v.labels);
      break;
    case DT_INT32:
      whole = copy_labels<std::int32_t>(im.data, count, v.labels);
      break;
    case DT_UINT32:
      whole = copy_labels<std::uint32_t>(im.data, count, v.labels);
      break;
    case DT_INT64:
      whole = copy_labels<std::int64_t>(im.data, count, v.labels);
      break;
    case DT_UINT64:
      whole = copy_labels<std::uint64_t>(im.data, count, v.labels);
      break;
    case DT_FLOAT32:
      whole = copy_labels<float>(im.data, count, v.labels);
      break;
    case DT_FLOAT64:
      whole = copy_labels<double>(im.data, count, v.labels);
      break;
    default:
      throw InputError(file, 0, "datatype",
                       std::string("a label map must hold integers, got ") + nifti_datatype_string(im.datatype));
  }
  if (!whole) {
    throw InputError(file, 0, "datatype",
                     "voxels with fractional or out-of-range values: a label map, not an intensity image, is needed");
  }
  return v;
}

}  // namespace magvine::ct
