#pragma once
/// @file vcan_peer.hpp
/// Helpers for tests that run inside the vcan VM (run-vcan-vm.sh): the interfaces the VM created
/// and can-utils (cansend, cangen, candump are on PATH there) as the peer on the bus.
///
/// Any Catch2 test linked into test_vcan_socketcan runs in the VM; a driver test adds its source
/// with target_sources(test_vcan_socketcan PRIVATE ...).

#include <initializer_list>
#include <string>

#include "agv/core/timestamp.hpp"

namespace agv::test {

/// The interface the bus monitor (candump -L) records: $AGV_VCAN_IF, default vcan0.
std::string vcanInterface();
/// A second interface that tests may take down and up: $AGV_VCAN_IF2, default vcan1.
std::string vcanSpareInterface();

/// Runs a program (looked up on PATH) with `args` and waits for it. Returns its exit status, or
/// -1 when it could not be started or did not exit normally.
int runPeer(std::initializer_list<std::string> args);

/// `cansend <interface> <frame>` (frame in cansend's syntax, e.g. "181#0102", "12345678#AA",
/// "701#R", error frames as 8 hex digits with 0x20000000 set). The tool is $AGV_CANSEND or cansend.
/// Returns its exit status. The frame is queued at every receiving socket when this returns.
int cansend(const std::string& interface, const std::string& frame);

/// Sets or clears IFF_UP of an interface (needs CAP_NET_ADMIN: root in the VM).
bool setLinkUp(const std::string& interface, bool up);

/// CLOCK_REALTIME now.
Timestamp realtimeNow();

}  // namespace agv::test
