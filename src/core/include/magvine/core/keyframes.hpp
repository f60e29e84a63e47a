#pragma once
/// Piecewise-linear keyframes: where a time falls between increasing keyframe times, held beyond the first and the
/// last. The one home of keyframe interpolation; schedules (pressure, tether), magnet poses (magnetics) and applied
/// fields over time build on it.

#include <algorithm>
#include <cstddef>

namespace magvine {

/// Time t lies between keyframes `before` and `after` at fraction `u` ∈ [0, 1] (before == after, u = 0, outside the
/// keyframes' span: held at the nearer end).
struct KeyframeSpan {
  std::size_t before = 0;
  std::size_t after = 0;
  double u = 0.0;
};

/// `count` ≥ 1 keyframes whose times `time_of(k)` increase strictly.
template <class TimeOf>
KeyframeSpan keyframe_span(std::size_t count, double t, const TimeOf& time_of) {
  if (count == 0 || t <= time_of(0)) return {};
  if (t >= time_of(count - 1)) return {count - 1, count - 1, 0.0};
  std::size_t lo = 0;
  std::size_t hi = count - 1;
  while (hi - lo > 1) {  // time_of(lo) < t < time_of(hi)
    const std::size_t mid = lo + (hi - lo) / 2;
    (time_of(mid) < t ? lo : hi) = mid;
  }
  const double t0 = time_of(lo);
  const double t1 = time_of(hi);
  return {lo, hi, std::clamp((t - t0) / (t1 - t0), 0.0, 1.0)};
}

/// (1 − u)·a + u·b.
template <class T>
T lerp(const T& a, const T& b, double u) {
  return (1.0 - u) * a + u * b;
}

}  // namespace magvine
