#include "agv/localization/landmark_map.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>

namespace agv {

LandmarkMap::LandmarkMap(const LandmarkMapParams& params) noexcept : params_(params) {
  const bool ok = params.cellSize >= 0.05 && params.cellSize <= 1000.0 && params.updateRate >= 0.0 &&
                  params.updateRate <= 1.0 && params.initialHits >= 1 && params.maxHits >= params.initialHits;
  if (!ok) {
    paramsValid_ = false;
    const MapMode mode = params.mode;
    params_ = LandmarkMapParams{};
    params_.mode = mode;
  }
  clear();
}

void LandmarkMap::clear() noexcept {
  for (std::size_t i = 0; i < kLandmarkGridBuckets; ++i) {
    buckets_[i] = kNoLandmark;
  }
  for (std::size_t i = 0; i < kMaxLandmarks; ++i) {
    nodes_[i] = Node{};
    slots_[i] = Landmark{};
    // Free list is a stack: slot 0 is handed out first.
    freeList_[i] = static_cast<LandmarkIndex>(kMaxLandmarks - 1U - i);
  }
  freeCount_ = kMaxLandmarks;
  size_ = 0;
  nextId_ = 1;
  counters_ = LandmarkMapCounters{};
}

std::int32_t LandmarkMap::cellOf(double v) const noexcept {
  return static_cast<std::int32_t>(std::floor(v / params_.cellSize));
}

Status LandmarkMap::checkPoint(double x, double y) const noexcept {
  if (!std::isfinite(x) || !std::isfinite(y)) {
    return Status::NonFiniteInput;
  }
  if (std::fabs(x) > kMaxMapCoordinate || std::fabs(y) > kMaxMapCoordinate) {
    return Status::OutOfRange;
  }
  return Status::Ok;
}

void LandmarkMap::link(LandmarkIndex index) noexcept {
  Node& n = nodes_[index];
  n.cx = cellOf(slots_[index].x);
  n.cy = cellOf(slots_[index].y);
  const std::size_t b = bucketOf(n.cx, n.cy);
  n.next = buckets_[b];
  buckets_[b] = index;
}

void LandmarkMap::unlink(LandmarkIndex index) noexcept {
  // The removed node keeps its `next`, so a query walking the chain may remove the node it visits.
  const Node& n = nodes_[index];
  const std::size_t b = bucketOf(n.cx, n.cy);
  if (buckets_[b] == index) {
    buckets_[b] = n.next;
    return;
  }
  LandmarkIndex i = buckets_[b];
  for (std::size_t guard = 0; i != kNoLandmark && guard < kMaxLandmarks; ++guard) {
    if (nodes_[i].next == index) {
      nodes_[i].next = n.next;
      return;
    }
    i = nodes_[i].next;
  }
}

Result<LandmarkIndex> LandmarkMap::allocate(LandmarkKind kind, double x, double y, double variance) noexcept {
  const Status s = checkPoint(x, y);
  if (s != Status::Ok || !std::isfinite(variance) || variance < 0.0) {
    ++counters_.refusedInvalid;
    return s != Status::Ok ? s : Status::InvalidArgument;
  }
  if (freeCount_ == 0) {
    ++counters_.refusedFull;
    return Status::CapacityExceeded;
  }
  const LandmarkIndex index = freeList_[--freeCount_];
  Landmark& l = slots_[index];
  l = Landmark{};
  l.x = x;
  l.y = y;
  l.variance = variance;
  l.kind = kind;
  nodes_[index].live = true;
  link(index);
  ++size_;
  return index;
}

Result<LandmarkIndex> LandmarkMap::addSurveyed(LandmarkKind kind, double x, double y, double sigma,
                                               std::uint32_t id) noexcept {
  if (!std::isfinite(sigma) || sigma < 0.0) {
    ++counters_.refusedInvalid;
    return Status::InvalidArgument;
  }
  if (id == 0 || findById(id) != kNoLandmark) {
    ++counters_.refusedInvalid;
    return Status::InvalidArgument;
  }
  const Result<LandmarkIndex> r = allocate(kind, x, y, sigma * sigma);
  if (!r.ok()) {
    return r;
  }
  Landmark& l = slots_[r.value()];
  l.surveyed = true;
  l.id = id;
  l.hits = params_.maxHits;
  if (id >= nextId_) {
    nextId_ = id + 1U;
  }
  return r;
}

Result<LandmarkIndex> LandmarkMap::insert(LandmarkKind kind, double x, double y, double variance) noexcept {
  if (params_.mode != MapMode::Dynamic) {
    return Status::Unsupported;
  }
  const Result<LandmarkIndex> r = allocate(kind, x, y, variance);
  if (!r.ok()) {
    return r;
  }
  Landmark& l = slots_[r.value()];
  l.hits = params_.initialHits;
  l.id = nextId_++;
  if (nextId_ == 0) {
    nextId_ = 1;  // wrapped after 4e9 insertions; ids of long-dead landmarks are reused
  }
  ++counters_.inserted;
  return r;
}

void LandmarkMap::copyFrom(const LandmarkMap& other) noexcept {
  if (&other == this) {
    return;
  }
  params_ = other.params_;
  paramsValid_ = other.paramsValid_;
  std::copy(std::begin(other.slots_), std::end(other.slots_), std::begin(slots_));
  std::copy(std::begin(other.nodes_), std::end(other.nodes_), std::begin(nodes_));
  std::copy(std::begin(other.buckets_), std::end(other.buckets_), std::begin(buckets_));
  std::copy(std::begin(other.freeList_), std::end(other.freeList_), std::begin(freeList_));
  freeCount_ = other.freeCount_;
  size_ = other.size_;
  nextId_ = other.nextId_;
  counters_ = other.counters_;
}

Status LandmarkMap::reinforce(LandmarkIndex index, double x, double y, double observationVariance,
                              std::uint32_t cycle) noexcept {
  if (index >= kMaxLandmarks || !nodes_[index].live) {
    return Status::NotFound;
  }
  if (checkPoint(x, y) != Status::Ok || !std::isfinite(observationVariance) || observationVariance < 0.0) {
    return Status::NonFiniteInput;
  }
  Landmark& l = slots_[index];
  l.lastMatchedCycle = cycle;
  if (l.surveyed || params_.mode != MapMode::Dynamic) {
    return Status::Ok;
  }
  if (l.hits < params_.maxHits) {
    ++l.hits;
  }
  const double a = params_.updateRate;
  const double nx = l.x + a * (x - l.x);
  const double ny = l.y + a * (y - l.y);
  l.variance = (1.0 - a) * (1.0 - a) * l.variance + a * a * observationVariance;
  if (cellOf(nx) != nodes_[index].cx || cellOf(ny) != nodes_[index].cy) {
    unlink(index);
    l.x = nx;
    l.y = ny;
    link(index);
  } else {
    l.x = nx;
    l.y = ny;
  }
  return Status::Ok;
}

bool LandmarkMap::weaken(LandmarkIndex index) noexcept {
  if (index >= kMaxLandmarks || !nodes_[index].live) {
    return false;
  }
  Landmark& l = slots_[index];
  if (l.surveyed || params_.mode != MapMode::Dynamic) {
    return false;
  }
  --l.hits;
  if (l.hits <= 0) {
    (void)remove(index);
    return true;
  }
  return false;
}

Status LandmarkMap::remove(LandmarkIndex index) noexcept {
  if (index >= kMaxLandmarks || !nodes_[index].live) {
    return Status::NotFound;
  }
  unlink(index);
  nodes_[index].live = false;
  freeList_[freeCount_++] = index;
  --size_;
  ++counters_.deleted;
  return Status::Ok;
}

LandmarkIndex LandmarkMap::findById(std::uint32_t id) const noexcept {
  for (std::size_t i = 0; i < kMaxLandmarks; ++i) {
    if (nodes_[i].live && slots_[i].id == id) {
      return static_cast<LandmarkIndex>(i);
    }
  }
  return kNoLandmark;
}

}  // namespace agv
