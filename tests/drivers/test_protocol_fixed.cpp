// The portable protocol decoders on fixed telegrams written out byte by byte from the documented
// layouts (docs/drivers.md), each with its decoded values worked out by hand: the telegram framer
// (CoLa A and CoLa B streams cut at awkward places, with noise), a CoLa A LMDscandata (LMS1xx
// header fields of SICK's telegram listing, five beams), a NAV350 mNPOSGetData request and reply
// (pose, two reflectors, a three-beam scan) and the PLC register map's word orders and blocks.
// Heap-free test code: also runs in the Cortex-M7 image (MCU), so only the portable subset of
// agv_test.hpp, and every large object is static (64 KiB stack there).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "agv/core/angle.hpp"
#include "agv/drivers/protocol/plc/plc_register_map.hpp"
#include "agv/drivers/protocol/sick/cola_a_scan.hpp"
#include "agv/drivers/protocol/sick/nav350.hpp"
#include "agv/drivers/protocol/sick/telegram_framer.hpp"
#include "agv_test.hpp"

using agv::Duration;
using agv::LaserScan;
using agv::Span;
using agv::Status;
using agv::Timestamp;
using namespace agv::drivers::sick;

namespace {

template <std::size_t N>
Span<const std::uint8_t> textBytes(const char (&s)[N]) {
  return Span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(s), N - 1);  // without the NUL
}

bool sameBytes(Span<const std::uint8_t> a, Span<const std::uint8_t> b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size()) == 0;
}

// CoLa A LMDscandata as an LMS1xx sends it (header values of SICK's telegram listing; the DIST1
// channel shortened to five beams), between STX and ETX:
//   sRA LMDscandata, version 1, device 1, serial 89A27F, status 0 0, telegram counter 343, scan
//   counter 347, time since start-up 27477BA9 us, time of transmission 2747813B us (0x592 = 1426 us
//   later), inputs 0 0, outputs 7 0, reserved 0, scan frequency 1388 (5000 = 50 Hz), measurement
//   frequency 168, 0 encoders, 1 16-bit channel: DIST1, scale 3F800000 (1.0f), offset 00000000,
//   start FFF92230 (-450000 = -45 deg), step 1388 (5000 = 0.5 deg), 5 values: 1C2 (450 mm), 0 (no
//   echo), BB8 (3000 mm), FFFF (65535 mm), 2 (2 mm); 0 8-bit channels; position, name, comment,
//   time, event: 0.
constexpr char kColaAScan[] =
    "sRA LMDscandata 1 1 89A27F 0 0 343 347 27477BA9 2747813B 0 0 7 0 0 1388 168 0 1 DIST1 3F800000 00000000 "
    "FFF92230 1388 5 1C2 0 BB8 FFFF 2 0 0 0 0 0 0";

// The same scan as an LMS5xx stream telegram: RSSI1 in the 16-bit list, DIST1 in the 8-bit list
// with scale 40000000 (2.0f) and offset 40E00000 (7.0f mm): 100 -> 207 mm, 5DC -> 3007 mm.
constexpr char kColaAScan5xx[] =
    "sSN LMDscandata 1 1 10B2C3 0 0 1 2 100 200 0 0 0 0 0 9C4 168 1 0 0 1 RSSI1 3F800000 00000000 "
    "FFFF3CB0 683 2 FE FE 1 DIST1 40000000 40E00000 FFFF3CB0 683 2 64 5DC 0 0 0 0 0";

