#pragma once
/// CSV input and output of the `magvine field` contract.
///
/// Input: a header naming the columns x,y,z (metres), then one point per line. Blank lines and lines starting
/// with '#' are skipped. Output columns: x,y,z,Bx,By,Bz,G11,G12,G13,G21,G22,G23,G31,G32,G33 (SI, Gij = ∂Bi/∂xj),
/// numbers printed in their shortest exact (round-trip) form.

#include <filesystem>
#include <ostream>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "magvine/core/eigen_types.hpp"
#include "magvine/magnetics/field_sample.hpp"

namespace magvine::scene {

/// Reads points; InputError naming file and line for a missing header, a wrong column count, a non-number,
/// NaN/inf, or a file without points.
std::vector<Vec3> read_points_csv(const std::filesystem::path& file);
std::vector<Vec3> parse_points_csv(std::string_view text, const std::string& file_label);

/// The header line of the output (no newline).
std::string field_csv_header();
/// Writes the header and one row per point.
void write_field_csv(std::ostream& out, std::span<const Vec3> points, std::span<const magnetics::FieldSample> samples);

}  // namespace magvine::scene
