#pragma once
/// @file can_encoder_source.hpp
/// The vehicle's encoder input over a simulated CAN bus: the simulated vehicle's encoder
/// measurements go through the simulated CANopen nodes (`SimCanEncoders`) onto the bus as frames,
/// and the vehicle's decoder (`canopen::CanopenEncoders`, the code the real vehicle runs on its
/// SocketCAN frames) turns them back into `hal::EncoderSample`s. Frames the decoder sends (NMT
/// Start, SYNC) go to the nodes. An optional filter drops frames on the bus (fault injection).

#include <cstdint>
#include <functional>

#include "agv/drivers/protocol/canopen/canopen_encoders.hpp"
#include "agv/hal/encoder_source.hpp"
#include "agv/sim/sim_can_encoders.hpp"

namespace agv::sim {

/// What crossed the simulated bus.
struct CanBusCounters {
  std::uint64_t framesToDecoder = 0;  ///< node frames delivered to the decoder (after the filter)
  std::uint64_t framesToNodes = 0;    ///< decoder frames (NMT, SYNC) delivered to the nodes
  std::uint64_t framesDropped = 0;    ///< frames the filter dropped (both directions)
  std::uint64_t drivePositions = 0;   ///< decoded as drive positions
  std::uint64_t steeringPositions = 0;
  std::uint64_t heartbeats = 0;
  std::uint64_t emcys = 0;
  std::uint64_t malformed = 0;
  std::uint64_t ignored = 0;
  std::uint64_t measurements = 0;       ///< encoder measurements of the vehicle put on the bus
  std::uint64_t samples = 0;            ///< samples the decoder produced
  std::uint64_t sampleMismatches = 0;   ///< decoded samples that differ from the measurement sent
  std::uint64_t samplesWithheld = 0;    ///< decoded while the decoder reported a fault: not delivered
  std::uint64_t faultReads = 0;         ///< reads answered with the decoder's fault (Timeout, DeviceFault)
  std::uint64_t driveCounterWraps = 0;  ///< overflows of the drive's 32-bit position value on the bus

  /// Frames the decoder classified (positions, heartbeats, EMCYs).
  std::uint64_t framesDecoded() const noexcept { return drivePositions + steeringPositions + heartbeats + emcys; }
  CanBusCounters& operator+=(const CanBusCounters& o) noexcept;
};

/// `hal::EncoderSource` of the navigation in the simulation: every sample it returns was decoded
/// from CAN frames. `read()` puts the vehicle's pending measurements on the bus one at a time
/// (decoder service with SYNC/NMT to the nodes, then the nodes' frames to the decoder) until the
/// decoder has a sample:
/// - `Ok`: the decoded sample (drive ticks include the counter's start, see `SimCanEncodersParams`);
/// - `Timeout` / `DeviceFault`: the decoder's health (heartbeat timeout, node not operational or
///   EMCY active); a sample decoded meanwhile is withheld, as a vehicle stops on encoder faults;
/// - `NotFound`: no new measurement (or none decodable yet, e.g. the nodes are still starting).
class CanEncoderSource final : public hal::EncoderSource {
 public:
  /// Returns true to deliver `frame`, false to drop it. `toDecoder` tells the direction.
  using FrameFilter = std::function<bool(const drivers::CanFrame& frame, bool toDecoder)>;

  /// `measurements` is the vehicle's raw encoder source (kept by reference).
  CanEncoderSource(hal::EncoderSource& measurements, const SimCanEncodersParams& params);

  /// `validateSimCanEncoders` of the parameters.
  Status validate() const noexcept;

  Status read(hal::EncoderSample& out) noexcept override;
  /// The decoder's health (`CanopenEncoders::health`), as the real source reports it.
  Status health() const noexcept override { return decoder_.health(); }

  void setFilter(FrameFilter filter) { filter_ = std::move(filter); }

  const drivers::canopen::CanopenEncoders& decoder() const noexcept { return decoder_; }
  const SimCanEncoders& nodes() const noexcept { return nodes_; }
  /// The simulated nodes, e.g. to send them a frame from another master (fault injection).
  SimCanEncoders& nodes() noexcept { return nodes_; }
  /// Counters so far; `driveCounterWraps` is taken from the nodes.
  CanBusCounters counters() const noexcept;

 private:
  bool deliver(const drivers::CanFrame& frame, bool toDecoder);
  void step(const hal::EncoderSample& measurement);

  hal::EncoderSource& measurements_;
  SimCanEncoders nodes_;
  drivers::canopen::CanopenEncoders decoder_;
  FrameFilter filter_;
  bool started_ = false;
  hal::EncoderSample lastSent_{};
  CanBusCounters counters_{};
};

}  // namespace agv::sim
