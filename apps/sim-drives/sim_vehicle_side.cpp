#include "sim_vehicle_side.hpp"

#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>

#include "agv/core/angle.hpp"
#include "agv/drivers/protocol/sick/nav350.hpp"
#include "sim_drive_side.hpp"

namespace agv::simdrives {

namespace {

constexpr Duration kDrivePeriod = Duration::fromMilliseconds(10);

/// Reads exactly `n` bytes into `out` unless the peer closes or `stop()` turns true (then false).
template <typename Stop>
bool readExactly(int fd, std::uint8_t* out, std::size_t n, Stop stop) {
  std::size_t got = 0;
  while (got < n) {
    if (stop()) {
      return false;
    }
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 100) != 1) {
      continue;
    }
    const ssize_t r = ::recv(fd, out + got, n - got, 0);
    if (r <= 0) {
      return false;  // closed (or reset)
    }
    got += static_cast<std::size_t>(r);
  }
  return true;
}

bool parseNumber(const std::string& s, double& v) {
  char* end = nullptr;
  v = std::strtod(s.c_str(), &end);
  return !s.empty() && end != nullptr && *end == '\0' && std::isfinite(v);
}

}  // namespace

bool parseDirectMove(const std::string& text, DirectMove& out, std::string& error) {
  error = "'" + text + "': expected SPEED:STEER@FROM-TO (m/s, degrees, seconds)";
  const std::size_t colon = text.find(':');
  const std::size_t at = text.find('@');
  if (colon == std::string::npos || at == std::string::npos || at < colon) {
    return false;
  }
  const std::size_t dash = text.find('-', at + 2);  // not the sign of FROM
  if (dash == std::string::npos) {
    return false;
  }
  DirectMove m;
  double steerDeg = 0.0;
  if (!parseNumber(text.substr(0, colon), m.speed) || !parseNumber(text.substr(colon + 1, at - colon - 1), steerDeg) ||
      !parseNumber(text.substr(at + 1, dash - at - 1), m.from) || !parseNumber(text.substr(dash + 1), m.to) ||
      m.from < 0.0 || m.to <= m.from) {
    return false;
  }
  m.steer = deg2rad(steerDeg);
  out = m;
  error.clear();
  return true;
}

SimVehicleSide::SimVehicleSide(const SimVehicleSideOptions& options, Timestamp now, std::FILE* log)
    : options_(options), log_(log) {
  sim::WorldParseError perr;
  const Status parsed = options_.worldFile.empty() ? sim::parseWorld(sim::defaultWorldText(), world_, perr)
                                                   : sim::loadWorldFile(options_.worldFile, world_, perr);
  if (parsed != Status::Ok) {
    status_ = parsed;
    error_ = "world " + (options_.worldFile.empty() ? std::string("(built-in)") : options_.worldFile) + ": line " +
             std::to_string(perr.line) + ": " + perr.message;
    return;
  }
  caster_ = std::make_unique<sim::RayCaster>(world_, 1.0);
  sim::SimVehicleParams vp;
  vehicle_ = std::make_unique<sim::SimVehicle>(vp, options_.seed * 7919U + 17U);
  vehicle_->reset(options_.start, now);
  sim::SimLaserParams lp;
  lp.angularResolution = deg2rad(options_.laserResolutionDeg);
  lp.scanRate = options_.laserRate;
  laser_ = std::make_unique<sim::SimLaser>(*caster_, lp, options_.seed * 104729U + 3U);
  if (laser_->status() != Status::Ok) {
    status_ = laser_->status();
    error_ = std::string("laser parameters refused: ") + toString(status_);
    return;
  }
  server_ = std::make_unique<drivers::LoopbackServer>(options_.laserPort);
  if (!server_->ok()) {
    status_ = Status::DeviceFault;
    error_ = "laser port " + std::to_string(options_.laserPort) + ": cannot listen on 127.0.0.1";
    return;
  }
  start_ = now;
  nextDrive_ = now;
  nextSweep_ = now + laser_->period();
  sweepStartPose_ = vehicle_->trueLaserPose();
  server_->start([this](drivers::LoopbackServer& s) { serve(s); });
}

SimVehicleSide::~SimVehicleSide() {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  newSweep_.notify_all();
  if (server_) {
    server_->join();
  }
}

std::uint64_t SimVehicleSide::replies() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return replies_;
}

std::uint32_t SimVehicleSide::deviceMs(Timestamp t) const noexcept {
  return static_cast<std::uint32_t>(static_cast<std::int64_t>(std::llround((t - start_).seconds() * 1e3)));
}

