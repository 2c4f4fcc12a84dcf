#pragma once
/// @file surface_map.hpp
/// The surfaces the vehicle has seen so far, kept as a likelihood field built online from its own
/// scans: the map-less counterpart of a mapping run's field (docs/localization.md, "Surface map").
/// Without a surveyed map the localizer has nothing absolute to hold on to, but what it saw a
/// moment ago is still there: each scan matched against the walls of the scans before it keeps
/// the heading and position to what the laser resolves instead of what the wheels say, and the
/// first scans anchor the map, so the vehicle drifts only where it sees nothing it saw before.
///
/// Model: the valid beams of an inserted scan (up to `maxRange`) are world points; two
/// neighbouring beams within `normalSpan` lie on one surface, and the straight *piece* between
/// them is added to the field (`LikelihoodFieldBase::addSegment`), its normal across it on the
/// sensor's side; a beam with no such neighbour is a point facing back along the beam. Pieces,
/// because distances to the beam points alone would be up to half their spacing (10 cm at 12 m)
/// too large on the wall itself. A piece is *new* when the field has no surface within
/// `newSurfaceDistance` of its ends and middle; new pieces are added to the field and kept in a
/// ring of `MaxPieces`, so the map grows with the area seen, not with time spent in it. The field
/// covers a square of `side` around the sensor; when the sensor comes within `recentreMargin` of
/// its edge, the field is rebuilt around the sensor from the pieces kept, or, with
/// `recentreByShift`, moved by whole cells (only the uncovered strips filled again). When the
/// ring is full the oldest piece is dropped (it leaves the field at the next recentre, which then
/// rebuilds the whole field).
///
/// What it cannot do: a surface inserted at a wrong pose stays wrong (the caller inserts only
/// scans whose pose it trusts), a wall is kept as first seen (later views do not refine it), and a
/// place left and re-entered after the ring has dropped it is mapped again from the current
/// estimate (no loop closure).
///
/// Heap-free: the field, the ring and a scan's worth of points (16 KB, for `LaserScan` input) live
/// inside `SurfaceMap<FieldCells, MaxPieces>`. Work per insert: the scan's beams x three field
/// samples, plus the cells within maxDistance of each new piece's bounding box; a recentre
/// re-adds at most `MaxPieces` pieces (with `recentreByShift`: moves the cells and re-adds the
/// pieces only to the uncovered strips, unless a piece was dropped).

#include <cstddef>
#include <cstdint>

#include "agv/core/pose2.hpp"
#include "agv/core/status.hpp"
#include "agv/localization/likelihood_field.hpp"
#include "agv/localization/localizer.hpp"
#include "agv/localization/scan_matcher.hpp"
#include "agv/scan/laser_scan.hpp"

