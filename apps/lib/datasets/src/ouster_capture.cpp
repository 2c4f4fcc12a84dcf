#include "agv/datasets/ouster_capture.hpp"

#include <cmath>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>

namespace agv::datasets {

namespace {
constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

bool readText(const std::string& path, std::string& text, std::string& error) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    error = "cannot open " + path;
    return false;
  }
  text.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return true;
}

bool numberArray(const nlohmann::json& j, const char* name, std::size_t n, std::vector<double>& out,
                 std::string& error) {
  if (!j.contains(name) || !j[name].is_array() || j[name].size() != n) {
    error = std::string(name) + ": missing or not an array of " + std::to_string(n) + " numbers";
    return false;
  }
  out.clear();
  for (const auto& v : j[name]) {
    if (!v.is_number() || !std::isfinite(v.get<double>())) {
      error = std::string(name) + ": not a finite number";
      return false;
    }
    out.push_back(v.get<double>());
  }
  return true;
}

bool countField(const nlohmann::json& j, const char* name, std::uint16_t& out, std::string& error) {
  if (!j.contains(name) || !j[name].is_number_unsigned() || j[name].get<std::uint64_t>() > 65535U) {
    error = std::string("data_format.") + name + ": missing or not a count";
    return false;
  }
  out = static_cast<std::uint16_t>(j[name].get<std::uint64_t>());
  return true;
}
}  // namespace

bool parseOusterMetadata(const std::string& text, OusterMetadata& out, std::string& error) {
  using drivers::ouster::Profile;
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object()) {
    error = "not a JSON object";
    return false;
  }
  out = OusterMetadata{};
  if (j.contains("prod_line") && j["prod_line"].is_string()) {
    out.prodLine = j["prod_line"].get<std::string>();
  }
  if (j.contains("lidar_mode") && j["lidar_mode"].is_string()) {
    out.lidarMode = j["lidar_mode"].get<std::string>();
  }
  if (!j.contains("data_format") || !j["data_format"].is_object()) {
    error = "data_format: missing";
    return false;
  }
  const nlohmann::json& df = j["data_format"];
  out.profileName = "LEGACY";
  if (df.contains("udp_profile_lidar")) {
    if (!df["udp_profile_lidar"].is_string()) {
      error = "data_format.udp_profile_lidar: not a string";
      return false;
    }
    out.profileName = df["udp_profile_lidar"].get<std::string>();
  }
  if (out.profileName == "LEGACY") {
    out.format.profile = Profile::Legacy;
  } else if (out.profileName == "RNG19_RFL8_SIG16_NIR16") {
    out.format.profile = Profile::Rng19Rfl8Sig16Nir16;
  } else if (out.profileName == "RNG19_RFL8_SIG16_NIR16_DUAL") {
    out.format.profile = Profile::Rng19Rfl8Sig16Nir16Dual;
  } else if (out.profileName == "RNG15_RFL8_NIR8") {
    out.format.profile = Profile::Rng15Rfl8Nir8;
  } else {
    error = "data_format.udp_profile_lidar: unsupported profile " + out.profileName;
    return false;
  }
  if (!countField(df, "columns_per_packet", out.format.columnsPerPacket, error) ||
      !countField(df, "pixels_per_column", out.format.pixelsPerColumn, error) ||
      !countField(df, "columns_per_frame", out.format.columnsPerFrame, error)) {
    return false;
  }
  if (drivers::ouster::validate(out.format) != Status::Ok) {
    error = "data_format: counts beyond the decoder's capacities";
    return false;
  }
  const std::size_t h = out.format.pixelsPerColumn;
  std::vector<double> alt;
  std::vector<double> az;
  std::vector<double> shift;
  if (!numberArray(j, "beam_altitude_angles", h, alt, error) || !numberArray(j, "beam_azimuth_angles", h, az, error) ||
      !numberArray(df, "pixel_shift_by_row", h, shift, error)) {
    return false;
  }
  drivers::ouster::OusterIntrinsics& in = out.intrinsics;
  in.beams = static_cast<std::uint16_t>(h);
  in.columnsPerFrame = out.format.columnsPerFrame;
  for (std::size_t i = 0; i < h; ++i) {
    in.altitudeRad[i] = static_cast<float>(alt[i] * kDegToRad);
    in.azimuthRad[i] = static_cast<float>(az[i] * kDegToRad);
    if (std::fabs(shift[i]) > out.format.columnsPerFrame) {
      error = "data_format.pixel_shift_by_row: shift beyond the frame";
      return false;
    }
    in.pixelShift[i] = static_cast<std::int16_t>(shift[i]);
  }
  if (!j.contains("lidar_origin_to_beam_origin_mm") || !j["lidar_origin_to_beam_origin_mm"].is_number()) {
    error = "lidar_origin_to_beam_origin_mm: missing";
    return false;
  }
  in.beamOriginM = static_cast<float>(j["lidar_origin_to_beam_origin_mm"].get<double>() / 1000.0);
  std::vector<double> t;
  if (!numberArray(j, "lidar_to_sensor_transform", 16, t, error)) {
    return false;
  }
  for (std::size_t k = 0; k < 16; ++k) {
    const bool translation = k == 3 || k == 7 || k == 11;
    in.lidarToSensor[k] = static_cast<float>(translation ? t[k] / 1000.0 : t[k]);
  }
  if (j.contains("beam_to_lidar_transform")) {
    std::vector<double> b;
    if (!numberArray(j, "beam_to_lidar_transform", 16, b, error)) {
      return false;
    }
    // Newer metadata: n from the beam origin's x and z offsets, z offset of the beam origin.
    in.beamOriginM = static_cast<float>(std::hypot(b[3], b[11]) / 1000.0);
    in.beamZOffsetM = static_cast<float>(b[11] / 1000.0);
  }
  if (j.contains("udp_port_lidar") && j["udp_port_lidar"].is_number_unsigned()) {
    out.udpPortLidar = static_cast<std::uint16_t>(j["udp_port_lidar"].get<std::uint64_t>());
  }
  return true;
}

