// Reader of ROS 2 bags (rosbag2, sqlite3 storage) of velodyne_msgs/msg/VelodyneScan messages.
#include <cstring>
#include <string>

#include "agv/datasets/velodyne_recording.hpp"

#if AGV_DATASETS_HAVE_SQLITE
#include <sqlite3.h>
#endif

namespace agv::datasets {

namespace {

constexpr std::size_t kPayloadBytes = 1206;  // velodyne_msgs/VelodynePacket: uint8[1206] data
constexpr char kScanType[] = "velodyne_msgs/msg/VelodyneScan";

/// Little-endian CDR reader over one message (offsets relative to the body after the 4-byte
/// encapsulation header, as CDR aligns them).
class Cdr {
 public:
  Cdr(const std::uint8_t* body, std::size_t size) : body_(body), size_(size) {}
  bool align(std::size_t a) {
    pos_ = (pos_ + a - 1) / a * a;
    return pos_ <= size_;
  }
  template <typename T>
  bool read(T& v) {
    if (!align(sizeof(T)) || size_ - pos_ < sizeof(T)) {
      return false;
    }
    std::memcpy(&v, body_ + pos_, sizeof(T));  // the host is little-endian (x86-64, aarch64, armhf)
    pos_ += sizeof(T);
    return true;
  }
  const std::uint8_t* take(std::size_t n) {
    if (size_ - pos_ < n) {
      return nullptr;
    }
    const std::uint8_t* p = body_ + pos_;
    pos_ += n;
    return p;
  }

 private:
  const std::uint8_t* body_;
  std::size_t size_;
  std::size_t pos_ = 0;
};

/// One message's CDR bytes: header fields into `msg`, payloads appended to `rec`.
bool parseScan(const std::uint8_t* data, std::size_t size, VelodyneScanMessage& msg, PacketRecording& rec,
               std::string& error) {
  if (size < 4 || data[0] != 0x00 || data[1] != 0x01) {
    error = size < 4 ? "shorter than its CDR header"
                     : "not little-endian CDR (encapsulation " +
                           std::to_string(size < 2 ? 0 : data[0] * 256 + data[1]) + ")";
    return false;
  }
  Cdr cdr(data + 4, size - 4);
  std::uint32_t frameLength = 0;
  if (!cdr.read(msg.stampSec) || !cdr.read(msg.stampNanosec) || !cdr.read(frameLength)) {
    error = "truncated header";
    return false;
  }
  const std::uint8_t* frame = cdr.take(frameLength);
  if (frame == nullptr || frameLength == 0 || frame[frameLength - 1] != 0) {
    error = "bad frame_id";
    return false;
  }
  msg.frameId.assign(reinterpret_cast<const char*>(frame), frameLength - 1);
  std::uint32_t count = 0;
  if (!cdr.read(count)) {
    error = "truncated packet count";
    return false;
  }
  msg.firstPacket = rec.packets;
  msg.packetCount = count;
  for (std::uint32_t k = 0; k < count; ++k) {
    std::int32_t sec = 0;
    std::uint32_t nanosec = 0;
    const bool stamp = cdr.read(sec) && cdr.read(nanosec);
    const std::uint8_t* payload = stamp ? cdr.take(kPayloadBytes) : nullptr;
    if (payload == nullptr) {
      error = "packet " + std::to_string(k) + " of " + std::to_string(count) + " truncated (" + std::to_string(size) +
              " bytes)";
      return false;
    }
    rec.bytes.insert(rec.bytes.end(), payload, payload + kPayloadBytes);
    ++rec.packets;
  }
  return true;
}

}  // namespace

#if AGV_DATASETS_HAVE_SQLITE

bool readVelodyneScanBag(const std::string& path, VelodyneScanBag& out, std::string& error) {
  out = VelodyneScanBag{};
  out.packets.packetBytes = kPayloadBytes;
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
    error = path + ": cannot open as SQLite (" + (db != nullptr ? sqlite3_errmsg(db) : "no memory") + ")";
    sqlite3_close(db);
    return false;
  }
  bool ok = true;
  sqlite3_stmt* st = nullptr;
  // The topic: exactly one of type VelodyneScan. (A file that is not SQLite fails here.)
  std::int64_t topicId = -1;
  int topics = 0;
  if (sqlite3_prepare_v2(db, "select id, name from topics where type = ?", -1, &st, nullptr) != SQLITE_OK) {
    error = path + ": not a rosbag2 file (" + sqlite3_errmsg(db) + ")";
    ok = false;
  } else {
    sqlite3_bind_text(st, 1, kScanType, -1, SQLITE_STATIC);
    while (sqlite3_step(st) == SQLITE_ROW) {
      ++topics;
      topicId = sqlite3_column_int64(st, 0);
      const unsigned char* name = sqlite3_column_text(st, 1);
      out.topic = name != nullptr ? reinterpret_cast<const char*>(name) : "";
    }
    if (topics != 1) {
      error = path + ": " + std::to_string(topics) + " topics of type " + kScanType + " (one expected)";
      ok = false;
    }
  }
  sqlite3_finalize(st);
  st = nullptr;
  if (ok && sqlite3_prepare_v2(db, "select timestamp, data from messages where topic_id = ? order by timestamp", -1,
                               &st, nullptr) != SQLITE_OK) {
    error = path + ": " + sqlite3_errmsg(db);
    ok = false;
  }
  if (ok) {
    sqlite3_bind_int64(st, 1, topicId);
    int rc = SQLITE_ROW;
    while (ok && (rc = sqlite3_step(st)) == SQLITE_ROW) {
      VelodyneScanMessage msg;
      msg.bagTimeNs = sqlite3_column_int64(st, 0);
      const auto* data = static_cast<const std::uint8_t*>(sqlite3_column_blob(st, 1));
      const auto size = static_cast<std::size_t>(sqlite3_column_bytes(st, 1));
      std::string why;
      if (data == nullptr || !parseScan(data, size, msg, out.packets, why)) {
        error = path + ": message " + std::to_string(out.messages.size()) + ": " + (data == nullptr ? "empty" : why);
        ok = false;
        break;
      }
      out.messages.push_back(msg);
    }
    if (ok && rc != SQLITE_DONE) {
      error = path + ": " + sqlite3_errmsg(db);
      ok = false;
    }
  }
  sqlite3_finalize(st);
  sqlite3_close(db);
  if (ok && out.packets.packets == 0) {
    error = path + ": no packet in " + std::to_string(out.messages.size()) + " VelodyneScan messages";
    ok = false;
  }
  if (!ok) {
    out = VelodyneScanBag{};
  }
  return ok;
}

#else

bool readVelodyneScanBag(const std::string& path, VelodyneScanBag& out, std::string& error) {
  out = VelodyneScanBag{};
  error = path + ": this build has no SQLite (install libsqlite3-dev and reconfigure) to read ROS 2 bags";
  return false;
}

#endif

}  // namespace agv::datasets
