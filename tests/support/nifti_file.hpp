#pragma once
// Writes small NIfTI-1 label maps byte by byte from the format's published layout (nifti1.h field offsets), so the
// CT import's reader is checked against files written without libnifti.

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <vector>

namespace magvine::test {

/// A label map to write: dims, voxel sizes [mm], the qform's rotation (unit quaternion w, x, y, z) and offset [mm].
struct NiftiLabels {
  std::array<int, 3> dims{0, 0, 0};
  std::array<float, 3> voxel_mm{1.0f, 1.0f, 1.0f};
  std::array<double, 4> quaternion{1.0, 0.0, 0.0, 0.0};
  std::array<float, 3> offset_mm{0.0f, 0.0f, 0.0f};
  int nt = 1;                 ///< > 1 writes a 4-D image
  bool as_float = false;      ///< float32 voxels instead of int16
  std::vector<float> values;  ///< dims[0]·dims[1]·dims[2]·nt, i fastest
};

/// Fills `labels.values` from f(i, j, k) (one volume).
inline void fill(NiftiLabels& labels, const std::function<float(int, int, int)>& f) {
  labels.values.clear();
  for (int k = 0; k < labels.dims[2]; ++k) {
    for (int j = 0; j < labels.dims[1]; ++j) {
      for (int i = 0; i < labels.dims[0]; ++i) labels.values.push_back(f(i, j, k));
    }
  }
}

/// The voxel (i, j, k) centre in world mm under the qform the file will carry (NIfTI method 2, qfac = 1).
inline std::array<double, 3> voxel_to_world(const NiftiLabels& l, double i, double j, double k) {
  const auto [w, x, y, z] = l.quaternion;
  const double r[3][3] = {{w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)},
                          {2 * (x * y + w * z), w * w + y * y - x * x - z * z, 2 * (y * z - w * x)},
                          {2 * (x * z - w * y), 2 * (y * z + w * x), w * w + z * z - x * x - y * y}};
  const double s[3] = {i * l.voxel_mm[0], j * l.voxel_mm[1], k * l.voxel_mm[2]};
  std::array<double, 3> out{};
  for (int a = 0; a < 3; ++a) out[a] = r[a][0] * s[0] + r[a][1] * s[1] + r[a][2] * s[2] + l.offset_mm[a];
  return out;
}

/// Writes `l` as a single-file NIfTI-1 (.nii): 348-byte header, 4 empty extension bytes, voxels at offset 352.
inline void write_nifti(const std::filesystem::path& path, const NiftiLabels& l) {
  std::array<char, 352> h{};
  const auto put = [&h](std::size_t offset, const auto value) { std::memcpy(h.data() + offset, &value, sizeof value); };
  put(0, std::int32_t{348});
  put(40, std::int16_t(l.nt > 1 ? 4 : 3));
  for (int d = 0; d < 3; ++d) put(42 + 2 * d, std::int16_t(l.dims[static_cast<std::size_t>(d)]));
  put(48, std::int16_t(l.nt));
  for (int d = 4; d < 7; ++d) put(42 + 2 * d, std::int16_t{1});
  put(70, std::int16_t(l.as_float ? 16 : 4));  // DT_FLOAT32 or DT_INT16
  put(72, std::int16_t(l.as_float ? 32 : 16));
  put(76, 1.0f);  // qfac
  for (int d = 0; d < 3; ++d) put(80 + 4 * d, l.voxel_mm[static_cast<std::size_t>(d)]);
  put(108, 352.0f);                                        // vox_offset
  put(252, std::int16_t{1});                               // qform_code: scanner anatomical
  const double sign = l.quaternion[0] < 0.0 ? -1.0 : 1.0;  // the file stores b, c, d with a ≥ 0
  for (int q = 0; q < 3; ++q) put(256 + 4 * q, float(sign * l.quaternion[static_cast<std::size_t>(q + 1)]));
  for (int d = 0; d < 3; ++d) put(268 + 4 * d, l.offset_mm[static_cast<std::size_t>(d)]);
  std::memcpy(h.data() + 344, "n+1", 4);
  std::ofstream out(path, std::ios::binary);
  out.write(h.data(), static_cast<std::streamsize>(h.size()));
  for (const float v : l.values) {
    if (l.as_float) {
      out.write(reinterpret_cast<const char*>(&v), sizeof v);
    } else {
      const auto s = static_cast<std::int16_t>(std::lround(v));
      out.write(reinterpret_cast<const char*>(&s), sizeof s);
    }
  }
}

}  // namespace magvine::test