bool readOusterMetadata(const std::string& path, OusterMetadata& out, std::string& error) {
  std::string text;
  if (!readText(path, text, error)) {
    return false;
  }
  if (!parseOusterMetadata(text, out, error)) {
    error = path + ": " + error;
    return false;
  }
  return true;
}

bool readPcapUdp(const std::string& path, std::uint16_t port, std::vector<std::vector<std::uint8_t>>& payloads,
                 PcapStats& stats, std::string& error) {
  payloads.clear();
  stats = PcapStats{};
  std::string bytes;
  if (!readText(path, bytes, error)) {
    return false;
  }
  const auto* b = reinterpret_cast<const std::uint8_t*>(bytes.data());
  const std::size_t size = bytes.size();
  if (size < 24) {
    error = path + ": shorter than a pcap header";
    return false;
  }
  const std::uint32_t magicLe = b[0] | (b[1] << 8U) | (b[2] << 16U) | (static_cast<std::uint32_t>(b[3]) << 24U);
  bool swap = false;
  if (magicLe == 0xA1B2C3D4U || magicLe == 0xA1B23C4DU) {
    swap = false;
  } else if (magicLe == 0xD4C3B2A1U || magicLe == 0x4D3CB2A1U) {
    swap = true;
  } else {
    error = path + ": not a classic pcap file (magic)";
    return false;
  }
  auto u32 = [&](std::size_t o) {
    return swap ? (static_cast<std::uint32_t>(b[o]) << 24U) | (b[o + 1] << 16U) | (b[o + 2] << 8U) | b[o + 3]
                : b[o] | (b[o + 1] << 8U) | (b[o + 2] << 16U) | (static_cast<std::uint32_t>(b[o + 3]) << 24U);
  };
  auto be16 = [&](std::size_t o) { return static_cast<std::uint16_t>((b[o] << 8U) | b[o + 1]); };
  if (u32(20) != 1U) {
    error = path + ": link type " + std::to_string(u32(20)) + " is not Ethernet";
    return false;
  }
  std::size_t off = 24;
  while (off < size) {
    if (off + 16 > size) {
      error = path + ": record header past the end of the file";
      return false;
    }
    const std::uint32_t incl = u32(off + 8);
    off += 16;
    if (incl > size - off) {
      error = path + ": record past the end of the file";
      return false;
    }
    ++stats.records;
    const std::size_t rec = off;
    off += incl;
    std::size_t e = rec + 12;
    if (incl < 14) {
      ++stats.truncated;
      continue;
    }
    std::uint16_t type = be16(e);
    if (type == 0x8100U && incl >= 18) {
      e += 4;
      type = be16(e);
    }
    const std::size_t ip = e + 2;
    if (type != 0x0800U || ip + 20 > rec + incl || (b[ip] >> 4U) != 4U) {
      ++stats.notUdp;
      continue;
    }
    const std::size_t ihl = static_cast<std::size_t>(b[ip] & 0x0FU) * 4U;
    const std::uint16_t frag = be16(ip + 6);
    if (b[ip + 9] != 17U || ihl < 20 || (frag & 0x3FFFU) != 0U) {
      ++stats.notUdp;
      continue;
    }
    const std::size_t udp = ip + ihl;
    if (udp + 8 > rec + incl) {
      ++stats.truncated;
      continue;
    }
    const std::uint16_t dport = be16(udp + 2);
    const std::uint16_t ulen = be16(udp + 4);
    if (ulen < 8 || udp + ulen > rec + incl) {
      ++stats.truncated;
      continue;
    }
    if (dport != port) {
      ++stats.otherPort;
      continue;
    }
    ++stats.matched;
    payloads.emplace_back(b + udp + 8, b + udp + ulen);
  }
  return true;
}

}  // namespace agv::datasets
