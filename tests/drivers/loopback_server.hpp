#pragma once
// The scripted TCP peer of the transport and vehicle tests, shared with agvnav-sim-drives.
#include "agv/drivers/linux/loopback_server.hpp"

namespace agv::test {
using drivers::closedPort;
using drivers::LoopbackServer;
}  // namespace agv::test