// NAV350 reply `sAN mNPOSGetData` (binary CoLa payload, big-endian), 158 bytes.
constexpr std::uint8_t kNavReply[] = {
    's',  'A',  'N',  ' ',  'm',  'N',  'P',  'O',  'S', 'G', 'e', 't', 'D', 'a', 't', 'a', ' ',  //
    0x00, 0x01,                                                                                   // version 1
    0x00, 0x01, 0x02,                                // error 0, wait 1, mask 2
    0x00, 0x01,                                      // pose valid
    0x00, 0x00, 0x30, 0x39,                          // x 12345 mm
    0xFF, 0xFF, 0xE5, 0x7B,                          // y -6789 mm
    0x00, 0x04, 0x1E, 0xB0,                          // phi 270000 mdeg
    0x00, 0x01,                                      // pose details valid
    0x00,                                            // output mode
    0x00, 0x0F, 0x42, 0x40,                          // timestamp 1000000 ms
    0x00, 0x00, 0x00, 0x0F,                          // mean deviation 15 mm
    0x04,                                            // navigation mode 4
    0x00, 0x00, 0x00, 0x00,                          // info state
    0x03,                                            // used reflectors 3
    0x00, 0x01, 0x01, 0x00, 0x02,                    // landmarks valid, filter 1, 2 reflectors
    0x00, 0x01,                                      // #1 cartesian valid
    0x00, 0x00, 0x13, 0x88, 0xFF, 0xFF, 0xF8, 0x30,  //    x 5000 mm, y -2000 mm
    0x00, 0x01,                                      //    polar valid
    0x00, 0x00, 0x17, 0x70, 0x00, 0x00, 0xD2, 0xF0,  //    6000 mm at 54000 mdeg
    0x00, 0x01,                                      //    details valid
    0x00, 0x07, 0x00, 0x2A, 0x01, 0x00, 0x02,        //    local 7, global 42, type 1, subtype 2
    0x00, 0x64, 0x00, 0x0F, 0x42, 0x38,              //    quality 100, timestamp 999992 ms
    0x00, 0x50, 0x00, 0x0C, 0x00, 0xC8,              //    size 80 mm, hits 12, echo 200
    0x01, 0x2C, 0x01, 0x36,                          //    beams 300..310
    0x00, 0x00,                                      // #2 no cartesian
    0x00, 0x01,                                      //    polar valid
    0x00, 0x00, 0x09, 0xC4, 0x00, 0x05, 0x7E, 0x40,  //    2500 mm at 360000 mdeg
    0x00, 0x00,                                      //    no details
    0x00, 0x01,                                      // 1 scan channel
    'D',  'I',  'S',  'T',  '1',                     //
    0x3F, 0x80, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // scale 1.0f, offset 0.0f
    0xFF, 0xFF, 0x50, 0x38, 0x00, 0xFA,              // start -45000 mdeg, step 250 mdeg
    0x00, 0x0F, 0x42, 0x18, 0x00, 0x03,              // timestamp 999960 ms, 3 values
    0x00, 0x00, 0x0B, 0xB8, 0x00, 0x00, 0x00, 0x00,  // 3000 mm, 0 (no echo)
    0x00, 0x00, 0x13, 0x88,                          // 5000 mm
    0x00, 0x00,                                      // no remission
};
constexpr std::uint8_t kNavReplyChecksum = 0x75;  // XOR of the 158 payload bytes

// The request `sMN mNPOSGetData 1 2` as it goes on the wire (19-byte payload, checksum 0x7A).
constexpr std::uint8_t kNavRequestTelegram[] = {0x02, 0x02, 0x02, 0x02, 0x00, 0x00, 0x00, 0x13,  //
                                                's',  'M',  'N',  ' ',  'm',  'N',  'P',  'O',  'S',  'G',
                                                'e',  't',  'D',  'a',  't',  'a',  ' ',  0x01, 0x02,  //
                                                0x7A};

/// Feeds `data` to the framer in pieces of `chunk` bytes, collecting what it delivers into
/// `copies` (each telegram copied, as the view is only valid until the next call). Returns the
/// number of telegrams.
std::size_t feedInChunks(TelegramFramer& f, Span<const std::uint8_t> data, std::size_t chunk,
                         std::uint8_t (*copies)[512], std::size_t* lengths, std::size_t maxTelegrams) {
  std::size_t got = 0;
  std::size_t pos = 0;
  while (pos < data.size()) {
    const std::size_t n = data.size() - pos < chunk ? data.size() - pos : chunk;
    std::size_t taken = 0;
    while (taken < n) {
      taken += f.feed(Span<const std::uint8_t>(data.data() + pos + taken, n - taken));
      Span<const std::uint8_t> t;
      while (f.next(t)) {
        if (got < maxTelegrams && t.size() <= 512U) {
          std::memcpy(copies[got], t.data(), t.size());
          lengths[got] = t.size();
        }
        ++got;
      }
    }
    pos += n;
  }
  return got;
}

}  // namespace

