#pragma once
/// The events of an experiment run: the growth's own (robot::GrowthEventKind: stall, resume, blocked, squeeze, burst,
/// retract, solver) and the navigator's (recover, workspace), as one enum; events.json and the run's figures name
/// them through event_name, the only place their text is made.

#include <string>
#include <string_view>

#include "magvine/robot/growth.hpp"

namespace magvine::scene {

enum class EventKind {
  kStall = static_cast<int>(robot::GrowthEventKind::kStall),
  kResume = static_cast<int>(robot::GrowthEventKind::kResume),
  kBlocked = static_cast<int>(robot::GrowthEventKind::kBlocked),
  kSqueeze = static_cast<int>(robot::GrowthEventKind::kSqueeze),
  kBurst = static_cast<int>(robot::GrowthEventKind::kBurst),
  kRetract = static_cast<int>(robot::GrowthEventKind::kRetract),
  kSolver = static_cast<int>(robot::GrowthEventKind::kSolver),
  kRecover,    ///< the navigator backs the vine out of a wrong turn or a hold, or gives the pressure back
  kWorkspace,  ///< a magnet's pose was replaced: it overlaps the anatomy even at the navigator's farthest
               ///< placement, or an arm cannot hold it there (out of reach, a collision, too near the skin)
  kTorque,     ///< an arm needs more than a joint's torque limit to hold its magnet
};

/// "stall", "resume", …, "recover", "workspace", "torque".
std::string_view event_name(EventKind kind);
/// The run's kind of a growth event.
EventKind event_kind(robot::GrowthEventKind kind);

/// Something that happened during a run.
struct RunEvent {
  double time = 0.0;    ///< [s]
  double length = 0.0;  ///< everted (or inserted) length then [m]
  EventKind kind = EventKind::kStall;
  std::string detail;  ///< human-readable cause with numbers (kPa, mm, N)
};

/// A growth event as a run event.
RunEvent run_event(const robot::GrowthEvent& e);

}  // namespace magvine::scene
