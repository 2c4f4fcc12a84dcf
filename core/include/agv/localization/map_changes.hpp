#pragma once
/// @file map_changes.hpp
/// What changed since the mapping run. A likelihood field from a mapping run (natural navigation)
/// keeps every surface where that run saw it; in a warehouse the pallets do not stay there. A
/// pallet block shifted by 10 cm keeps its points inside the matcher's inlier band, where they
/// pull the pose towards the old block: in a lane lined with moved blocks that bias is most of
/// what the match sees (docs/localization.md, "Map changes").
///
/// The mechanism, the thesis' dynamic landmark map carried over to surfaces:
/// - *detect* (`MapChangeDetector::select`): at a pose the mapping run's field placed (a fused
///   match), the scan points that lie farther from every mapped surface than the field explains
///   the others are surfaces the mapping run did not see there. The threshold is the larger of
///   `MapChangeParams::distance` and `sigmas` robust standard deviations of this scan's own
///   residuals (1.4826 x their median over the points within the matcher's inlier band): a map
///   whose walls fit to 1 cm calls a 5 cm shift a change, a map that fits a real building to
///   6 cm (a SLAM map's own inconsistency) does not call its walls changes. The caller adds the
///   selected points to a map of changes of its own (a `SurfaceMap`), placed with that match's
///   pose, so the changes live in the field's frame and not in the filter's;
/// - *use* (`MapChangeDetector::keepUnchanged`): before the next match, the points that lie on a
///   known change (within `distance` of a change surface) and off the mapped surfaces (farther
///   than `distance` from them) are left out: they carry no information about the pose in the
///   mapping run's frame. A point that fits the mapped field is always kept, so a pallet put back
///   where it stood, or a change recorded next to an unchanged wall, takes nothing from the match.
///
/// Heap-free: the detector holds a scan's worth of residuals (4 bytes a beam). Work: two field
/// samples per point, and one selection (nth_element) over at most kMaxScanBeams residuals.

#include <cstddef>

#include "agv/core/capacities.hpp"
#include "agv/core/fixed_vector.hpp"
#include "agv/core/pose2.hpp"
#include "agv/core/status.hpp"
#include "agv/localization/likelihood_field.hpp"
#include "agv/localization/scan_matcher.hpp"
#include "agv/localization/surface_map.hpp"

namespace agv {

/// Parameters of the change detection.
struct MapChangeParams {
  /// [m] the smallest distance from the mapped surfaces that counts as a change, and the band
  /// around a change surface whose points are not matched. 4 cm: three standard deviations of a
  /// range noise of 1 cm plus the field's quantisation (5 cm cells, 1.4 cm), so that an unchanged
  /// wall is not taken for a change; a block moved by less is matched as it stands (its bias is
  /// smaller than that).
  double distance = 0.04;
  /// A point is a change only beyond this many robust standard deviations of its scan's
  /// residuals (see the file comment).
  double sigmas = 3.0;
  /// [m] residuals within this band are the ones the robust standard deviation is taken over
  /// (the scan matcher's inlier band, `ScanMatchParams::inlierDistance`).
  double inlierDistance = 0.30;
  /// `Ok`, `NonFiniteInput`, or `InvalidArgument` (a value not positive, or the inlier band not
  /// above `distance`).
  Status validate() const noexcept;
};

/// The parameters of a `SurfaceMap` that keeps the changes: `surface`'s, with the field's
/// saturation cut to three cells (at least `changes.distance` plus two cells). Only the band of
/// `changes.distance` around a change is ever asked for, and each new piece updates the cells within
/// the saturation distance of it: at the default 5 cm cells a tenth of the work of the 0.5 m field.
SurfaceMapParams changeMapParams(const SurfaceMapParams& surface, const MapChangeParams& changes) noexcept;

/// The change detection of one scan against a mapping run's field (see the file comment).
class MapChangeDetector {
 public:
  explicit MapChangeDetector(const MapChangeParams& params = MapChangeParams{}) noexcept : params_(params) {}
  MapChangeDetector(const MapChangeDetector&) = delete;
  MapChangeDetector& operator=(const MapChangeDetector&) = delete;

  /// Copies into `out` (cleared first) the points of `points` (laser frame) that, seen from the
  /// laser at world pose `sensor`, lie farther than the change threshold (`threshold()` after the
  /// call) from every surface of `field`, or outside it: the surfaces the mapping run did not see
  /// there. The order is kept (`SurfaceMapBase::insert` joins neighbouring points into pieces);
  /// non-finite points are skipped. `NonFiniteInput` (sensor pose), `NotInitialized` (field not
  /// built), `InvalidArgument` (params); `out` is empty then.
  Status select(const MatchPoints& points, const Pose2d& sensor, const LikelihoodFieldBase& field,
                MatchPoints& out) noexcept;

  /// Copies into `out` (cleared first) the points of `points` (laser frame) to match against
  /// `field`, seen from the laser at world pose `sensor`: all but those within `distance` of a
  /// surface of `changes` and farther than `distance` from every surface of `field`, which
  /// `dropped` counts. With `field` or `changes` not built every point is copied. The order is
  /// kept. `NonFiniteInput` (sensor pose), `InvalidArgument` (params): every point is copied then.
  Status keepUnchanged(const MatchPoints& points, const Pose2d& sensor, const LikelihoodFieldBase& field,
                       const LikelihoodFieldBase& changes, MatchPoints& out, std::size_t& dropped) const noexcept;

  /// [m] the change threshold of the last `select` (`distance` before any).
  double threshold() const noexcept { return threshold_; }
  const MapChangeParams& params() const noexcept { return params_; }

 private:
  MapChangeParams params_;
  double threshold_ = params_.distance;
  FixedVector<float, kMaxScanBeams> residuals_{};  // |residual| of one scan's points
};

}  // namespace agv