TEST_CASE("Framer, CoLa A: telegrams between noise, cut at every chunk size", "[drivers][laser][mcu]") {
  // noise, STX telegram ETX, noise, STX telegram ETX
  static std::uint8_t stream[2 * sizeof kColaAScan + 16];
  std::size_t n = 0;
  const char noise[] = "xx";
  for (int k = 0; k < 2; ++k) {
    std::memcpy(stream + n, noise, 2);
    n += 2;
    stream[n++] = 0x02;
    std::memcpy(stream + n, kColaAScan, sizeof kColaAScan - 1);
    n += sizeof kColaAScan - 1;
    stream[n++] = 0x03;
  }
  static std::uint8_t copies[2][512];
  std::size_t lengths[2] = {};
  static TelegramFramer f(Framing::ColaA);  // 32 KiB: static; counters compared as differences
  for (std::size_t chunk : {std::size_t{1}, std::size_t{7}, std::size_t{64}, n}) {
    const FramerCounters before = f.counters();
    REQUIRE(feedInChunks(f, Span<const std::uint8_t>(stream, n), chunk, copies, lengths, 2) == 2U);
    CHECK(sameBytes(Span<const std::uint8_t>(copies[0], lengths[0]), textBytes(kColaAScan)));
    CHECK(sameBytes(Span<const std::uint8_t>(copies[1], lengths[1]), textBytes(kColaAScan)));
    CHECK(f.counters().telegrams - before.telegrams == 2U);
    CHECK(f.counters().garbageBytes - before.garbageBytes == 4U);
    CHECK(f.counters().truncated == before.truncated);
    CHECK(f.buffered() == 0U);
  }
}

TEST_CASE("Framer, CoLa B: the NAV350 reply framed, checksum checked, damaged copy dropped", "[drivers][laser][mcu]") {
  static std::uint8_t telegram[sizeof kNavReply + 9];
  const std::size_t m =
      encodeColaB(Span<const std::uint8_t>(kNavReply, sizeof kNavReply), Span<std::uint8_t>(telegram));
  REQUIRE(m == sizeof kNavReply + 9U);
  CHECK((telegram[0] == 0x02U && telegram[1] == 0x02U && telegram[2] == 0x02U && telegram[3] == 0x02U));
  CHECK((telegram[4] == 0x00U && telegram[5] == 0x00U && telegram[6] == 0x00U && telegram[7] == 0x9EU));  // 158
  CHECK(telegram[m - 1] == kNavReplyChecksum);

  // damaged copy (one payload bit flipped: checksum mismatch), then the good one
  static std::uint8_t stream[2 * (sizeof kNavReply + 9)];
  std::memcpy(stream, telegram, m);
  stream[8 + 40] ^= 0x10U;
  std::memcpy(stream + m, telegram, m);
  static std::uint8_t copies[2][512];
  std::size_t lengths[2] = {};
  static TelegramFramer f(Framing::ColaB);
  for (std::size_t chunk : {std::size_t{1}, std::size_t{5}, std::size_t{100}, 2 * m}) {
    const FramerCounters before = f.counters();
    REQUIRE(feedInChunks(f, Span<const std::uint8_t>(stream, 2 * m), chunk, copies, lengths, 2) == 1U);
    CHECK(sameBytes(Span<const std::uint8_t>(copies[0], lengths[0]),
                    Span<const std::uint8_t>(kNavReply, sizeof kNavReply)));
    CHECK(f.counters().checksumErrors - before.checksumErrors == 1U);
    CHECK(f.counters().telegrams - before.telegrams == 1U);
    CHECK(f.buffered() == 0U);
  }
}

TEST_CASE("CoLa A LMS1xx scan: header fields, angles, ranges, no echo, stamp and sweep", "[drivers][laser][mcu]") {
  static LaserScan scan;
  ColaAScanInfo info;
  const Timestamp at = Timestamp::fromSeconds(100.0);
  REQUIRE(parseColaAScan(textBytes(kColaAScan), ColaAScanConfig{}, at, scan, &info) == Status::Ok);
  CHECK(info.serialNumber == 0x89A27FU);
  CHECK(info.deviceStatus == 0U);
  CHECK(info.telegramCounter == 0x343U);
  CHECK(info.scanCounter == 0x347U);
  CHECK(info.timeSinceStartupUs == 0x27477BA9U);
  CHECK(info.timeOfTransmissionUs == 0x2747813BU);
  AGV_CHECK_NEAR(info.scanFrequency, 50.0, 1e-9);
  AGV_CHECK_NEAR(info.scaleFactor, 1.0, 0.0);
  AGV_CHECK_NEAR(info.scaleOffset, 0.0, 0.0);
  CHECK(info.beamCount == 5U);
  CHECK(info.noReturnBeams == 1U);

  REQUIRE(scan.size() == 5U);
  AGV_CHECK_NEAR(scan.angleMin, agv::deg2rad(-135.0), 1e-6);  // -45 deg device, 0 deg = device y axis
  AGV_CHECK_NEAR(scan.angleIncrement, agv::deg2rad(0.5), 1e-7);
  AGV_CHECK_NEAR(scan.ranges[0], 0.450, 1e-6);
  CHECK(scan.isValid(0));
  CHECK(std::isinf(scan.ranges[1]));
  CHECK_FALSE(scan.isValid(1));
  AGV_CHECK_NEAR(scan.ranges[2], 3.000, 1e-6);
  CHECK(scan.isValid(2));
  AGV_CHECK_NEAR(scan.ranges[3], 65.535, 1e-5);
  CHECK(scan.isValid(3));
  AGV_CHECK_NEAR(scan.ranges[4], 0.002, 1e-7);
  CHECK_FALSE(scan.isValid(4));  // below rangeMin 0.05 m
  CHECK(scan.stamp == at - Duration::fromMicroseconds(1426));
  // 4 steps of 0.5 deg of a 20 ms revolution: 2/360 * 20 ms = 111.1 us
  AGV_CHECK_NEAR(scan.sweepDuration.seconds(), 0.02 * 2.0 / 360.0, 1e-9);
}

