#pragma once
/// Physical constants and the unit conversions allowed at the I/O boundary.
/// Inside magvine everything is SI: m, kg, s, rad, N, Pa, T, A·m².

#include <numbers>
#include <optional>
#include <string_view>

namespace magvine {

inline constexpr double kPi = std::numbers::pi;
/// Vacuum permeability μ0 [H/m] (the pre-2019 exact value; the CODATA 2018 value differs by 5.5e-10 relative).
inline constexpr double kMu0 = 4.0e-7 * kPi;

inline constexpr double kMmToM = 1e-3;
inline constexpr double kCmToM = 1e-2;
inline constexpr double kKpaToPa = 1e3;
inline constexpr double kMtToT = 1e-3;
inline constexpr double kDegToRad = kPi / 180.0;

/// Length units accepted in files.
enum class LengthUnit { kMm, kCm, kM };

/// Metres per one file unit.
constexpr double metres_per(LengthUnit u) {
  switch (u) {
    case LengthUnit::kMm: return kMmToM;
    case LengthUnit::kCm: return kCmToM;
    case LengthUnit::kM: return 1.0;
  }
  return 1.0;
}

/// Parses "mm" | "cm" | "m"; nullopt for anything else.
constexpr std::optional<LengthUnit> parse_length_unit(std::string_view s) {
  if (s == "mm") return LengthUnit::kMm;
  if (s == "cm") return LengthUnit::kCm;
  if (s == "m") return LengthUnit::kM;
  return std::nullopt;
}

}  // namespace magvine
