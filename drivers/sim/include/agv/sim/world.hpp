#pragma once
/// @file world.hpp
/// The simulated warehouse: 2D obstacle geometry (walls, pallet blocks, racks, pillars,
/// reflector poles) and the paths vehicles drive, loaded from the text format of
/// docs/world-format.md.
///
/// Simulation code (host only): it uses the standard containers freely.

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "agv/core/pose2.hpp"
#include "agv/core/status.hpp"

namespace agv::sim {

/// A point of the world plane [m].
struct Point2 {
  double x = 0.0;
  double y = 0.0;
};

/// What an obstacle primitive belongs to (for plots and statistics; the laser treats all alike,
/// except that only `Reflector` circles are reported as reflectors).
enum class ObstacleKind : unsigned char { Wall, Pallet, Rack, Pillar, Reflector };

/// A straight obstacle edge from `a` to `b` (non-degenerate).
struct Segment {
  Point2 a;
  Point2 b;
  ObstacleKind kind = ObstacleKind::Wall;
};

/// A cylindrical obstacle: building pillar or reflector pole.
struct Circle {
  Point2 centre;
  double radius = 0.0;  ///< [m] > 0
  ObstacleKind kind = ObstacleKind::Pillar;
};

/// A path a vehicle drives forward, as the logical point's trajectory: a start pose and a
/// sequence of straight and circular pieces, sampled densely into `points` on load.
struct Path {
  std::string name;
  Pose2d start;                ///< start pose of the logical point (heading along the path)
  double length = 0.0;         ///< [m] exact length of the pieces
  std::vector<Pose2d> points;  ///< samples every <= `kPathSampleStep` m, first = start, last = end
};

/// Spacing of the path samples [m].
inline constexpr double kPathSampleStep = 0.02;

/// A mission: one drive from a start pose through several operation points (stops where the
/// vehicle stands for a pick or a drop and its pose error is measured), as consecutive legs. Leg
/// k ends at operation point k and starts where leg k-1 ended; the last leg ends at the last one.
struct Mission {
  std::string name;
  Pose2d start;            ///< start pose of the logical point
  double length = 0.0;     ///< [m] sum of the legs
  std::vector<Path> legs;  ///< one per operation point, named NAME/1, NAME/2, ...
};

/// A `pallet` box of the world file: a movable object (a pallet block, a staged pallet), the four
/// segments `firstSegment`..`firstSegment + 3` of `World::segments`.
struct PalletBox {
  double xmin = 0.0;
  double ymin = 0.0;
  double xmax = 0.0;
  double ymax = 0.0;
  std::size_t firstSegment = 0;
};

/// The whole warehouse.
struct World {
  std::vector<Segment> segments;
  std::vector<Circle> circles;
  std::vector<Path> paths;
  std::vector<Mission> missions;   ///< `mission` statements, in file order
  std::vector<PalletBox> pallets;  ///< the `pallet` boxes (movable objects), in file order

  /// The mission named `name`, or nullptr.
  const Mission* findMission(std::string_view name) const noexcept;
  /// The path named `name`, or nullptr.
  const Path* findPath(std::string_view name) const noexcept;
  /// Axis-aligned bounding box of every obstacle (min corner, max corner). Zero box when empty.
  void bounds(Point2* lo, Point2* hi) const noexcept;
  /// Number of reflector poles.
  std::size_t reflectorCount() const noexcept;
};

/// Where and why a world text failed to parse.
struct WorldParseError {
  int line = 0;         ///< 1-based line number (0 = not a line-specific problem)
  std::string message;  ///< what is wrong, naming the keyword or field
};

/// Parses the text format of docs/world-format.md into `out` (replacing its content).
/// Returns `Ok`, or `Malformed` (unknown keyword, wrong field count, not a number),
/// `NonFiniteInput`, `InvalidArgument` (non-positive radius, degenerate wall or box, duplicate
/// path name, bad path piece) or `EmptyInput` (no obstacle at all); `error` then names the line.
Status parseWorld(std::string_view text, World& out, WorldParseError& error);

/// Reads and parses a world file. `NotFound` (with error.line = 0) when it cannot be read.
Status loadWorldFile(const std::string& path, World& out, WorldParseError& error);

/// The built-in warehouse: a 40 m x 25 m hall with racks, pillars, a block storage of pallet
/// blocks with four lanes, 18 reflector poles, the four reference paths P1..P4 (three of 12 m,
/// one of 7 m) ending inside the block storage and three missions M1..M3 (60-94 m, 3-4 operation
/// points at lanes and rack faces). The main job's embedded default.
std::string_view defaultWorldText() noexcept;

}  // namespace agv::sim