namespace agv {

/// Parameters of a surface map.
struct SurfaceMapParams {
  /// Cell size and saturation of the field (the scan matcher's inlier band must fit inside).
  LikelihoodFieldParams field{};
  /// [m] side of the square the field covers around the sensor. 40 m at 5 cm is 640 000 cells.
  double side = 40.0;
  /// [m] the field is rebuilt around the sensor when it comes this close to an edge (a laser
  /// that reaches `maxRange` then still has the surfaces it sees inside the field).
  double recentreMargin = 12.0;
  /// [m] a piece whose ends or middle lie farther than this from every stored surface is new. A
  /// tenth of the field's 0.5 m saturation: a wall seen again from nearby adds nothing.
  double newSurfaceDistance = 0.05;
  /// [m] beams beyond this are not inserted. Far walls hold the heading over a path (HIL: median
  /// final error 3.1 mm with 20 m, 6.9 mm with 12 m), but a far point carries the heading error
  /// times its range across the beam (20 m x 0.1 deg = 3.5 cm). Beyond `recentreMargin` a piece
  /// may fall outside the field near its edge and is then not kept; docs/localization.md,
  /// "Surface map", has the range and gate variants measured.
  double maxRange = 20.0;
  /// [m] two neighbouring beams closer than this lie on one surface (a piece between them, the
  /// normal the field signs its distances with across it); a beam with no neighbour that near is
  /// a point whose normal is the beam's direction back to the sensor.
  double normalSpan = 0.3;
  /// How a recentre moves the field. false (the default): the field is rebuilt from every kept
  /// piece, centred on the sensor exactly, a piece with an end outside the new area left out whole.
  /// true: the field moves by whole cells of the grid fixed at the first insert, keeps the cells
  /// both areas share and fills only the uncovered strips, a piece that crosses the edge kept up
  /// to it; the same field as its own full rebuild (`rebuild`; a cell on a rounding boundary of the
  /// quantum may differ by one) for a fraction of the work (intel: 0.42 s instead of 1.21 s for the
  /// map-less replay). Not the default yet: the static-map replay's laser odometry runs on a
  /// surface map, and its figures move with where the grid falls (docs/localization.md,
  /// "Recentring by shift").
  bool recentreByShift = false;
  /// [m] where the grid falls: the field's grid is moved by this (its origin by this up to whole
  /// cells) from centring on the sensor (at every recentre, or with `recentreByShift` at the first
  /// insert). 0 for a vehicle; a sub-cell offset draws another of the equally valid grids, which
  /// is how a result's dependence on the grid is measured (docs/localization.md, "Laser
  /// odometry: the wider retry").
  double gridOffsetX = 0.0;
  double gridOffsetY = 0.0;
  /// `Ok`, `NonFiniteInput`, or `InvalidArgument` (invalid field, a non-positive side, distance
  /// or range, a margin of half the side or more).
  Status validate() const noexcept;
};

/// A kept piece of surface (world frame): the straight stretch between two neighbouring beams
/// (a and b), or one beam's point (a = b), and its normal on the side it was seen from (not
/// normalised).
struct SurfacePiece {
  float ax = 0.0F;
  float ay = 0.0F;
  float bx = 0.0F;
  float by = 0.0F;
  float nx = 0.0F;
  float ny = 0.0F;
};

/// What one insert did.
struct SurfaceInsert {
  Status status = Status::Ok;
  std::uint16_t beams = 0;  ///< valid beams within maxRange
  std::uint16_t added = 0;  ///< new surface pieces
  bool recentred = false;   ///< the field was rebuilt around the sensor first
};

/// The map over caller-provided storage (see `SurfaceMap` for the owning type).
class SurfaceMapBase {
 public:
  SurfaceMapBase(const SurfaceMapBase&) = delete;
  SurfaceMapBase& operator=(const SurfaceMapBase&) = delete;

  /// Adds the new surface pieces of `scan` seen by the laser at world pose `sensor`.
  /// `InvalidArgument` (invalid parameters), `NonFiniteInput` (sensor pose), `CapacityExceeded`
  /// (the field storage is smaller than `side` needs); nothing is changed then.
  SurfaceInsert insert(const LaserScan& scan, const Pose2d& sensor) noexcept;
  /// The same with the scan's points in the laser frame (e.g. de-skewed; non-finite ones skipped).
  SurfaceInsert insert(const MatchPoints& points, const Pose2d& sensor) noexcept;

  /// The beams of `scan` this map takes (valid, within `maxRange`) as points in the laser frame,
  /// in scan order, into `out` (cleared first): what a scan is matched against it with.
  void takenBeams(const LaserScan& scan, MatchPoints& out) const noexcept;

  /// Forgets every surface (the field is unconfigured until the next insert).
  void clear() noexcept;

  /// Rebuilds the field where it stands from every piece kept (what a recentre does after a piece
  /// was dropped). With `recentreByShift`, a recentre's moved field equals this (to one quantum in
  /// a rare cell whose distance falls on a rounding boundary).
  /// `NotInitialized` before the first insert.
  Status rebuild() noexcept;

  /// The field to match against (not `built()` before the first insert with a surface).
  const LikelihoodFieldBase& field() const noexcept { return field_; }
  /// Surface pieces kept, and the capacity.
  std::size_t size() const noexcept { return size_; }
  std::size_t capacity() const noexcept { return capacity_; }
  /// Pieces added since construction or `clear`, dropped from a full ring, and recentres.
  std::size_t added() const noexcept { return added_; }
  std::size_t dropped() const noexcept { return dropped_; }
  std::size_t recentres() const noexcept { return recentres_; }
  const SurfaceMapParams& params() const noexcept { return params_; }

 protected:
  SurfaceMapBase(LikelihoodFieldBase& field, SurfacePiece* pieces, std::size_t capacity,
                 const SurfaceMapParams& params) noexcept
      : field_(field), pieces_(pieces), capacity_(capacity), params_(params), valid_(params.validate()) {}
  ~SurfaceMapBase() = default;