TEST_CASE("CoLa A LMS5xx scan: DIST1 in the 8-bit list, scale 2 and offset 7 mm applied", "[drivers][laser][mcu]") {
  static LaserScan scan;
  ColaAScanInfo info;
  REQUIRE(parseColaAScan(textBytes(kColaAScan5xx), ColaAScanConfig{}, Timestamp::fromSeconds(1.0), scan, &info) ==
          Status::Ok);
  REQUIRE(scan.size() == 2U);
  AGV_CHECK_NEAR(info.scanFrequency, 25.0, 1e-9);
  AGV_CHECK_NEAR(info.scaleFactor, 2.0, 0.0);
  AGV_CHECK_NEAR(info.scaleOffset, 7.0, 0.0);
  AGV_CHECK_NEAR(scan.angleMin, agv::deg2rad(-5.0 - 90.0), 1e-6);   // FFFF3CB0 = -50000
  AGV_CHECK_NEAR(scan.angleIncrement, agv::deg2rad(0.1667), 1e-7);  // 683 = 1667
  AGV_CHECK_NEAR(scan.ranges[0], 0.207, 1e-6);
  AGV_CHECK_NEAR(scan.ranges[1], 3.007, 1e-6);
  CHECK(scan.stamp == Timestamp::fromSeconds(1.0) - Duration::fromMicroseconds(0x100));
}

TEST_CASE("CoLa A: cut or damaged telegrams are refused with a reason", "[drivers][laser][mcu]") {
  static LaserScan scan;
  const Span<const std::uint8_t> good = textBytes(kColaAScan);
  // cut inside the DIST1 values, before "BB8"
  const char* cut = std::strstr(kColaAScan, " BB8");
  REQUIRE(cut != nullptr);
  const auto cutLength = static_cast<std::size_t>(cut - kColaAScan);
  CHECK(parseColaAScan(Span<const std::uint8_t>(good.data(), cutLength), ColaAScanConfig{}, Timestamp{}, scan) ==
        Status::Truncated);
  CHECK(scan.size() == 0U);
  static char bad[sizeof kColaAScan];
  std::memcpy(bad, kColaAScan, sizeof kColaAScan);
  bad[1] = 'X';  // "sXA"
  CHECK(parseColaAScan(textBytes(bad), ColaAScanConfig{}, Timestamp{}, scan) == Status::Malformed);
  std::memcpy(bad, kColaAScan, sizeof kColaAScan);
  char* g = std::strstr(bad, "BB8");
  REQUIRE(g != nullptr);
  g[1] = 'Z';  // not a hex digit
  CHECK(parseColaAScan(textBytes(bad), ColaAScanConfig{}, Timestamp{}, scan) == Status::Malformed);
  CHECK(scan.size() == 0U);
}

TEST_CASE("NAV350 request: the exact telegram of sMN mNPOSGetData 1 2", "[drivers][laser][mcu]") {
  std::uint8_t payload[32];
  const std::size_t n = encodeNav350PoseRequest(true, Nav350Mask::PoseReflectorsScan, Span<std::uint8_t>(payload));
  REQUIRE(n == 19U);
  std::uint8_t tel[64];
  const std::size_t m = encodeColaB(Span<const std::uint8_t>(payload, n), Span<std::uint8_t>(tel));
  CHECK(sameBytes(Span<const std::uint8_t>(tel, m),
                  Span<const std::uint8_t>(kNavRequestTelegram, sizeof kNavRequestTelegram)));
}

