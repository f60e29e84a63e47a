#pragma once
/// Wall-clock timing for runtimes reported in outputs and studies (never asserted in tests).

#include <chrono>

namespace magvine {

/// Seconds since construction (steady clock).
class Stopwatch {
 public:
  Stopwatch() : m_start(std::chrono::steady_clock::now()) {}
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - m_start).count();
  }

 private:
  std::chrono::steady_clock::time_point m_start;
};

}  // namespace magvine
