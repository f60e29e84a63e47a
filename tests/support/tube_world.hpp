#pragma once
// A generated tube phantom with its collision world, for robot tests that grow a body in it.

#include "magvine/anatomy/collision_world.hpp"
#include "magvine/anatomy/phantom.hpp"

namespace magvine::test {

struct TubeWorld {
  anatomy::Phantom phantom;
  anatomy::CollisionWorld world;
  explicit TubeWorld(const anatomy::TubeParams& p) : phantom(anatomy::make_tube_phantom(p)), world(phantom.mesh) {}
};

}  // namespace magvine::test
