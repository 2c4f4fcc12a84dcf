#include "agv/calib/calibration_file.hpp"

#include <cmath>

#include "../text_format.hpp"
#include "agv/core/angle.hpp"

namespace agv {

namespace {

enum Key : int {
  kWheelbase,
  kDriveScale,
  kSteerForward,
  kSteerBackward,
  kLaserX,
  kLaserY,
  kLaserTheta,
  kKeyCount,
};

struct KeySpec {
  const char* name;
  double minValue;
  double maxValue;
  bool hasSigma;  ///< false: the value is given, not estimated (wheelbase)
};

constexpr double kTwoPi = 2.0 * kPi<double>;

// Value ranges of the format (documented in the header).
constexpr KeySpec kKeys[kKeyCount] = {
    {"wheelbase", 0.1, 20.0, false},
    {"drive_scale", 0.0, 0.1, true},
    {"steer_offset_forward", -0.5, 0.5, true},
    {"steer_offset_backward", -0.5, 0.5, true},
    {"laser_x", -50.0, 50.0, true},
    {"laser_y", -50.0, 50.0, true},
    {"laser_theta", -kTwoPi, kTwoPi, true},
};

bool inRange(Key k, double v) noexcept {
  if (k == kDriveScale) {
    return v > 0.0 && v <= kKeys[k].maxValue;  // a zero scale would make every distance zero
  }
  return v >= kKeys[k].minValue && v <= kKeys[k].maxValue;
}

/// A sigma is at least 0 and at most the width of its value's range (larger says nothing, and
/// could not be written back with the file's decimals).
bool sigmaInRange(Key k, double sigma) noexcept {
  return sigma >= 0.0 && sigma <= kKeys[k].maxValue - kKeys[k].minValue;
}

/// The sigma field of `k` in `s` (const or not); nullptr for the wheelbase, which has none.
template <typename Sigmas>
auto sigmaSlot(Sigmas& s, Key k) noexcept -> decltype(&s.driveScale) {
  switch (k) {
    case kDriveScale:
      return &s.driveScale;
    case kSteerForward:
      return &s.steerOffsetForward;
    case kSteerBackward:
      return &s.steerOffsetBackward;
    case kLaserX:
      return &s.laserX;
    case kLaserY:
      return &s.laserY;
    case kLaserTheta:
      return &s.laserTheta;
    default:
      return nullptr;
  }
}

}  // namespace

Status parseCalibrationFile(Span<const char> textIn, VehicleCalibration& out, CalibrationFileReport* report) noexcept {
  CalibrationFileReport local;
  CalibrationFileReport& rep = report != nullptr ? *report : local;
  rep = CalibrationFileReport{};

  double values[kKeyCount] = {};
  double sigmas[kKeyCount] = {};
  bool seen[kKeyCount] = {};
  text::RecordReader reader(textIn.data(), textIn.size(), "agvnav-calibration", kCalibrationFileFormatVersion,
                            "the first record is not 'agvnav-calibration <version>'");
  const auto fail = [&](Status s, const char* detail) {
    const Status r = reader.fail(s, detail);
    rep.errorLine = reader.errorLine();
    rep.detail = reader.detail();
    rep.records = reader.records();
    return r;
  };
  const char* tb = nullptr;
  const char* te = nullptr;
  const char* p = nullptr;
  const char* e = nullptr;
  // Bounded: the reader consumes the text.
  while (reader.next(&tb, &te, &p, &e)) {
    rep.version = reader.version();
    const char* fb[3] = {};
    const char* fe[3] = {};
    int fields = 0;
    while (fields < 3 && text::nextToken(p, e, &fb[fields], &fe[fields])) {
      ++fields;
    }
    int key = -1;
    for (int k = 0; k < kKeyCount; ++k) {
      if (text::tokenIs(tb, te, kKeys[k].name)) {
        key = k;
      }
    }
    if (key < 0) {
      return fail(Status::Malformed, "unknown key");
    }
    const Key k = static_cast<Key>(key);
    rep.key = kKeys[k].name;
    const int maxFields = kKeys[k].hasSigma ? 2 : 1;
    if (fields < 1 || fields > maxFields) {
      return fail(Status::Malformed, nullptr);
    }
    double v = 0.0;
    double sigma = 0.0;
    if (!text::parseNumber(fb[0], fe[0], &v) || (fields == 2 && !text::parseNumber(fb[1], fe[1], &sigma))) {
      return fail(Status::Malformed, nullptr);
    }
    if (seen[k]) {
      return fail(Status::InvalidArgument, nullptr);
    }
    if (!inRange(k, v) || !sigmaInRange(k, sigma)) {
      return fail(Status::OutOfRange, nullptr);
    }
    seen[k] = true;
    values[k] = v;
    sigmas[k] = sigma;
    rep.key = nullptr;
  }
  rep.version = reader.version();
  rep.records = reader.records();
  if (reader.status() != Status::Ok) {
    rep.errorLine = reader.errorLine();
    rep.detail = reader.detail();
    return reader.status();
  }
  for (int k = 0; k < kKeyCount; ++k) {
    if (!seen[k]) {
      rep.key = kKeys[k].name;
      return Status::NotFound;
    }
  }
  VehicleCalibration cal;
  cal.params.wheelbase = values[kWheelbase];
  cal.params.driveScale = values[kDriveScale];
  cal.params.steerOffsetForward = values[kSteerForward];
  cal.params.steerOffsetBackward = values[kSteerBackward];
  cal.laserPose = Pose2d{values[kLaserX], values[kLaserY], normalizeAngle(values[kLaserTheta])};
  for (int k = 0; k < kKeyCount; ++k) {
    double* slot = sigmaSlot(cal.sigmas, static_cast<Key>(k));
    if (slot != nullptr) {
      *slot = sigmas[k];
    }
  }
  out = cal;
  return Status::Ok;
}

Result<std::size_t> formatCalibrationFile(const VehicleCalibration& cal, Span<char> out) noexcept {
  const double values[kKeyCount] = {
      cal.params.wheelbase, cal.params.driveScale, cal.params.steerOffsetForward, cal.params.steerOffsetBackward,
      cal.laserPose.x,      cal.laserPose.y,       cal.laserPose.theta,
  };
  for (int k = 0; k < kKeyCount; ++k) {
    const Key key = static_cast<Key>(k);
    const double s = kKeys[k].hasSigma ? *sigmaSlot(cal.sigmas, key) : 0.0;
    if (!std::isfinite(values[k]) || !inRange(key, values[k]) || !std::isfinite(s) || !sigmaInRange(key, s)) {
      return Status::OutOfRange;
    }
  }
  static constexpr const char* kComments[kKeyCount] = {
      "L [m], given", "s_w [m/tick]", "alpha_F [rad]",     "alpha_B [rad]",
      "laser x [m]",  "laser y [m]",  "laser theta [rad]",
  };
  text::Writer w{out.data(), out.data() + out.size()};
  w.put("agvnav-calibration 2\n# key value sigma (SI units; sigma 0 = not known)\n");
  for (int k = 0; k < kKeyCount; ++k) {
    const Key key = static_cast<Key>(k);
    const int decimals = key == kDriveScale ? 12 : 9;
    w.put(kKeys[k].name);
    w.put(' ');
    w.putFixed(values[k], decimals);
    if (kKeys[k].hasSigma) {
      w.put(' ');
      w.putFixed(*sigmaSlot(cal.sigmas, key), decimals);
    }
    w.put("  # ");
    w.put(kComments[k]);
    if (key == kSteerForward || key == kSteerBackward || key == kLaserTheta) {
      w.put(" (");
      w.putFixed(rad2deg(values[k]), 4);
      w.put(" deg)");
    }
    w.put('\n');
  }
  w.put("end ");
  w.putUnsigned(kKeyCount, 1);
  w.put('\n');
  if (w.overflow) {
    return Status::Truncated;
  }
  return w.written(out.data());
}

}  // namespace agv
