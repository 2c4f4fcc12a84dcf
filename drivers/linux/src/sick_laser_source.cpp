#include "agv/drivers/linux/sick_laser_source.hpp"

#include <cmath>
#include <cstring>

namespace agv::drivers {
namespace {

ColaAScanClientConfig colaConfig(const SickLaserSourceConfig& c) noexcept {
  ColaAScanClientConfig out;
  out.tcp = c.tcp;
  out.scan = c.scan;
  out.subscribe = c.subscribe;
  return out;
}

Nav350ClientConfig navConfig(const SickLaserSourceConfig& c) noexcept {
  Nav350ClientConfig out;
  out.tcp = c.tcp;
  out.nav = c.nav;
  return out;
}

}  // namespace

const char* toString(SickLaserModel model) noexcept {
  switch (model) {
    case SickLaserModel::Lms1xx:
      return "lms1xx";
    case SickLaserModel::Lms5xx:
      return "lms5xx";
    case SickLaserModel::Tim:
      return "tim";
    case SickLaserModel::Nav350:
      return "nav350";
  }
  return "unknown";
}

bool parseSickLaserModel(const char* name, SickLaserModel& model) noexcept {
  if (name == nullptr) {
    return false;
  }
  for (const SickLaserModel m :
       {SickLaserModel::Lms1xx, SickLaserModel::Lms5xx, SickLaserModel::Tim, SickLaserModel::Nav350}) {
    if (std::strcmp(name, toString(m)) == 0) {
      model = m;
      return true;
    }
  }
  return false;
}

std::uint16_t defaultPort(SickLaserModel model) noexcept {
  return model == SickLaserModel::Nav350 ? 2112 : 2111;
}

void applyModelRanges(SickLaserModel model, sick::ColaAScanConfig& scan, sick::Nav350Config& nav) noexcept {
  switch (model) {
    case SickLaserModel::Lms1xx:
      scan.rangeMin = 0.5F;
      scan.rangeMax = 20.0F;
      break;
    case SickLaserModel::Lms5xx:
      scan.rangeMin = 0.05F;
      scan.rangeMax = 80.0F;
      break;
    case SickLaserModel::Tim:
      scan.rangeMin = 0.05F;
      scan.rangeMax = 25.0F;
      break;
    case SickLaserModel::Nav350:
      nav.rangeMin = 0.5F;
      nav.rangeMax = 250.0F;
      break;
  }
}

SickLaserSource::SickLaserSource(const SickLaserSourceConfig& config) noexcept
    : config_(config), cola_(colaConfig(config)), nav_(navConfig(config)) {}

bool SickLaserSource::connected() const noexcept {
  return config_.model == SickLaserModel::Nav350 ? nav_.connected() : cola_.connected();
}

int SickLaserSource::fileDescriptor() const noexcept {
  return config_.model == SickLaserModel::Nav350 ? nav_.fileDescriptor() : cola_.fileDescriptor();
}

const TcpStreamCounters& SickLaserSource::tcpCounters() const noexcept {
  return config_.model == SickLaserModel::Nav350 ? nav_.tcpCounters() : cola_.tcpCounters();
}

const sick::FramerCounters& SickLaserSource::framerCounters() const noexcept {
  return config_.model == SickLaserModel::Nav350 ? nav_.framerCounters() : cola_.framerCounters();
}

void SickLaserSource::disconnect() noexcept {
  if (config_.model == SickLaserModel::Nav350) {
    nav_.disconnect();
  } else {
    cola_.disconnect();
  }
}

Status SickLaserSource::health() const noexcept {
  if (!started_) {
    return Status::NotInitialized;
  }
  const Timestamp now = monotonicNow();
  if (now - lastHeard_ > config_.scanTimeout) {
    return Status::Timeout;
  }
  // Answering, but with error replies only (a NAV350 reporting a fault) for longer than the
  // timeout: a fault, not "ok" on the strength of an old sweep.
  if (now - (haveSweep_ ? lastGood_ : startedAt_) > config_.scanTimeout) {
    return Status::DeviceFault;
  }
  return haveSweep_ ? Status::Ok : Status::NotInitialized;
}

Status SickLaserSource::silence(Timestamp now) noexcept {
  // A connection opened since the last sweep gets a whole scanTimeout to deliver one: otherwise,
  // with scanTimeout <= reconnectInterval, the cycle that opens a connection would close it again
  // before the laser could answer, forever.
  const std::uint32_t connects = tcpCounters().connects;
  if (connects != connectsSeen_) {
    connectsSeen_ = connects;
    lastSweep_ = now;
  }
  if (now - lastHeard_ <= config_.scanTimeout) {
    return Status::NotFound;
  }
  if (now - lastSweep_ > config_.scanTimeout) {
    // Silent on an open connection (stream lost, request unanswered): start over, once per timeout.
    if (connected()) {
      disconnect();
      ++counters_.silenceReconnects;
    }
    lastSweep_ = now;
  }
  return Status::Timeout;
}

Status SickLaserSource::readNav(hal::LaserMeasurement& out, Timestamp now) noexcept {
  const std::uint32_t errorsBefore = nav_.counters().decodeErrors;
  const std::uint32_t implausibleBefore = nav_.counters().implausible;
  const Status s = nav_.poll(true, config_.navMask, reply_, config_.connectBudget);
  counters_.malformed += nav_.counters().decodeErrors - errorsBefore;
  counters_.implausible += nav_.counters().implausible - implausibleBefore;
  if (s != Status::Ok && s != Status::CapacityExceeded) {
    if (nav_.counters().decodeErrors != errorsBefore) {
      return Status::Malformed;
    }
    return silence(now);
  }
  if (reply_.errorCode != 0U) {
    ++counters_.deviceErrors;
    lastHeard_ = now;  // the device answers: not silent, but faulty
    lastSweep_ = now;
    return Status::DeviceFault;
  }
  if (reply_.scanValid) {
    out.scan = reply_.scan;
  } else {
    out.scan.ranges.clear();
    out.scan.stamp = reply_.receivedAt;  // the instant the reflectors' stamps are relative to
  }
  out.reflectors.clear();
  out.hasReflectors = reply_.landmarksValid;
  for (std::size_t i = 0; i < reply_.reflectors.size(); ++i) {
    const sick::Nav350Reflector& r = reply_.reflectors[i];
    if (!r.hasPolar) {
      continue;  // only the polar measurement is in the sensor frame
    }
    hal::ReflectorObservation o;
    o.x = static_cast<float>(r.range * std::cos(r.bearing));
    o.y = static_cast<float>(r.range * std::sin(r.bearing));
    o.id = r.hasDetails ? r.localId : std::uint16_t{0};
    // The device stamps each reflector: its time within the turn, for the motion compensation.
    o.stamped = r.hasDetails && sick::nav350VehicleTime(reply_, r.timestampMs, o.stamp);
    (void)out.reflectors.push_back(o);  // refusals counted by the list
  }
  counters_.truncatedSweeps += (s == Status::CapacityExceeded || reply_.reflectors.refusedCount() > 0U) ? 1U : 0U;
  return Status::Ok;
}

Status SickLaserSource::read(hal::LaserMeasurement& out) noexcept {
  const Timestamp now = monotonicNow();
  if (!started_) {
    started_ = true;
    startedAt_ = now;
    lastSweep_ = now;
    lastHeard_ = now;
  }
  Status s = Status::Ok;
  if (config_.model == SickLaserModel::Nav350) {
    s = readNav(out, now);
  } else {
    const std::uint32_t errorsBefore = cola_.counters().decodeErrors;
    const std::uint32_t implausibleBefore = cola_.counters().implausible;
    s = cola_.poll(out.scan, config_.connectBudget);
    counters_.malformed += cola_.counters().decodeErrors - errorsBefore;
    counters_.implausible += cola_.counters().implausible - implausibleBefore;
    if (s == Status::Ok || s == Status::CapacityExceeded) {
      counters_.truncatedSweeps += s == Status::CapacityExceeded ? 1U : 0U;
      out.reflectors.clear();
      out.hasReflectors = false;
      s = Status::Ok;
    } else if (cola_.counters().decodeErrors != errorsBefore) {
      s = Status::Malformed;
    } else {
      s = silence(now);
    }
  }
  if (s == Status::Ok) {
    ++counters_.sweeps;
    haveSweep_ = true;
    lastSweep_ = now;
    lastHeard_ = now;
    lastGood_ = now;
  }
  return s;
}

}  // namespace agv::drivers
