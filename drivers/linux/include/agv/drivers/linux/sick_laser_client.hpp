#pragma once
/// @file sick_laser_client.hpp
/// SICK laser drivers over TCP: CoLa A scan stream (LMS1xx/5xx/TiM) and NAV350 pose requests
/// (binary CoLa). Each owns a `TcpStream` (bounded waits, rate-limited reconnection) and a
/// `TelegramFramer`; decoding is the portable code of agv::drivers_protocol.

#include <cstdint>

#include "agv/drivers/linux/tcp_stream.hpp"
#include "agv/drivers/protocol/sick/cola_a_scan.hpp"
#include "agv/drivers/protocol/sick/nav350.hpp"
#include "agv/drivers/protocol/sick/telegram_framer.hpp"

namespace agv::drivers {

/// Counters of a laser client (the framer's and the socket's are available separately).
struct LaserClientCounters {
  std::uint32_t decoded = 0;         ///< scans / replies delivered
  std::uint32_t decodeErrors = 0;    ///< telegrams of the expected kind that failed to decode
  std::uint32_t implausible = 0;     ///< of those, refused for an implausible scan header (OutOfRange)
  std::uint32_t otherTelegrams = 0;  ///< telegrams of another kind (acknowledgements, events), ignored
};

/// Configuration of the CoLa A scan client.
struct ColaAScanClientConfig {
  TcpStreamConfig tcp;  ///< default port 2111
  sick::ColaAScanConfig scan;
  /// true: send `sEN LMDscandata 1` after each connection and receive the `sSN` stream;
  /// false: poll each scan with `sRN LMDscandata` (answered by `sRA`).
  bool subscribe = true;
};

/// LMS1xx/5xx/TiM scan stream over CoLa A.
class ColaAScanClient {
 public:
  explicit ColaAScanClient(const ColaAScanClientConfig& config) noexcept;

  /// Waits at most `timeout` for the next scan, (re)connecting as needed. Ok (or
  /// CapacityExceeded: more beams than kMaxScanBeams, the first kept) with `scan` filled; Timeout;
  /// Lost when the device cannot be reached within the timeout (retried on the next call).
  Status receive(LaserScan& scan, Duration timeout) noexcept;

  /// Non-blocking variant for a polling loop: returns a scan already received, else reads what the
  /// socket holds without waiting. When not connected and an attempt is due (`reconnectInterval`),
  /// connects (waiting at most `connectBudget`) and subscribes or polls again. Ok/CapacityExceeded
  /// with `scan` filled; Timeout when no complete scan is there yet; Lost when not connected.
  Status poll(LaserScan& scan, Duration connectBudget) noexcept;

  /// Closes the connection (the next call reconnects when the interval allows and subscribes again).
  void disconnect() noexcept;
  bool connected() const noexcept { return tcp_.connected(); }

  const LaserClientCounters& counters() const noexcept { return counters_; }
  const sick::FramerCounters& framerCounters() const noexcept { return framer_.counters(); }
  const TcpStreamCounters& tcpCounters() const noexcept { return tcp_.counters(); }
  /// The connection's socket (-1 when not connected), to wait on; valid until the next call.
  int fileDescriptor() const noexcept { return tcp_.fileDescriptor(); }
  const sick::ColaAScanInfo& lastInfo() const noexcept { return info_; }

 private:
  Status sendCommand(const char* command, Duration timeout) noexcept;
  bool decodeBuffered(LaserScan& scan, Status& result) noexcept;

  ColaAScanClientConfig config_;
  TcpStream tcp_;
  sick::TelegramFramer framer_{sick::Framing::ColaA};
  sick::ColaAScanInfo info_{};
  LaserClientCounters counters_{};
  bool pollRequested_ = false;  ///< poll(): an `sRN LMDscandata` is outstanding (polling mode)
};

/// Configuration of the NAV350 client.
struct Nav350ClientConfig {
  Nav350ClientConfig() noexcept { tcp.port = 2112; }
  TcpStreamConfig tcp;  ///< default port 2112 (binary CoLa)
  sick::Nav350Config nav;
};

/// NAV350 pose/reflector/scan requests over binary CoLa.
class Nav350Client {
 public:
  explicit Nav350Client(const Nav350ClientConfig& config) noexcept;

  /// Sends `sMN mNPOSGetData <wait> <mask>` and waits at most `timeout` for the reply.
  /// Ok / CapacityExceeded with `reply` filled (check reply.errorCode); Timeout; Lost.
  Status requestPose(bool waitForNextScan, sick::Nav350Mask mask, sick::Nav350PoseReply& reply,
                     Duration timeout) noexcept;

  /// Non-blocking variant for a polling loop: sends the request when none is outstanding, returns
  /// the reply once it is there, else reads what the socket holds without waiting. Connection as
  /// `ColaAScanClient::poll`. Ok/CapacityExceeded with `reply`; Timeout; Lost.
  Status poll(bool waitForNextScan, sick::Nav350Mask mask, sick::Nav350PoseReply& reply,
              Duration connectBudget) noexcept;

  /// Closes the connection (an outstanding request is forgotten).
  void disconnect() noexcept;
  bool connected() const noexcept { return tcp_.connected(); }

  const LaserClientCounters& counters() const noexcept { return counters_; }
  const sick::FramerCounters& framerCounters() const noexcept { return framer_.counters(); }
  const TcpStreamCounters& tcpCounters() const noexcept { return tcp_.counters(); }
  /// The connection's socket (-1 when not connected), to wait on; valid until the next call.
  int fileDescriptor() const noexcept { return tcp_.fileDescriptor(); }

 private:
  bool decodeBuffered(sick::Nav350PoseReply& reply, Status& result) noexcept;

  Nav350ClientConfig config_;
  TcpStream tcp_;
  sick::TelegramFramer framer_{sick::Framing::ColaB};
  LaserClientCounters counters_{};
  bool pollRequested_ = false;  ///< poll(): a request is outstanding
};

}  // namespace agv::drivers
