// Validation of the localizer's parameters (localizer.hpp) and of the pose filter's (pose_ekf.hpp).
#include <cmath>
#include <initializer_list>

#include "agv/localization/localizer.hpp"
#include "agv/localization/pose_ekf.hpp"

namespace agv {
namespace {

bool allFinite(std::initializer_list<double> values) noexcept {
  for (const double v : values) {
    if (!std::isfinite(v)) {
      return false;
    }
  }
  return true;
}

bool allFinite(const double (&values)[kLandmarkKindCount]) noexcept {
  for (const double v : values) {
    if (!std::isfinite(v)) {
      return false;
    }
  }
  return true;
}

bool allNonNegative(const double (&values)[kLandmarkKindCount]) noexcept {
  for (const double v : values) {
    if (v < 0.0) {
      return false;
    }
  }
  return true;
}

/// `NonFiniteInput` before `InvalidArgument`, as every `validate()` of the library orders them.
Status verdict(bool finite, bool valid) noexcept {
  if (!finite) {
    return Status::NonFiniteInput;
  }
  return valid ? Status::Ok : Status::InvalidArgument;
}

}  // namespace

Status PoseEkfParams::validate() const noexcept {
  return verdict(allFinite({varianceFloorXY, varianceFloorTheta}), varianceFloorXY > 0.0 && varianceFloorTheta > 0.0);
}

Status LaserModel::validate() const noexcept {
  const bool finite = mounting.isFinite() &&
                      allFinite({rangeMin, rangeMax, angleMin, angleMax, rangeSigma, bearingSigma}) &&
                      allFinite(kindSigma);
  const bool valid = rangeMin >= 0.0 && rangeMin < rangeMax && angleMin < angleMax && rangeSigma >= 0.0 &&
                     bearingSigma >= 0.0 && allNonNegative(kindSigma);
  return verdict(finite, valid);
}

Status AssociationParams::validate() const noexcept {
  return verdict(
      allFinite({gate, maxSearchRadius, searchLandmarkVariance, ambiguityMargin, supportSigma, fieldCheckGate}),
      gate > 0.0 && maxSearchRadius > 0.0 && searchLandmarkVariance >= 0.0 && ambiguityMargin >= 0.0 &&
          supportSigma >= 0.0 && minSupport > 0U && fieldCheckGate >= 0.0);
}

Status OcclusionParams::validate() const noexcept {
  const bool finite =
      allFinite({viewRangeMargin, viewAngleMargin, sigmas}) && allFinite(kindDepth) && allFinite(supportRadius);
  const bool valid = viewRangeMargin >= 0.0 && viewAngleMargin >= 0.0 && sigmas > 0.0 && allNonNegative(kindDepth) &&
                     allNonNegative(supportRadius);
  return verdict(finite, valid);
}

Status MapLifecycleParams::validate() const noexcept {
  return verdict(allFinite({insertSeparation}),
                 insertSeparation >= 0.0 && minHitsConfirmed >= 0 && minHitsToCorrect >= 0);
}

Status LocalizerHealthParams::validate() const noexcept {
  bool ratesOk = true;
  for (const double r : detectionRate) {
    ratesOk = ratesOk && r >= 0.0 && r <= 1.0;
  }
  for (const double r : minObservedMatchedFraction) {
    ratesOk = ratesOk && r >= 0.0 && r <= 1.0;
  }
  const bool finite = allFinite(detectionRate) && allFinite(minObservedMatchedFraction) &&
                      allFinite({minMatchedFraction, minFieldInlierFraction, maxPositionSigma, maxHeadingSigma});
  const bool valid = ratesOk && minMatchedFraction >= 0.0 && minMatchedFraction <= 1.0 &&
                     minFieldInlierFraction >= 0.0 && minFieldInlierFraction <= 1.0 && maxPositionSigma > 0.0 &&
                     maxHeadingSigma > 0.0 && lostAfterBadCycles > 0U && minMatchesForFix > 0U;
  return verdict(finite, valid);
}

Status LocalizerParams::validate() const noexcept {
  for (const Status s : {ekf.validate(), laser.validate(), association.validate(), occlusion.validate(), map.validate(),
                         health.validate(), scanMatch.validate()}) {
    if (s != Status::Ok) {
      return s;
    }
  }
  if (!std::isfinite(scanMatchGate)) {
    return Status::NonFiniteInput;
  }
  if (!(scanMatchGate > 0.0)) {
    return Status::InvalidArgument;
  }
  return maxScanLead.ns >= 0 ? Status::Ok : Status::InvalidArgument;
}

}  // namespace agv
