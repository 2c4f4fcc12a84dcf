#pragma once
/// @file reloc_oracle.hpp
/// Truth-based uniqueness oracle of the HIL's relocalization stage: is the vehicle's pose the only
/// one on the map that explains what it can see? Independent of the localizer's own decision
/// (`GlobalLocalizer`): it takes the noise-free set of reflectors visible from the true pose and
/// searches the map exhaustively for another pose that places every one of them on a landmark.

#include <cstddef>
#include <vector>

#include "agv/core/pose2.hpp"
#include "agv/sim/ray_caster.hpp"
#include "agv/sim/sim_laser.hpp"

namespace agv::hil {

/// A point [m] (map frame for landmarks, vehicle frame for observations).
struct OraclePoint {
  double x = 0.0;
  double y = 0.0;
};

struct UniquenessParams {
  /// [m] an observation placed within this of a landmark is explained by it: the localizer's
  /// association gate (`GlobalLocalizerParams::inlierGate`).
  double tolerance = 0.15;
  /// Poses farther apart than either bound are distinct (the 0.5 m / 10 deg).
  double distinctDistance = 0.5;     ///< [m]
  double distinctAngle = 0.1745329;  ///< [rad] 10 deg
};

/// The oracle's verdict for one pose.
struct Uniqueness {
  bool unique = false;           ///< no distinct pose explains as many observations as the truth
  std::size_t visible = 0;       ///< observations (reflectors visible from the true pose)
  std::size_t truthSupport = 0;  ///< observations the true pose places on a landmark
  std::size_t otherSupport = 0;  ///< the most any distinct pose places on a landmark
  Pose2d other{};                ///< that pose (meaningful when otherSupport > 0)
  std::size_t hypotheses = 0;    ///< poses tried
};

/// Judges `truth` (vehicle pose, map frame) given `observations` (the noise-free visible
/// landmarks in the vehicle frame) and the map's landmark positions `map`. Every pose that
/// explains all observations maps the two farthest-apart observations onto two landmarks whose
/// distance matches theirs within 2 x tolerance, so trying every such ordered landmark pair (with
/// one least-squares refit on the associations) is exhaustive. Fewer than 2 observations never
/// fix a pose: not unique. O(M^2 n M) for M landmarks and n observations (HIL only).
Uniqueness judgeUniqueness(const std::vector<OraclePoint>& map, const std::vector<OraclePoint>& observations,
                           const Pose2d& truth, const UniquenessParams& params = UniquenessParams{});

/// The reflector centres (map frame, noise-free) the simulated laser detects from `laserPose`
/// when standing still: the same field-of-view, range and line-of-sight rules as `SimLaser`.
std::vector<OraclePoint> visibleReflectors(const sim::RayCaster& caster, const sim::SimLaserParams& laser,
                                           const Pose2d& laserPose);
/// The map points (map frame, e.g. frozen FALKO corners) in clear view of the laser at `laserPose`:
/// within its field of view, `maxRange` and range limits, and no surface on the beam towards it
/// short of 0.10 m before it (a corner lies on the surfaces that form it).
std::vector<OraclePoint> visibleMapPoints(const sim::RayCaster& caster, const sim::SimLaserParams& laser,
                                          const Pose2d& laserPose, const std::vector<OraclePoint>& points,
                                          double maxRange);

}  // namespace agv::hil