TEST_CASE("NAV350 reply: pose, reflectors, scan and device times decoded to SI units", "[drivers][laser][mcu]") {
  static Nav350PoseReply r;
  const Timestamp at = Timestamp::fromSeconds(50.0);
  REQUIRE(parseNav350PoseReply(Span<const std::uint8_t>(kNavReply, sizeof kNavReply), Nav350Config{}, at, r) ==
          Status::Ok);
  CHECK(r.version == 1U);
  CHECK(r.errorCode == 0U);
  CHECK(r.wait == 1U);
  CHECK(r.mask == 2U);
  REQUIRE(r.poseValid);
  AGV_CHECK_NEAR(r.pose.x, 12.345, 1e-12);
  AGV_CHECK_NEAR(r.pose.y, -6.789, 1e-12);
  AGV_CHECK_NEAR(r.pose.theta, -agv::kPi<double> / 2.0, 1e-12);  // 270 deg into (-pi, pi]
  REQUIRE(r.poseDetailsValid);
  CHECK(r.poseTimestampMs == 1000000U);
  AGV_CHECK_NEAR(r.meanDeviation, 0.015, 1e-12);
  CHECK(r.navigationMode == 4U);
  CHECK(r.usedReflectors == 3U);

  REQUIRE(r.landmarksValid);
  CHECK(r.landmarkFilter == 1U);
  CHECK(r.reflectorCount == 2U);
  REQUIRE(r.reflectors.size() == 2U);
  const Nav350Reflector& a = r.reflectors[0];
  CHECK(a.hasCartesian);
  AGV_CHECK_NEAR(a.x, 5.0, 1e-12);
  AGV_CHECK_NEAR(a.y, -2.0, 1e-12);
  CHECK(a.hasPolar);
  AGV_CHECK_NEAR(a.range, 6.0, 1e-12);
  AGV_CHECK_NEAR(a.bearing, agv::deg2rad(54.0), 1e-12);
  CHECK(a.hasDetails);
  CHECK(a.localId == 7U);
  CHECK(a.globalId == 42U);
  CHECK(a.type == 1U);
  CHECK(a.subType == 2U);
  CHECK(a.quality == 100U);
  CHECK(a.timestampMs == 999992U);
  AGV_CHECK_NEAR(a.size, 0.080, 1e-12);
  CHECK(a.hitCount == 12U);
  CHECK(a.meanEcho == 200U);
  CHECK(a.startIndex == 300U);
  CHECK(a.endIndex == 310U);
  const Nav350Reflector& b = r.reflectors[1];
  CHECK_FALSE(b.hasCartesian);
  CHECK(b.hasPolar);
  CHECK_FALSE(b.hasDetails);
  AGV_CHECK_NEAR(b.range, 2.5, 1e-12);
  AGV_CHECK_NEAR(b.bearing, 0.0, 1e-12);  // 360 deg

  REQUIRE(r.scanValid);
  CHECK(r.scanTimestampMs == 999960U);
  REQUIRE(r.scan.size() == 3U);
  AGV_CHECK_NEAR(r.scan.angleMin, agv::deg2rad(-45.0), 1e-6);
  AGV_CHECK_NEAR(r.scan.angleIncrement, agv::deg2rad(0.25), 1e-7);
  AGV_CHECK_NEAR(r.scan.ranges[0], 3.0, 1e-6);
  CHECK_FALSE(r.scan.isValid(1));
  AGV_CHECK_NEAR(r.scan.ranges[2], 5.0, 1e-6);

  // Device times onto the vehicle clock: the newest instant of the reply (the pose, 1000000 ms) is
  // the reception; the reflector lies 8 ms before it, the scan 40 ms.
  CHECK(r.hasDeviceTime);
  CHECK(r.newestDeviceMs == 1000000U);
  Timestamp t;
  REQUIRE(nav350VehicleTime(r, a.timestampMs, t));
  CHECK(t == at - Duration::fromMilliseconds(8));
  REQUIRE(nav350VehicleTime(r, r.scanTimestampMs, t));
  CHECK(t == at - Duration::fromMilliseconds(40));
  CHECK_FALSE(nav350VehicleTime(r, 1000001U, t));  // after the newest instant
}

