#pragma once
/// @file canopen_encoder_source.hpp
/// The vehicle's drive and steering encoders as CANopen nodes on a SocketCAN bus (Linux only):
/// a `hal::EncoderSource` made of a `SocketCanBus` and the portable `canopen::CanopenEncoders`
/// decoder.
///
/// `open()` opens the bus with acceptance filters for the two nodes' objects (TPDOs, EMCY,
/// heartbeat) and sends NMT Start to both nodes. Each `read()` never blocks: it reads the frames
/// waiting in the socket (at most `maxFramesPerRead`), stamped by the kernel at reception
/// (SO_TIMESTAMPNS, mapped onto CLOCK_MONOTONIC), feeds them to the decoder, sends what is due
/// (SYNC every `syncPeriod`, NMT Start to a node that booted again) and returns the oldest
/// complete sample. Faults: heartbeat timeout, EMCY, a node not operational, CAN error frames,
/// bus-off and a lost or missing interface; the bus reopens itself (see `SocketCanBus`), a bus
/// that could not be opened at all is retried every `openRetryInterval`, and NMT Start is sent
/// again after every recovery (reopen, bus-off restart).
///
/// No heap after construction; not thread-safe (one loop owns the source).

#include <cstdint>

#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/drivers/linux/socketcan_bus.hpp"
#include "agv/drivers/protocol/canopen/canopen_encoders.hpp"
#include "agv/hal/encoder_source.hpp"

namespace agv::drivers {

/// Configuration of a `CanopenEncoderSource`.
struct CanopenEncoderSourceConfig {
  /// Interface name (can0, vcan0 ...; at most 15 characters), copied by the constructor.
  const char* interfaceName = "can0";
  /// Node ids, PDO mapping, scaling, direction, heartbeat timeout, SYNC period, sample trigger.
  canopen::CanopenEncodersConfig canopen;
  /// Time between attempts to open a bus that could not be opened (interface missing or down).
  Duration openRetryInterval = Duration::fromSeconds(1.0);
  /// Bound of the frames one `read()` handles (the rest wait in the socket for the next call).
  std::uint32_t maxFramesPerRead = 64;
  /// Socket receive buffer in bytes (0: kernel default); see `SocketCanConfig`.
  int receiveBufferBytes = 0;
  /// A bus-off with no restart report for this long makes the bus reopen its socket.
  Duration busOffReopenAfter = Duration::fromSeconds(2.0);
};

/// Running totals of a `CanopenEncoderSource` (the bus's own counters are in `busHealth()`).
struct CanopenEncoderSourceCounters {
  std::uint64_t framesHandled = 0;  ///< data frames given to the decoder
  std::uint64_t errorFrames = 0;    ///< CAN error frames seen (decoded by the bus)
  std::uint64_t samples = 0;        ///< samples returned by `read()`
  std::uint64_t nmtStartsSent = 0;  ///< NMT Start frames the kernel accepted
  std::uint64_t syncsSent = 0;      ///< SYNC frames the kernel accepted
  std::uint64_t sendFailures = 0;   ///< NMT/SYNC frames refused (bus-off, link down, queue full)
  std::uint64_t openAttempts = 0;   ///< calls to open the bus (first one included)
  std::uint64_t recoveries = 0;     ///< reopens and bus-off restarts after which NMT Start was re-sent
};

/// CiA 402 drive + CiA 406 steering encoder over SocketCAN, as a `hal::EncoderSource`.
class CanopenEncoderSource final : public hal::EncoderSource {
 public:
  explicit CanopenEncoderSource(const CanopenEncoderSourceConfig& config) noexcept;
  ~CanopenEncoderSource() = default;
  CanopenEncoderSource(const CanopenEncoderSource&) = delete;
  CanopenEncoderSource& operator=(const CanopenEncoderSource&) = delete;

  /// Checks the configuration, opens the bus and sends NMT Start to both nodes.
  /// `InvalidArgument` for a bad configuration (nothing opened, `read()` then returns it too);
  /// the bus's failure (`NotFound`, `Unsupported`, `DeviceFault`) when it cannot be opened now:
  /// `read()` keeps trying every `openRetryInterval`.
  Status open() noexcept;
  /// Closes the bus; `read()` returns `NotInitialized` until `open()`.
  void close() noexcept;

  /// See `hal::EncoderSource::read`. Never waits. `Ok` with the oldest complete sample (kernel
  /// receive time of its last frame); `NotFound` when none is complete yet; `Timeout` when a
  /// node's heartbeat timed out; `DeviceFault` when the bus is down, missing or bus-off, an EMCY
  /// is active or a node is not operational; `InvalidArgument`/`NotInitialized` as for `open()`.
  /// A pending sample is returned before any fault is reported.
  Status read(hal::EncoderSample& out) noexcept override;

  /// Current state without reading: `Ok`, or the fault `read()` would report when it has no sample
  /// (`NotInitialized` until both positions arrived).
  Status health() const noexcept override;

  /// Oldest unreported EMCY, once (see `CanopenEncoders::takeEmcy`).
  bool takeEmcy(canopen::EmcyRecord& record) noexcept { return decoder_.takeEmcy(record); }

  const canopen::CanopenEncoders& decoder() const noexcept { return decoder_; }
  const SocketCanHealth& busHealth() const noexcept { return bus_.health(); }
  /// The CAN socket (-1 while the bus is not open), for a loop that waits for frames on it
  /// (apps/vehicle); valid until the next `read()`.
  int fileDescriptor() const noexcept { return bus_.fileDescriptor(); }
  const CanopenEncoderSourceCounters& counters() const noexcept { return counters_; }
  /// The status of the last attempt to open the bus (`Ok` once open).
  Status openStatus() const noexcept { return openStatus_; }

 private:
  Status tryOpen(Timestamp now) noexcept;
  void sendFrame(const CanFrame& frame) noexcept;
  void sendStartup() noexcept;
  void watchRecovery() noexcept;

  CanopenEncoderSourceConfig config_;
  char name_[16] = {};
  canopen::CanopenEncoders decoder_;
  SocketCanBus bus_;
  Status configStatus_ = Status::Ok;
  Status openStatus_ = Status::NotInitialized;
  bool wanted_ = false;  ///< open() was called and close() was not
  Timestamp nextOpen_{};
  std::uint64_t seenReopens_ = 0;
  bool wasBusOff_ = false;
  CanopenEncoderSourceCounters counters_{};
};

}  // namespace agv::drivers
