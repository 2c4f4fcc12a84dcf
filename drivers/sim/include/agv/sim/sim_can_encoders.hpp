#pragma once
/// @file sim_can_encoders.hpp
/// The vehicle's two CANopen encoder nodes, simulated: a CiA 402 traction drive sending its
/// position actual value (0x6064) and a CiA 406 steering encoder sending its position value
/// (0x6004), each in a TPDO, with their heartbeats and NMT state machine. The frames are built by
/// the portable encoders of `agv/drivers/protocol/canopen/canopen_encoders.hpp`, so the vehicle-side
/// decoder (`canopen::CanopenEncoders`) reads exactly what it reads from the real devices.

#include <cstddef>
#include <cstdint>

#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/drivers/protocol/can_frame.hpp"
#include "agv/drivers/protocol/canopen/canopen_encoders.hpp"
#include "agv/hal/encoder_sample.hpp"

namespace agv::sim {

/// Set-up of the two simulated nodes.
struct SimCanEncodersParams {
  /// The bus as commissioned: node ids, PDO mappings, directions, steering resolution and zero,
  /// heartbeat consumer time, SYNC period. The simulated nodes send according to `drive` and
  /// `steering`; with `syncPeriod` > 0 their TPDOs are synchronous (transmission type 1: sent on
  /// each SYNC), otherwise cyclic (one per measurement). The same struct configures the decoder.
  drivers::canopen::CanopenEncodersConfig bus;
  /// Drive position [ticks, forward positive, `bus.drive.direction` applied] while the simulated
  /// wheel counter reads 0. Default: 30000 ticks (3 m at 1e-4 m/tick) below the overflow of the
  /// drive's INTEGER32 position value, so a run crosses the 2^32 wrap of the raw counter. Must
  /// lie in [-2^31, 2^31) for the decoder's first (absolute) value to equal it.
  std::int64_t driveTicksAtZero = (std::int64_t{1} << 31) - 30000;
  /// Heartbeat producer time of both nodes (object 0x1017).
  Duration heartbeatPeriod = Duration::fromMilliseconds(100);
};

/// The commissioning of the simulated vehicle's bus: drive node 1 (TPDO1 0x181, 32-bit, counting
/// down when driving forward), steering node 2 (TPDO1 0x182, 32-bit field, single-turn encoder of
/// `steerCountsPerRevolution` counts with straight ahead at 16000 of 16384 for 14 bits, so left
/// turns cross the revolution wrap), heartbeat consumer time 300 ms, no SYNC.
SimCanEncodersParams defaultSimCanEncoders(std::uint32_t steerCountsPerRevolution);

/// InvalidArgument when the decoder would refuse `params.bus` (`CanopenEncoders::validate`) or
/// `driveTicksAtZero` lies outside [-2^31, 2^31).
Status validateSimCanEncoders(const SimCanEncodersParams& params) noexcept;

/// Counters of the simulated nodes.
struct SimCanNodeCounters {
  std::uint64_t drivePdos = 0;     ///< drive TPDOs sent
  std::uint64_t steeringPdos = 0;  ///< steering TPDOs sent
  std::uint64_t heartbeats = 0;    ///< heartbeat and boot-up frames sent
  std::uint64_t syncsReceived = 0;
  std::uint64_t nmtReceived = 0;
  /// Drive TPDOs whose INTEGER32 position value overflowed since the previous one (a jump of
  /// 2^32 in the signed value: the wrap the decoder must unwrap).
  std::uint64_t driveCounterWraps = 0;
};

/// The two nodes, powered on at construction: pre-operational (no PDOs), their boot-up messages
/// sent with the first measurement; an NMT Start makes them operational, a reset sends the
/// boot-up again. Frames are stamped with the measurement time they belong to.
class SimCanEncoders {
 public:
  /// Most frames one call writes: a boot-up or heartbeat per node and a TPDO per node.
  static constexpr std::size_t kMaxFramesPerMeasurement = 4;

  explicit SimCanEncoders(const SimCanEncodersParams& params) noexcept;

  /// A frame the nodes receive (NMT for either node or all nodes, SYNC); others are ignored.
  void receive(const drivers::CanFrame& frame) noexcept;

  /// The nodes' positions at `truth.stamp` (the simulated wheel counter and the measured steering
  /// angle): writes into `out` the frames they send at that time (boot-up after power-on or a
  /// reset, heartbeats when due, TPDOs when operational and, in synchronous mode, a SYNC was
  /// received since the previous measurement) and returns their count.
  std::size_t measure(const hal::EncoderSample& truth, Span<drivers::CanFrame> out) noexcept;

  /// What the decoder should report for `truth` (drive ticks with the counter's start added).
  hal::EncoderSample expectedDecoded(const hal::EncoderSample& truth) const noexcept;

  /// NMT state of each node.
  drivers::canopen::NmtState driveState() const noexcept { return drive_.state; }
  drivers::canopen::NmtState steeringState() const noexcept { return steer_.state; }
  const SimCanNodeCounters& counters() const noexcept { return counters_; }
  const SimCanEncodersParams& params() const noexcept { return params_; }

 private:
  struct Node {
    drivers::canopen::NmtState state = drivers::canopen::NmtState::PreOperational;
    bool bootPending = true;  ///< sends its boot-up message at the next measurement
  };
  static void nmt(drivers::canopen::NmtCommand command, Node& node) noexcept;

  SimCanEncodersParams params_;
  Node drive_{};
  Node steer_{};
  bool syncReceived_ = false;
  bool heartbeatStarted_ = false;
  Timestamp nextHeartbeat_{};
  bool haveLastValue_ = false;
  std::int64_t lastValue_ = 0;  // drive position value as the device's signed field holds it
  SimCanNodeCounters counters_{};
};

}  // namespace agv::sim
