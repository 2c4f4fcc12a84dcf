#pragma once
/// @file modbus_plc_link.hpp
/// The PLC link over Modbus TCP (libmodbus): the vehicle either serves its register map to a
/// polling PLC (role Server) or writes its status into the PLC and reads the PLC's command
/// registers (role Client). Register map and checks: agv/drivers/protocol/plc/plc_register_map.hpp and
/// docs/plc-link.md.
///
/// Cycle budget: `cycle()` never blocks longer than the budget it is given, in both roles (the
/// client's connect, write and read are a non-blocking state machine carried over cycles, each
/// step bounded by `responseTimeout`). Server: every socket is non-blocking; a request
/// is assembled across cycles (agv/drivers/protocol/plc/modbus_request.hpp) and must be whole within
/// `responseTimeout` of its first byte; a reply that does not fit in the peer's send buffer drops
/// the peer; peers silent for `idleTimeout` are dropped; a new connection when every slot is taken
/// evicts a peer that never sent a well-formed request of the map, else the longest-silent peer silent for
/// `evictSilentAfter`, else it is refused; `allowedPeers` restricts the addresses accepted
/// (docs/plc-link.md, "Connection policy"). A lost PLC is retried at most once per
/// `reconnectInterval`, with one connection attempt bounded by `responseTimeout`; in between, the
/// cycle returns Lost at once, so the localization cycle goes on.

#include <array>
#include <cstdint>

#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/drivers/protocol/plc/modbus_request.hpp"
#include "agv/drivers/protocol/plc/plc_register_map.hpp"
#include "agv/hal/plc_link.hpp"

struct _modbus;  // libmodbus context (modbus_t)

namespace agv::drivers {

/// Which side of the Modbus exchange the vehicle is.
enum class PlcLinkRole : std::uint8_t {
  Server,  ///< the PLC polls the vehicle (Modbus TCP server on `port`)
  Client,  ///< the vehicle writes to the PLC (Modbus TCP client to `address:port`)
};

struct ModbusPlcLinkConfig {
  PlcLinkRole role = PlcLinkRole::Server;
  char address[64] = "0.0.0.0";           ///< server: address to bind; client: the PLC's IPv4 address
  std::uint16_t port = 502;               ///< server: 0 picks a free port (see boundPort())
  plc::PlcMapConfig map;                  ///< word order, set-pose bounds
  std::uint16_t remoteStatusBase = 0;     ///< client: PLC holding register receiving the status block
  std::uint16_t remoteCommandBase = 100;  ///< client: PLC holding register of the command block
  bool clientReadsCommands = true;        ///< client: read the command block every cycle
  Duration responseTimeout = Duration::fromMilliseconds(50);  ///< one request / connect attempt
  Duration reconnectInterval = Duration::fromMilliseconds(1000);
  Duration plcHeartbeatTimeout =
      Duration::fromMilliseconds(1000);  ///< PLC heartbeat register unchanged this long = lost
  int maxConnections = 4;                ///< server: simultaneous PLC connections (see the policy above)
  /// server: a connection with no well-formed request of the map (03, 06, 16, 23) for this long is
  /// closed (refused and discarded requests do not count).
  Duration idleTimeout = Duration::fromSeconds(10.0);
  /// server, all slots taken: a peer that completed requests may be evicted for a new connection
  /// only after this long without one (a PLC polling faster keeps its slot).
  Duration evictSilentAfter = Duration::fromSeconds(1.0);
  /// server: IPv4 addresses (network byte order) allowed to connect; none = any address.
  std::array<std::uint32_t, 4> allowedPeers{};
  int allowedPeerCount = 0;
  /// hal::PlcLink::publish(): how long one publication may serve requests (server role). 0 =
  /// answer what is pending and return at once (the HAL's "never blocks").
  Duration publishBudget = Duration{};
};

struct PlcLinkCounters {
  std::uint32_t requests = 0;        ///< server: requests answered; client: requests sent
  std::uint32_t rejectedWrites = 0;  ///< server: writes refused (exception); client: command blocks out of bounds
  std::uint32_t commands = 0;        ///< new commands accepted (sequence register changed)
  std::uint32_t connects = 0;
  std::uint32_t disconnects = 0;
  std::uint32_t connectFailures = 0;  ///< client attempts failed; server connections refused (full)
  std::uint32_t requestErrors = 0;    ///< failed exchanges (timeouts, broken connections)
  /// server: requests refused before the map: not Modbus (MBAP protocol id not 0: discarded) or a
  /// function code the map does not serve (exception 01)
  std::uint32_t refusedRequests = 0;
  std::uint32_t requestTimeouts = 0;  ///< server: peers dropped with a request not whole within responseTimeout
  std::uint32_t idleTimeouts = 0;     ///< server: peers dropped after idleTimeout without a request of the map
  std::uint32_t evictions = 0;        ///< server: peers closed to make room for a new connection
  std::uint32_t refusedPeers = 0;     ///< server: connections from an address not in allowedPeers
  std::uint32_t sendFailures = 0;     ///< server: peers dropped because a reply did not fit their send buffer
};

/// Also the HAL's `hal::PlcLink` (publish a `hal::PoseReport`, read `hal::PlcCommand`s).
class ModbusPlcLink final : public hal::PlcLink {
 public:
  explicit ModbusPlcLink(const ModbusPlcLinkConfig& config) noexcept;
  ~ModbusPlcLink();
  ModbusPlcLink(const ModbusPlcLink&) = delete;
  ModbusPlcLink& operator=(const ModbusPlcLink&) = delete;

