#pragma once
/// Counts of the costly components a run builds, so tests can show that a scene builds only what it uses (DESIGN.md:
/// no collision world without anatomy, no field gradients for uniform fields, no renderer without a camera output).
/// Incremented where each component is constructed, never in a solver's inner loop; relaxed atomics, so counts from
/// parallel trials add up.

#include <cstdint>

namespace magvine::usage {

enum class Component {
  kCollisionWorld,  ///< anatomy::CollisionWorld (contact BVH, edge tables)
  kGradientField,   ///< a robot field function that evaluates ∇B (magnets with gradients)
  kRenderer,        ///< render::AirwayRenderer (Embree scene of the anatomy for a camera)
  kCount
};

/// One more `c` built.
void note(Component c);
/// How many `c` were built since the program started (or the last reset).
std::uint64_t count(Component c);
/// Sets every count to 0 (tests).
void reset();

}  // namespace magvine::usage