std::size_t SimVehicleSide::step(Timestamp now, SimDrives& drives, Span<drivers::CanFrame> out, std::size_t count) {
  if (status_ != Status::Ok) {
    return count;
  }
  vehicle_->advanceTo(now);
  if (now >= nextDrive_) {
    nextDrive_ = nextDrive_ + kDrivePeriod;
    if (nextDrive_ <= now) {
      nextDrive_ = now + kDrivePeriod;
    }
    feedWheel(*vehicle_, drives.node(drives.traction().nodeId()), wheelTicks_, wheelSteer_);
    hal::DriveCommand cmd = motorsToVehicle(drives.traction(), drives.steering(), options_.drives,
                                            vehicle_->params().truth.driveScale, now);
    const double t = (now - start_).seconds();
    for (const DirectMove& m : options_.moves) {
      if (t >= m.from && t < m.to) {
        cmd.speed = m.speed;
        cmd.steeringAngle = m.steer;
      }
    }
    static_cast<void>(vehicle_->command(cmd));
    drivers::CanFrame encoder[2];
    steeringEncoderFrames(wheelSteer_, now, encoder);
    for (const drivers::CanFrame& f : encoder) {
      if (count < out.size()) {
        out[count++] = f;
      }
    }
  }
  if (now >= nextSweep_) {
    const Timestamp sweepStart = nextSweep_ - laser_->period();
    publishSweep(sweepStart, now);
    nextSweep_ = nextSweep_ + laser_->period();
    if (nextSweep_ <= now) {
      nextSweep_ = now + laser_->period();
    }
  }
  return count;
}

void SimVehicleSide::publishSweep(Timestamp start, Timestamp end) {
  const Pose2d endPose = vehicle_->trueLaserPose();
  hal::LaserMeasurement m;
  const Status s = laser_->scan(sweepStartPose_, endPose, start, m);
  sweepStartPose_ = endPose;
  if (s != Status::Ok) {
    return;
  }
  ++sweeps_;
  drivers::sick::Nav350PoseReply r;
  r.version = 1;
  r.wait = 1;
  r.mask = static_cast<std::uint8_t>(drivers::sick::Nav350Mask::PoseReflectorsScan);
  r.poseValid = true;
  r.pose = endPose;  // the device's own pose estimate: the truth (agvnav-vehicle does not use it)
  r.poseDetailsValid = true;
  r.poseTimestampMs = deviceMs(end);
  r.navigationMode = 4;
  r.landmarksValid = true;
  r.landmarkFilter = 1;
  std::uint16_t id = 1;
  for (const hal::ReflectorObservation& o : m.reflectors) {
    drivers::sick::Nav350Reflector ref;
    ref.hasPolar = true;
    ref.range = std::hypot(static_cast<double>(o.x), static_cast<double>(o.y));
    ref.bearing = std::atan2(static_cast<double>(o.y), static_cast<double>(o.x));
    ref.hasDetails = true;
    ref.localId = id++;
    ref.type = 1;
    ref.subType = 2;
    ref.quality = 100;
    ref.timestampMs = deviceMs(o.stamped ? o.stamp : end);
    ref.size = 0.08;
    static_cast<void>(r.reflectors.push_back(ref));
  }
  r.reflectorCount = static_cast<std::uint16_t>(r.reflectors.size());
  r.scanValid = true;
  r.scanTimestampMs = deviceMs(start);
  r.scan = m.scan;
  std::vector<std::uint8_t> payload(32768);  // one sweep at 0.25 deg: ~6 KB
  std::vector<std::uint8_t> framed(payload.size() + 16);
  const drivers::sick::Nav350Config config;
  const std::size_t n =
      drivers::sick::encodeNav350PoseReply(r, config, Span<std::uint8_t>(payload.data(), payload.size()));
  const std::size_t f = n == 0 ? 0
                               : drivers::sick::encodeColaB(Span<const std::uint8_t>(payload.data(), n),
                                                            Span<std::uint8_t>(framed.data(), framed.size()));
  if (f == 0) {
    if (log_ != nullptr) {
      std::fprintf(log_, "agvnav-sim-drives: a sweep does not fit the reply buffer\n");
    }
    return;
  }
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    framed.resize(f);
    reply_.swap(framed);
    ++replySeq_;
  }
  newSweep_.notify_all();
}

void SimVehicleSide::serve(drivers::LoopbackServer& server) {
  const auto stopping = [this] {
    const std::lock_guard<std::mutex> lock(mutex_);
    return stopping_;
  };
  while (!stopping()) {
    const int fd = server.accept(200);
    if (fd < 0) {
      continue;
    }
    if (log_ != nullptr) {
      std::fprintf(log_, "agvnav-sim-drives: laser connected\n");
    }
    // Binary CoLa requests: 4 STX bytes, a 32-bit big-endian length, the payload, a checksum.
    // Each is answered with the next sweep (`sMN mNPOSGetData 1 <mask>`: after the next scan).
    for (;;) {
      std::uint8_t head[8];
      if (!readExactly(fd, head, sizeof head, stopping)) {
        break;
      }
      const std::size_t length = (std::size_t{head[4]} << 24U) | (std::size_t{head[5]} << 16U) |
                                 (std::size_t{head[6]} << 8U) | std::size_t{head[7]};
      std::uint8_t body[1025];
      if (head[0] != 0x02 || length > 1024 || !readExactly(fd, body, length + 1, stopping)) {
        break;
      }
      std::vector<std::uint8_t> reply;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        const std::uint64_t seq = replySeq_;
        newSweep_.wait(lock, [&] { return stopping_ || replySeq_ != seq; });
        if (stopping_) {
          break;
        }
        reply = reply_;
        ++replies_;
      }
      drivers::LoopbackServer::send(fd, reply);
    }
    ::close(fd);
    if (log_ != nullptr) {
      std::fprintf(log_, "agvnav-sim-drives: laser disconnected\n");
    }
  }
}

}  // namespace agv::simdrives
