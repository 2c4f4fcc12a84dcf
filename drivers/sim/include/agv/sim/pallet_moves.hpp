#pragma once
/// @file pallet_moves.hpp
/// Pallets moved between runs: a seeded rearrangement of a world's movable objects (its `pallet`
/// boxes), so that maps built on the original layout become partly stale (docs/hil.md, "Missions").
///
/// Simulation code (host only): it uses the standard containers freely.

#include <cstdint>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/sim/world.hpp"

namespace agv::sim {

/// How the pallets of a world are rearranged for one run.
struct PalletMoveParams {
  double removeProbability = 0.1;     ///< each pallet box is taken away (a pick emptied the place)
  double moveProbability = 0.5;       ///< each remaining box is put back displaced
  double maxShift = 0.15;             ///< [m] displacement per axis, uniform in [-max, max]
  double maxRotation = deg2rad(3.0);  ///< [rad] rotation about the box centre, uniform
  int added = 3;                      ///< new pallets dropped in free space
  double addedLength = 1.2;           ///< [m] size of an added pallet (a loaded euro pallet)
  double addedWidth = 1.0;            ///< [m]
  double clearance = 1.0;             ///< [m] from every keep-clear point (the vehicle's route)
  double obstacleClearance = 0.3;     ///< [m] of an added pallet from every other obstacle
};

/// What one rearrangement did.
struct PalletChanges {
  int boxes = 0;    ///< pallet boxes of the original world
  int moved = 0;    ///< displaced and/or rotated
  int removed = 0;  ///< taken away
  int added = 0;    ///< new pallets placed
  /// Drawn to move but left in place: the moved box came too near the route.
  int keptForClearance = 0;
  double maxShift = 0.0;  ///< [m] largest displacement of a moved box's corner
};

/// A copy of `base` with its pallet boxes rearranged (seeded by `seed`, deterministic): removed,
/// displaced and rotated about their centres, and new ones added at free places. A moved box keeps
/// at least `params.clearance` from every point of `keepClear` (the route, where the vehicle and
/// its laser pass), or its original clearance when that was smaller (else it stays where it was);
/// an added one keeps `params.clearance` from the route and `params.obstacleClearance` from the
/// rest. Walls, racks, pillars, reflectors, paths and missions are unchanged. `out.pallets` holds
/// the new boxes (axis-aligned bounds of rotated ones).
void rearrangePallets(const World& base, const PalletMoveParams& params, std::uint64_t seed,
                      const std::vector<Point2>& keepClear, World& out, PalletChanges& changes);

/// A number that changes when any pallet segment moves (sum of the pallet segments' end
/// coordinates weighted by position): equal layouts give equal fingerprints.
double palletFingerprint(const World& world) noexcept;

/// Distance [m] from point `p` to segment `s` (0 on it).
double distanceToSegment(const Point2& p, const Segment& s) noexcept;

}  // namespace agv::sim
