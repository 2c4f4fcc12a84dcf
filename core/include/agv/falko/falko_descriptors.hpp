#pragma once
/// @file falko_descriptors.hpp
/// BSC (Binary Shape Context) and CGH (Cumulative Gaussian Histogram) descriptors of FALKO
/// keypoints, aligned to the keypoint orientation so that they do not change when the sensor turns.

#include <array>
#include <cstddef>
#include <cstdint>

#include "agv/core/capacities.hpp"
#include "agv/core/fixed_vector.hpp"
#include "agv/core/status.hpp"
#include "agv/falko/falko_keypoint.hpp"
#include "agv/falko/falko_params.hpp"
#include "agv/falko/scan_points.hpp"

namespace agv {

inline constexpr std::size_t kBscRings = 8;     ///< BSC radial rings (thesis: 8)
inline constexpr std::size_t kBscSectors = 16;  ///< BSC angular sectors (thesis: 16)
inline constexpr std::size_t kCghBins = 16;     ///< CGH angular bins (thesis: 16)

/// Binary shape context: cell (ring, sector) of the disc of radius R around the keypoint is set
/// when at least one scan point falls in it. Sector 0 is centred on orientation - pi, sectors
/// counter-clockwise; ring r covers distances [r, r + 1) * R / 8.
struct BscDescriptor {
  std::array<std::uint16_t, kBscRings> rings{};  ///< bit s of rings[r] = cell (r, s)
  /// True when cell (ring, sector) is occupied.
  bool occupied(std::size_t ring, std::size_t sector) const noexcept {
    return ((static_cast<unsigned>(rings[ring]) >> sector) & 1U) != 0U;
  }
};

/// Circular Gaussian histogram: the bearings (relative to the keypoint orientation) of the scan
/// points within R, each spread over neighbouring bins by a Gaussian of sigma `cghSigmaBins`;
/// normalised to sum 1 (all zero when no point lies within R).
struct CghDescriptor {
  std::array<float, kCghBins> bins{};
};

/// Hamming-like distance: number of cells occupied in exactly one of the two descriptors (0..128).
std::uint32_t bscDistance(const BscDescriptor& a, const BscDescriptor& b) noexcept;

/// Symmetric chi-square distance 0.5 * sum (a_i - b_i)^2 / (a_i + b_i), bins empty in both
/// skipped; 0 for identical histograms, 1 for disjoint normalised ones.
float cghDistance(const CghDescriptor& a, const CghDescriptor& b) noexcept;

using BscDescriptors = FixedVector<BscDescriptor, kMaxKeypoints>;
using CghDescriptors = FixedVector<CghDescriptor, kMaxKeypoints>;

/// Computes both descriptors for keypoints of one scan (one neighbourhood search per keypoint).
class FalkoDescriber {
 public:
  /// Precomputes the CGH kernel. Bad parameters make `describe` return `InvalidArgument`.
  explicit FalkoDescriber(const FalkoDescriptorParams& params = FalkoDescriptorParams{}) noexcept;

  const FalkoDescriptorParams& params() const noexcept { return params_; }

  /// Clears `bsc` and `cgh` and appends one descriptor of each kind per keypoint, in order.
  /// `points` must be the scan the keypoints were detected in. `CapacityExceeded` when an output
  /// is too small (the rest counted as refused); `OutOfRange` when a keypoint's beam index lies
  /// outside the scan (that keypoint gets empty descriptors).
  Status describe(const ScanPoints& points, const IVector<FalkoKeypoint>& keypoints, IVector<BscDescriptor>& bsc,
                  IVector<CghDescriptor>& cgh) const noexcept;

  /// Both descriptors of one keypoint.
  Status describe(const ScanPoints& points, const FalkoKeypoint& keypoint, BscDescriptor& bsc,
                  CghDescriptor& cgh) const noexcept;

 private:
  static constexpr std::size_t kKernelHalfWidth = 3;
  FalkoDescriptorParams params_;
  std::array<float, 2 * kKernelHalfWidth + 1> kernel_{};
  std::array<float, kBscRings - 1> ringBound2_{};  ///< squared outer radius of BSC rings 0..kBscRings-2
  bool valid_ = false;
};

}  // namespace agv