  /// Server: creates the context and listens (InvalidArgument bad address, Lost bind failure).
  /// Client: creates the context (the connection is made by cycle()).
  Status open() noexcept;
  /// Server: the listening port (useful with port 0).
  std::uint16_t boundPort() const noexcept { return boundPort_; }

  /// One PLC-link cycle at vehicle time `now`: publishes `status` (the link ORs in its own health
  /// bits PlcHeartbeatLost and CommandRejected), then serves requests for at most `budget`
  /// (server) or writes the status and reads the commands (client). Ok; Lost (client: PLC not
  /// reachable, retried later); NotInitialized (open() not called or failed).
  Status cycle(const plc::PlcStatus& status, Timestamp now, Duration budget) noexcept;
  /// Server: answers the requests pending now (and accepts connections) without waiting and
  /// without a new status: the registers keep the last published one. Lets a loop answer the PLC
  /// every cycle while it publishes less often. Client: carries on an exchange in flight (takes a
  /// reply that arrived, sends the command read), without starting a new one or reconnecting;
  /// Lost when not connected. NotInitialized before open().
  Status service(Timestamp now) noexcept;

  /// hal::PlcLink: publishes `report` (heartbeat counted here; health bits `report.health.bits`
  /// ORed with the link's own; calibration from setCalibration()) with one cycle of
  /// `publishBudget` on the monotonic clock.
  /// Ok; Timeout when the PLC cannot be reached (client role; retried later); NotInitialized.
  Status publish(const hal::PoseReport& report) noexcept override;
  /// hal::PlcLink: the newest new command (Localize with its initial pose, Calibrate, Stop);
  /// NotFound when there is none.
  Status readCommand(hal::PlcCommand& out) noexcept override;
  /// Calibration values published with the next reports.
  void setCalibration(const plc::PlcCalibration& calibration) noexcept { calibration_ = calibration; }

  /// A new command (its sequence register changed) since the last call: copies it and returns true.
  bool takeCommand(plc::PlcCommand& command) noexcept;
  /// True while the PLC's heartbeat register changed within plcHeartbeatTimeout.
  bool plcAlive() const noexcept { return plcAlive_; }
  bool connected() const noexcept;
  /// Server: the descriptors to wait on for input (the listening socket and the connections), at
  /// most `capacity` of them into `out`; returns how many. Client: the connection while a reply is
  /// awaited. Valid until the next cycle.
  int inputDescriptors(int* out, int capacity) const noexcept;

  const PlcLinkCounters& counters() const noexcept { return counters_; }

 private:
  static constexpr int kMaxClients = 8;
  /// One server connection: its socket and the request being assembled.
  struct Peer {
    int fd = -1;
    plc::MbapRequestFramer framer;
    Timestamp accepted{};
    Timestamp lastRequest{};  ///< last well-formed request of the map (or the accept)
    Timestamp firstByte{};    ///< first byte of the request being assembled
    bool served = false;      ///< sent at least one well-formed request of the map (03, 06, 16, 23)
  };
  Status serve(Timestamp now, Duration budget) noexcept;
  Status exchange(Timestamp now, Duration budget, bool startNew) noexcept;
  Status startConnect(Timestamp now) noexcept;
  bool sendClientRequest(std::size_t length, Timestamp now) noexcept;
  /// Closes the client connection (counted as a disconnect when it was up); returns Lost.
  Status failClient() noexcept;
  void acceptPeers(Timestamp now) noexcept;
  bool peerAllowed(std::uint32_t address) const noexcept;
  /// Reads what the socket holds for the current request; false when the peer must be dropped.
  bool readPeer(Peer& p, Timestamp now) noexcept;
  /// Answers the complete request of `p`; false when the peer must be dropped.
  bool handleRequest(Peer& p, Timestamp now) noexcept;
  bool sendAll(int fd, const std::uint8_t* data, std::size_t n) noexcept;
  void acceptCommand(const plc::PlcCommand& c, Timestamp now) noexcept;
  void closeClient(int index) noexcept;

  ModbusPlcLinkConfig config_;
  plc::PlcRegisterMap map_;
  _modbus* ctx_ = nullptr;
  void* mapping_ = nullptr;  // modbus_mapping_t*
  int listenFd_ = -1;
  std::array<Peer, kMaxClients> clients_{};
  bool clientConnected_ = false;
  /// Client: where the exchange with the PLC stands (carried over cycles).
  enum class ClientPhase : std::uint8_t { Idle, Connecting, AwaitWrite, AwaitRead };
  ClientPhase phase_ = ClientPhase::Idle;
  int clientFd_ = -1;
  Timestamp phaseDeadline_{};  ///< connect or reply due by then (responseTimeout)
  std::uint16_t transaction_ = 0;
  plc::MbapRequestFramer clientFramer_;
  std::array<std::uint8_t, plc::kMaxModbusAdu> clientRequest_{};
  std::uint16_t boundPort_ = 0;
  Timestamp nextAttempt_{};
  std::array<std::uint16_t, plc::PlcRegisterMap::kRegisterCount> table_{};  // client: last published + read
  bool haveCommand_ = false;
  bool newCommand_ = false;
  plc::PlcCommand command_{};
  std::uint16_t lastSequence_ = 0;
  bool sequenceSeen_ = false;
  std::uint16_t lastPlcHeartbeat_ = 0;
  Timestamp lastPlcHeartbeatChange_{};
  bool heartbeatSeen_ = false;
  bool plcAlive_ = false;
  bool lastRejected_ = false;
  Timestamp commandStamp_{};
  std::uint16_t publishCount_ = 0;
  plc::PlcCalibration calibration_{};
  PlcLinkCounters counters_{};
};

}  // namespace agv::drivers
