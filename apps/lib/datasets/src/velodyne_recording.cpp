#include "agv/datasets/velodyne_recording.hpp"

#include <fstream>
#include <iterator>

namespace agv::datasets {

bool readPacketRecording(const std::string& path, std::size_t packetBytes, PacketRecording& out, std::string& error) {
  out = PacketRecording{};
  if (packetBytes == 0) {
    error = "packet size 0";
    return false;
  }
  std::ifstream f(path, std::ios::binary);
  if (!f) {
    error = path + ": cannot open";
    return false;
  }
  out.bytes.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  if (out.bytes.empty()) {
    error = path + ": empty";
    return false;
  }
  if (out.bytes.size() % packetBytes != 0) {
    error = path + ": " + std::to_string(out.bytes.size()) + " bytes are not a whole number of " +
            std::to_string(packetBytes) + "-byte packets (not a file of concatenated raw payloads)";
    out.bytes.clear();
    return false;
  }
  out.packetBytes = packetBytes;
  out.packets = out.bytes.size() / packetBytes;
  return true;
}

}  // namespace agv::datasets
