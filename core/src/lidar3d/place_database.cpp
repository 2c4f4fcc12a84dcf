#include "agv/lidar3d/place_database.hpp"

#include <array>
#include <cmath>

#include "agv/core/angle.hpp"

namespace agv {

namespace {
bool positiveFinite(float v) noexcept {
  return std::isfinite(v) && v > 0.0F;
}
}  // namespace

bool isValid(const PlaceParams& p) noexcept {
  return positiveFinite(p.keyThreshold) && positiveFinite(p.chiSquareThreshold) &&
         positiveFinite(p.sorensenThreshold) && p.minYawOverlap >= 1 && p.minYawOverlap <= kOrientationBins &&
         std::isfinite(p.maxOrientationCost) && p.maxOrientationCost >= 0.0F && std::isfinite(p.maxLoopTranslation) &&
         p.maxLoopTranslation >= 0.0F && p.minAlignedFraction >= 0.0F && p.minAlignedFraction <= 1.0F &&
         isValid(p.align);
}

Status PlaceDatabaseBase::setParams(const PlaceParams& params) noexcept {
  if (!isValid(params)) {
    return Status::InvalidArgument;
  }
  params_ = params;
  return Status::Ok;
}

Status PlaceDatabaseBase::add(const NormalSignature& normal, const OrientationSignature& orientation,
                              std::uint32_t scan, PlaceUpdate& out) noexcept {
  out = PlaceUpdate{};
  if (normal.empty()) {
    ++refusedEmpty_;
    return Status::EmptyInput;
  }
  // 1. Loop query over the keys older than the newest m: the candidates passing both thresholds,
  // the kPlaceVerifyCandidates nearest by chi-square kept sorted.
  struct Candidate {
    std::uint32_t key;
    float chi2;
    float sor;
  };
  std::array<Candidate, kPlaceVerifyCandidates> best{};
  std::size_t kept = 0;
  const std::size_t searchable = size_ > params_.skipRecentKeys ? size_ - params_.skipRecentKeys : 0;
  for (std::size_t i = 0; i < searchable; ++i) {
    const float chi2 = chiSquareDistance(keys_[i].normal, normal);
    if (!(chi2 < params_.chiSquareThreshold)) {
      continue;
    }
    const float sor = sorensenDistance(keys_[i].normal, normal);
    if (!(sor < params_.sorensenThreshold)) {
      continue;
    }
    ++out.candidates;
    if (kept == kPlaceVerifyCandidates && !(chi2 < best[kept - 1].chi2)) {
      continue;
    }
    std::size_t at = kept < kPlaceVerifyCandidates ? kept++ : kept - 1;
    while (at > 0 && chi2 < best[at - 1].chi2) {  // insertion, nearest first
      best[at] = best[at - 1];
      --at;
    }
    best[at] = Candidate{static_cast<std::uint32_t>(i), chi2, sor};
  }
  const bool check = params_.maxOrientationCost > 0.0F;
  const bool verify = params_.maxLoopTranslation > 0.0F;
  for (std::size_t c = 0; c < kept; ++c) {
    const Result<YawEstimate> yaw = relativeYaw(keys_[best[c].key].orientation, orientation, params_.minYawOverlap);
    if (check && (!yaw.ok() || yaw.value().relativeCost() > params_.maxOrientationCost)) {
      ++out.rejectedByOrientation;
      continue;
    }
    if (verify) {
      // Two starts: the signature's yaw and the opposite heading (a road or an aisle looks much the
      // same both ways); the alignment pairing more of the query's bins is kept.
      Result<ProfileAlignment> al(Status::NotEnoughData);
      Result<ProfileAlignment> other(Status::NotEnoughData);
      for (int start = 0; start < 2 && yaw.ok(); ++start) {
        const float y0 = yaw.value().yaw + (start == 0 ? 0.0F : kPi<float>);
        const Result<ProfileAlignment> a =
            alignProfiles(keys_[best[c].key].orientation, orientation, y0, params_.align);
        if (a.ok() && (!al.ok() || a.value().matched > al.value().matched)) {
          other = al;
          al = a;
        } else {
          other = a;
        }
      }
      float alternative = 0.0F;
      if (al.ok() && other.ok() && std::fabs(angleDiff(other.value().yaw, al.value().yaw)) > 0.5F * kPi<float>) {
        alternative = other.value().inlierFraction();
      }
      if (!al.ok() || al.value().inlierFraction() < params_.minAlignedFraction ||
          !(al.value().translation() <= params_.maxLoopTranslation)) {
        ++out.rejectedByAlignment;
        continue;
      }
      if (out.loop && !(al.value().translation() < out.alignment.translation())) {
        continue;  // an earlier candidate is nearer
      }
      out.hasAlignment = true;
      out.alignment = al.value();
      out.alternativeInlierFraction = alternative;
    }
    out.loop = true;
    out.loopKey = best[c].key;
    out.loopScan = keys_[best[c].key].scan;
    out.chiSquare = best[c].chi2;
    out.sorensen = best[c].sor;
    out.hasYaw = yaw.ok();
    out.yaw = yaw.valueOr(YawEstimate{});
    if (!verify) {
      break;
    }
  }
  // 2. Key decision.
  if (size_ == 0) {
    out.isKey = true;
  } else {
    out.chiSquareToLastKey = chiSquareDistance(keys_[size_ - 1].normal, normal);
    out.isKey = out.chiSquareToLastKey > params_.keyThreshold;
  }
  if (!out.isKey) {
    return Status::Ok;
  }
  if (size_ >= capacity_) {
    ++refusedFull_;
    return Status::CapacityExceeded;
  }
  keys_[size_].normal = normal;
  keys_[size_].orientation = orientation;
  keys_[size_].scan = scan;
  out.keyIndex = static_cast<std::uint32_t>(size_);
  ++size_;
  return Status::Ok;
}

}  // namespace agv