 private:
  /// Recentres when needed; false with `out.status` set when the field cannot cover the sensor.
  bool prepare(const Pose2d& sensor, SurfaceInsert& out) noexcept;
  /// Centres the field on (x, y) and fills it from the pieces kept; with `recentreByShift`, moves
  /// it to the grid's nearest whole cell, keeping the cells it shares with the old area and
  /// filling the others (the whole field at the first insert, after a drop or when nothing is
  /// shared).
  Status recentre(double x, double y) noexcept;
  /// Adds every kept piece to the cells of `cells`.
  void fill(const CellRange& cells) noexcept;
  /// Offers a piece of surface from `a` to `b` with normal `n` (world frame); true when it was
  /// added (not added: the field already has a surface within newSurfaceDistance of its ends and
  /// middle, or an end lies outside the field).
  bool offer(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& n) noexcept;
  /// Builds the field once it holds a surface.
  void finish() noexcept;

  LikelihoodFieldBase& field_;
  SurfacePiece* pieces_;
  std::size_t capacity_;
  SurfaceMapParams params_;
  Status valid_;
  MatchPoints scratch_;   // a `LaserScan` as points
  std::size_t head_ = 0;  // index of the oldest piece
  std::size_t size_ = 0;
  std::size_t added_ = 0;
  std::size_t dropped_ = 0;
  std::size_t recentres_ = 0;
  std::size_t droppedAtRebuild_ = 0;  // dropped_ when the whole field was last filled
  bool anchored_ = false;             // the grid is fixed (at the first insert)
  double anchorX_ = 0.0;              // [m] origin of the grid's cell (0, 0)
  double anchorY_ = 0.0;
  double cellX_ = 0.0;  // the field's origin in whole cells from the anchor (integral values)
  double cellY_ = 0.0;
};

/// Whether the cycle `health` reports may write its scan into a surface map at
/// `health.scanPose`: a cycle the localizer did not refuse and is not lost in, whose scan match
/// (if any) was fused or found too little of the map to judge (the scan sees new ground, which
/// is how the map grows). A match refused for disagreeing with the prior (gate, fit, range,
/// convergence) keeps its scan out: the prior or the map is wrong, and writing would make it
/// worse.
bool mayExtendSurfaceMap(const LocalizerHealth& health) noexcept;

/// The same for a surface map kept as the fallback of a mapping run's field (`Localizer::correct`
/// with a fallback): a cycle not refused and not lost whose field match was fused (the scan placed
/// by the map), or whose fallback match was fused or saw too little of the surface map to judge
/// (new ground off the map), or, with no fallback match (the surface map still empty), whose field
/// match found too little of the map to judge. A match refused (gate, fit, convergence) keeps it
/// out.
bool mayExtendFallbackMap(const LocalizerHealth& health) noexcept;

/// The localizer's scan-matching settings for matching against a surface map: `base` with the
/// re-synchronisation and the widened recovery search off (`resyncAfter`, `widenAfter` = 0). Both
/// let a match overrule the filter's prior, which is right against a surveyed map when the
/// odometry slipped; a surface map was placed by that same filter and has no authority over it,
/// and a match that disagrees with the prior there is an ambiguity of the map (a lane lined with
/// identical pallet blocks), not a slip: it is refused, never forced.
ScanMatchParams surfaceMapMatching(const ScanMatchParams& base) noexcept;

/// A surface map with a field of `FieldCells` cells and a ring of `MaxPieces` pieces inside the
/// object (`FieldCells` bytes + 24 `MaxPieces` bytes + 16 KB): give it static storage or allocate
/// it once.
template <std::size_t FieldCells, std::size_t MaxPieces>
class SurfaceMap : public SurfaceMapBase {
  static_assert(MaxPieces >= 1, "a surface map keeps at least one piece");

 public:
  explicit SurfaceMap(const SurfaceMapParams& params = SurfaceMapParams{}) noexcept
      : SurfaceMapBase(field_, pieces_, MaxPieces, params) {}

 private:
  LikelihoodField<FieldCells> field_;
  SurfacePiece pieces_[MaxPieces] = {};
};

/// The size the programs use: the default 40 m square at 5 cm (640 000 of 1 M cells) and 65 536
/// pieces (about 2.6 MB in all).
using HallSurfaceMap = SurfaceMap<std::size_t{1} << 20U, std::size_t{1} << 16U>;

}  // namespace agv