TEST_CASE("NAV350 reply: every cut is Truncated, an error reply may stop after its header", "[drivers][laser][mcu]") {
  static Nav350PoseReply r;
  for (std::size_t len = 17; len < sizeof kNavReply; ++len) {
    const Status s = parseNav350PoseReply(Span<const std::uint8_t>(kNavReply, len), Nav350Config{}, Timestamp{}, r);
    CHECK(s == Status::Truncated);
    CHECK_FALSE(r.poseValid);
    CHECK(r.reflectors.size() == 0U);
  }
  static std::uint8_t errorReply[22];
  std::memcpy(errorReply, kNavReply, 22);
  errorReply[19] = 4;  // no position
  REQUIRE(parseNav350PoseReply(Span<const std::uint8_t>(errorReply, 22), Nav350Config{}, Timestamp{}, r) == Status::Ok);
  CHECK(r.errorCode == 4U);
  CHECK_FALSE(r.poseValid);
}

TEST_CASE("PLC register map: word orders of 1.0f and a status block with known registers", "[drivers][modbus][mcu]") {
  using namespace agv::drivers::plc;
  std::uint16_t w[2];
  packFloat(1.0F, WordOrder::ABCD, w);  // 1.0f = 3F 80 00 00
  CHECK((w[0] == 0x3F80U && w[1] == 0x0000U));
  packFloat(1.0F, WordOrder::CDAB, w);
  CHECK((w[0] == 0x0000U && w[1] == 0x3F80U));
  packFloat(1.0F, WordOrder::BADC, w);
  CHECK((w[0] == 0x803FU && w[1] == 0x0000U));
  packFloat(1.0F, WordOrder::DCBA, w);
  CHECK((w[0] == 0x0000U && w[1] == 0x803FU));

  PlcRegisterMap map;  // ABCD
  PlcStatus s;
  s.heartbeat = 4242;
  s.mode = agv::hal::NavMode::Calibrating;
  s.health = 5;
  s.lastStatus = Status::Rejected;
  s.pose = agv::Pose2d(12.5, -3.25, 1.5);  // 41480000, C0500000, 3FC00000
  s.matchedLandmarks = 7;
  s.visibleReflectors = 9;
  s.reflectorsFused = 6;
  s.cornersRejected = 11;
  s.routine.state = 3;
  s.routine.phase = 2;
  s.routine.segment = 5;
  s.routine.total = 24;
  s.routine.lastRefusal = Status::OutOfRange;
  s.routine.driveFault = 0x7305;
  static std::uint16_t table[PlcRegisterMap::kRegisterCount];
  for (auto& v : table) {
    v = 0xAAAA;
  }
  REQUIRE(map.encodeStatus(s, Span<std::uint16_t>(table)) == Status::Ok);
  CHECK(table[0] == 4242U);
  CHECK(table[1] == 2U);
  CHECK(table[2] == 5U);
  CHECK(table[3] == static_cast<std::uint16_t>(Status::Rejected));
  CHECK((table[4] == 0x4148U && table[5] == 0x0000U));
  CHECK((table[6] == 0xC050U && table[7] == 0x0000U));
  CHECK((table[8] == 0x3FC0U && table[9] == 0x0000U));
  CHECK(table[24] == 7U);
  CHECK(table[25] == 9U);
  CHECK(table[40] == 6U);
  CHECK(table[43] == 11U);
  CHECK(table[44] == 3U);   // routine state: driving
  CHECK(table[45] == 2U);   // phase: backward left
  CHECK(table[46] == 5U);   // segment 5
  CHECK(table[47] == 24U);  // of 24
  CHECK(table[48] == static_cast<std::uint16_t>(Status::OutOfRange));
  CHECK(table[49] == 0x7305U);                            // the drive's fault code
  CHECK(table[PlcRegisterMap::kStatusCount] == 0xAAAAU);  // nothing past the status block

  // A Localize command block as a PLC writes it: code 1, sequence 7, x 12.5, y -3.25, theta 1.5, heartbeat 99.
  const std::uint16_t block[9] = {1, 7, 0x4148, 0x0000, 0xC050, 0x0000, 0x3FC0, 0x0000, 99};
  const auto c = map.decodeCommandBlock(block);
  REQUIRE(c.ok());
  CHECK(c.value().code == PlcCommandCode::Localize);
  CHECK(c.value().sequence == 7U);
  AGV_CHECK_NEAR(c.value().pose.x, 12.5, 1e-9);
  AGV_CHECK_NEAR(c.value().pose.y, -3.25, 1e-9);
  AGV_CHECK_NEAR(c.value().pose.theta, 1.5, 1e-7);
  CHECK(c.value().plcHeartbeat == 99U);
}
