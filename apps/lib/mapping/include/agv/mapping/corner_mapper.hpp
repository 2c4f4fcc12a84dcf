#pragma once
/// @file corner_mapper.hpp
/// The FALKO corners of a mapping run, placed in the world at known poses, clustered by proximity
/// (a sighting joins the cluster whose mean is nearest, within the merge radius) and frozen into a
/// static corner map: a cluster becomes a surveyed corner when enough of its sightings agree on
/// one place. Host code (heap, offline or at start-up); `agvnav-hil` and `agvnav-replay` build their
/// static FALKO maps with it.

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <unordered_map>
#include <vector>

#include "agv/localization/landmark_map.hpp"

namespace agv::mapping {

/// Which clusters `CornerMapper::freeze` keeps, and the sigma it gives them. The defaults keep every
/// cluster of 5 sightings at the mean of all of them (no outlier rejection, no scatter test).
struct CornerFreezeParams {
  /// Sightings (inliers, when `inlierRadius` > 0) a cluster needs to be frozen.
  std::size_t minSightings = 5;
  /// [m] sightings farther than this from the cluster's median (per coordinate) are outliers: a
  /// keypoint of another object that fell into the cluster, a sighting from a bad pose. They are
  /// left out of the mean and the scatter. <= 0: every sighting is an inlier.
  double inlierRadius = 0.0;
  /// A cluster whose inliers are a smaller share of its sightings is refused: its "corner" moves
  /// with the viewpoint (the apex of a round pillar, a grazing edge), so there is no one place to
  /// freeze. 0.5 asks that most sightings agree.
  double minInlierFraction = 0.0;
  /// [m] largest scatter of the inliers (standard deviation per coordinate) a frozen cluster may
  /// have: a true corner's apex is seen at one place from everywhere.
  double maxScatter = std::numeric_limits<double>::infinity();
  /// [m] the frozen corner's sigma; <= 0: the scatter of its inliers (the precision of one
  /// sighting; the mapping poses' own error is common to all sightings and not in it).
  double sigma = 0.0;
};

/// What `CornerMapper::freeze` did with the clusters.
struct CornerFreezeStats {
  std::size_t clusters = 0;       ///< clusters in the mapper
  std::size_t frozen = 0;         ///< added to the map
  std::size_t tooFew = 0;         ///< fewer than `minSightings` (inlier) sightings
  std::size_t viewDependent = 0;  ///< inliers below `minInlierFraction` of the sightings
  std::size_t scattered = 0;      ///< inlier scatter above `maxScatter`
  std::size_t refusedByMap = 0;   ///< the map refused the landmark (full, out of range)
};

class CornerMapper {
 public:
  /// `mergeRadius` [m] (> 0): a sighting closer than this to a cluster's mean joins the nearest
  /// such cluster, else it starts a new one.
  explicit CornerMapper(double mergeRadius = 0.2);

  /// One sighting at `world` [m]. Non-finite sightings are skipped.
  void add(const Eigen::Vector2d& world);

  std::size_t clusters() const noexcept { return clusters_.size(); }
  std::size_t sightings() const noexcept { return sightings_; }

  /// Clears `frozen`, adds every cluster that passes `params` as a surveyed corner (ids 1, 2, ...,
  /// in the order the clusters were started) at the mean of its inliers, and sets it Static.
  CornerFreezeStats freeze(const CornerFreezeParams& params, LandmarkMap& frozen) const;

 private:
  struct Cluster {
    double sx = 0.0;
    double sy = 0.0;
    std::vector<Eigen::Vector2d> sightings;
  };
  std::int64_t cellOf(double v) const noexcept;  ///< grid cell index of a coordinate
  static std::uint64_t cellKey(std::int64_t cx, std::int64_t cy) noexcept;
  std::size_t nearest(const Eigen::Vector2d& w) const;

  double radius_;
  std::size_t sightings_ = 0;
  std::vector<Cluster> clusters_;
  /// Cells as wide as the merge radius -> the clusters started in them (indexed by their first sighting).
  std::unordered_map<std::uint64_t, std::vector<std::size_t>> grid_;
};

}  // namespace agv::mapping
