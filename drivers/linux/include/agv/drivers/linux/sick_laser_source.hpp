#pragma once
/// @file sick_laser_source.hpp
/// A SICK laser on TCP as a `hal::LaserSource` for a polling loop (Linux only): LMS1xx, LMS5xx and
/// TiM scan streams (CoLa A `LMDscandata`, `ColaAScanClient`) or a NAV350 (binary CoLa
/// `mNPOSGetData` with reflectors and scan, `Nav350Client`).
///
/// `read()` never waits for data: it returns a sweep already received or reads what the socket
/// holds. Connecting is the only bounded wait (`connectBudget`, at most once per
/// `tcp.reconnectInterval`), after which the scan stream is subscribed again (or the NAV350 asked
/// again). A laser silent for `scanTimeout` is reported (`Timeout`) and its connection closed and
/// reopened, once per `scanTimeout`.
///
/// No heap; not thread-safe (one loop owns the source).

#include <cstdint>

#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/drivers/linux/sick_laser_client.hpp"
#include "agv/hal/laser_source.hpp"

namespace agv::drivers {

/// The SICK device family; it selects the protocol and the usual range limits.
enum class SickLaserModel : std::uint8_t {
  Lms1xx,  ///< CoLa A scan stream, port 2111, 0.5 .. 20 m
  Lms5xx,  ///< CoLa A scan stream, port 2111, 0.05 .. 80 m
  Tim,     ///< CoLa A scan stream (TiM5xx/7xx), port 2111, 0.05 .. 25 m
  Nav350,  ///< binary CoLa pose/reflectors/scan requests, port 2112, 0.5 .. 250 m
};

/// Stable lower-case name ("lms1xx", "lms5xx", "tim", "nav350"). Never null.
const char* toString(SickLaserModel model) noexcept;
/// Parses a name of `toString`; false when unknown.
bool parseSickLaserModel(const char* name, SickLaserModel& model) noexcept;
/// The device's TCP port (2111 CoLa A, 2112 binary CoLa).
std::uint16_t defaultPort(SickLaserModel model) noexcept;
/// Sets `scan.rangeMin/rangeMax` (CoLa A models) or `nav.rangeMin/rangeMax` (NAV350) to the
/// model's measuring range.
void applyModelRanges(SickLaserModel model, sick::ColaAScanConfig& scan, sick::Nav350Config& nav) noexcept;

/// Configuration of a `SickLaserSource`.
struct SickLaserSourceConfig {
  SickLaserModel model = SickLaserModel::Lms1xx;
  TcpStreamConfig tcp;         ///< address and port of the device, connect timeout, reconnect interval
  sick::ColaAScanConfig scan;  ///< CoLa A models: angle offset, range limits
  bool subscribe = true;       ///< CoLa A: stream (`sEN LMDscandata 1`) or poll each scan (`sRN`)
  sick::Nav350Config nav;      ///< NAV350: angle offset, range limits
  sick::Nav350Mask navMask = sick::Nav350Mask::PoseReflectorsScan;  ///< NAV350: what each reply carries
  /// Longest a `read()` spends on one connection attempt (and on sending a command).
  Duration connectBudget = Duration::fromMilliseconds(20);
  /// No sweep for this long: `Timeout`, and the connection is closed and reopened.
  Duration scanTimeout = Duration::fromMilliseconds(1000);
};

/// Running totals of a `SickLaserSource`.
struct SickLaserSourceCounters {
  std::uint32_t sweeps = 0;             ///< sweeps returned by `read()`
  std::uint32_t truncatedSweeps = 0;    ///< of those, with more beams than kMaxScanBeams (first ones kept)
  std::uint32_t malformed = 0;          ///< telegrams of the expected kind that did not decode
  std::uint32_t implausible = 0;        ///< of those, refused for an implausible scan header (scale, offset, step)
  std::uint32_t deviceErrors = 0;       ///< NAV350 replies with a non-zero error code
  std::uint32_t silenceReconnects = 0;  ///< connections closed because the laser stayed silent
};

/// SICK laser over TCP as a `hal::LaserSource`.
class SickLaserSource final : public hal::LaserSource {
 public:
  explicit SickLaserSource(const SickLaserSourceConfig& config) noexcept;
  ~SickLaserSource() = default;
  SickLaserSource(const SickLaserSource&) = delete;
  SickLaserSource& operator=(const SickLaserSource&) = delete;

  /// See `hal::LaserSource::read`. `Ok` with a sweep (NAV350: `hasReflectors` with the
  /// reflectors of the reply, in the sensor frame); `NotFound` when none is complete yet;
  /// `Timeout` when the laser has been silent or unreachable for `scanTimeout`; `Malformed` when
  /// a telegram failed to decode in this call; `DeviceFault` for a NAV350 error reply.
  Status read(hal::LaserMeasurement& out) noexcept override;

  /// `Ok` when a sweep arrived within `scanTimeout`; `NotInitialized` before the first one (within
  /// `scanTimeout` of the first `read()`); `Timeout` when nothing was heard for `scanTimeout`;
  /// `DeviceFault` when the device answers but gave no sweep for `scanTimeout` (NAV350 error
  /// replies).
  Status health() const noexcept override;

  bool connected() const noexcept;
  /// The laser connection's socket (-1 when not connected), for a loop that waits for input on it
  /// (apps/vehicle); valid until the next `read()`.
  int fileDescriptor() const noexcept;
  const SickLaserSourceCounters& counters() const noexcept { return counters_; }
  /// Connection counters of the TCP stream in use.
  const TcpStreamCounters& tcpCounters() const noexcept;
  /// Framing counters (garbage, truncated, oversized telegrams) of the stream in use.
  const sick::FramerCounters& framerCounters() const noexcept;

 private:
  Status readNav(hal::LaserMeasurement& out, Timestamp now) noexcept;
  Status silence(Timestamp now) noexcept;
  void disconnect() noexcept;

  SickLaserSourceConfig config_;
  ColaAScanClient cola_;
  Nav350Client nav_;
  sick::Nav350PoseReply reply_{};
  bool started_ = false;
  bool haveSweep_ = false;
  Timestamp lastSweep_{};           ///< last sweep, or the first read(), or the last silence reconnect
  Timestamp lastHeard_{};           ///< last sweep or error reply, or the first read()
  Timestamp lastGood_{};            ///< last sweep returned
  Timestamp startedAt_{};           ///< the first read()
  std::uint32_t connectsSeen_ = 0;  ///< TCP connects seen by the silence check
  SickLaserSourceCounters counters_{};
};

}  // namespace agv::drivers
