// Internals shared by the simulator's translation units (not installed).
#pragma once

#include <cstdint>
#include <vector>

#include "ptda/sim/simulator.hpp"

namespace ptda::sim {

/// One job cycle's motion in cycle-local time (t = 0 at the first via point), starting at rest.
struct CyclePlan {
  std::vector<MotionPiece> pieces;  ///< angle0_rad relative to via point 0; cycle field unused
  std::vector<Plateau> plateaus;    ///< linear (constant-speed) parts, cycle-local times
  double duration_s = 0.0;          ///< first to last via point
};

/// Plans one cycle with Craig's LSPB through the via points. Throws ptda::Error (plain message, no
/// location) when a segment is too short for the acceleration limit.
[[nodiscard]] CyclePlan plan_cycle(const MotionSpec& m);

/// PRNG stream ids (one per independent kind of draw).
inline constexpr std::uint64_t kStreamJitter = 1;
inline constexpr std::uint64_t kStreamNoise = 2;
inline constexpr std::uint64_t kStreamCan = 3;
inline constexpr std::uint64_t kStreamOtherFrames = 4;

}  // namespace ptda::sim
