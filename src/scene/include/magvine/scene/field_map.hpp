#pragma once
/// Field maps: |B| and |∇B| sampled on a square in a coordinate plane, for plots (tools/plot_field_map.py).

#include <filesystem>
#include <string>

#include "magvine/magnetics/field_model.hpp"

namespace magvine::scene {

struct FieldMapSpec {
  std::string plane = "xz";    ///< two distinct axes of x, y, z: first is u (horizontal), second v
  Vec3 center = Vec3::Zero();  ///< centre of the square, world [m]
  double half_width = 0.3;     ///< half the side of the square [m]
  int resolution = 201;        ///< samples per side (≥ 2)
};

/// Samples the model (at its rest poses) and writes
///  - `csv`: columns u,v,x,y,z,Bx,By,Bz,B,gradB in SI (gradB = Frobenius norm of G [T/m]);
///  - `json`: the plane, the grid and, per source, its kind, name, projected outline and magnetisation
///    direction in plane coordinates (for drawing).
/// Both are written atomically; the folder is created once the spec is valid. Throws InputError otherwise.
void write_field_map(const magnetics::FieldModel& model, const FieldMapSpec& spec, const std::filesystem::path& csv,
                     const std::filesystem::path& json);

}  // namespace magvine::scene
