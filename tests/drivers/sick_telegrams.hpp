#pragma once
// Test-side builders of SICK telegrams from the documented field layouts (docs/drivers.md),
// written independently of the decoders under test.

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace agv::test {

inline std::uint32_t floatBits(float f) {
  std::uint32_t u = 0;
  std::memcpy(&u, &f, sizeof u);
  return u;
}

inline std::string hexField(std::uint32_t v) {
  char b[16];
  std::snprintf(b, sizeof b, "%X", v);
  return b;
}

/// One channel of an LMDscandata telegram.
struct ColaChannel {
  std::string name = "DIST1";
  float scale = 1.0F;
  float offset = 0.0F;
  std::int32_t startAngle = -450000;  // 1/10000 deg
  std::uint16_t step = 5000;          // 1/10000 deg
  std::vector<std::uint32_t> values;
};

/// Fields of an LMDscandata telegram (defaults: an LMS1xx at 50 Hz).
struct ColaScanFields {
  std::string type = "sSN";
  std::uint32_t serial = 0x89A27F;
  std::uint32_t telegramCounter = 0x343;
  std::uint32_t scanCounter = 0x347;
  std::uint32_t timeSinceStartup = 0x27477BA9;
  std::uint32_t timeOfTransmission = 0x27477BA9 + 3000;
  std::uint32_t scanFrequency = 5000;  // 1/100 Hz
  std::vector<std::pair<std::uint32_t, std::uint32_t>> encoders;
  std::vector<ColaChannel> channels16;
  std::vector<ColaChannel> channels8;
};

/// The text between STX and ETX.
inline std::string buildColaScan(const ColaScanFields& f) {
  std::string s = f.type + " LMDscandata 1 1 " + hexField(f.serial) + " 0 0 " + hexField(f.telegramCounter) + " " +
                  hexField(f.scanCounter) + " " + hexField(f.timeSinceStartup) + " " + hexField(f.timeOfTransmission) +
                  " 0 0 7 0 0 " + hexField(f.scanFrequency) + " 168 " +
                  hexField(static_cast<std::uint32_t>(f.encoders.size()));
  for (const auto& e : f.encoders) {
    s += " " + hexField(e.first) + " " + hexField(e.second);
  }
  for (const auto* list : {&f.channels16, &f.channels8}) {
    s += " " + hexField(static_cast<std::uint32_t>(list->size()));
    for (const ColaChannel& c : *list) {
      s += " " + c.name + " " + hexField(floatBits(c.scale)) + " " + hexField(floatBits(c.offset)) + " " +
           hexField(static_cast<std::uint32_t>(c.startAngle)) + " " + hexField(c.step) + " " +
           hexField(static_cast<std::uint32_t>(c.values.size()));
      for (std::uint32_t v : c.values) {
        s += " " + hexField(v);
      }
    }
  }
  s += " 0 0 0 0 0";  // position, name, comment, time, event: absent
  return s;
}

inline std::vector<std::uint8_t> stxEtx(const std::string& body) {
  std::vector<std::uint8_t> v;
  v.push_back(0x02);
  v.insert(v.end(), body.begin(), body.end());
  v.push_back(0x03);
  return v;
}

/// Big-endian writer.
struct BeWriter {
  std::vector<std::uint8_t> b;
  void u8(std::uint32_t v) { b.push_back(static_cast<std::uint8_t>(v)); }
  void u16(std::uint32_t v) {
    u8(v >> 8);
    u8(v);
  }
  void u32(std::uint32_t v) {
    u16(v >> 16);
    u16(v & 0xFFFF);
  }
  void i32(std::int32_t v) { u32(static_cast<std::uint32_t>(v)); }
  void f32(float f) { u32(floatBits(f)); }
  void text(const std::string& s) { b.insert(b.end(), s.begin(), s.end()); }
};

inline std::vector<std::uint8_t> colaB(const std::vector<std::uint8_t>& payload) {
  BeWriter w;
  w.u32(0x02020202);
  w.u32(static_cast<std::uint32_t>(payload.size()));
  w.b.insert(w.b.end(), payload.begin(), payload.end());
  std::uint8_t x = 0;
  for (std::uint8_t c : payload) {
    x ^= c;
  }
  w.u8(x);
  return w.b;
}

/// A reflector of a NAV350 reply in device units.
struct NavReflectorFields {
  std::int32_t xMm = 0, yMm = 0;
  std::uint32_t distMm = 0, phiMdeg = 0;
  std::uint16_t localId = 0, globalId = 0, quality = 0, sizeMm = 80;
  std::uint32_t timestampMs = 123450;  // device clock
};

/// NAV350 `sAN mNPOSGetData` payload in device units (mm, mdeg).
struct NavReplyFields {
  std::uint8_t errorCode = 0;
  bool pose = true;
  std::int32_t xMm = 0, yMm = 0;
  std::uint32_t phiMdeg = 0;
  bool poseDetails = true;
  std::uint32_t poseTimestampMs = 123456;  // device clock
  std::int32_t meanDevMm = 12;
  std::uint8_t usedReflectors = 0;
  bool landmarks = true;
  std::vector<NavReflectorFields> reflectors;
  bool scan = false;
  bool angleChannel = false;  // also send ANGL1 before DIST1
  float scale = 1.0F;         // DIST1 scale factor
  float offset = 0.0F;        // DIST1 offset [mm]
  std::int32_t startMdeg = 0;
  std::uint16_t stepMdeg = 250;
  std::uint32_t scanTimestampMs = 123400;  // device clock
  std::vector<std::uint32_t> distMm;
  bool remission = false;
};

inline std::vector<std::uint8_t> buildNavReply(const NavReplyFields& f) {
  BeWriter w;
  w.text("sAN mNPOSGetData ");
  w.u16(1);           // version
  w.u8(f.errorCode);  // error code
  w.u8(1);            // wait
  w.u8(2);            // mask
  w.u16(f.pose ? 1 : 0);
  if (f.pose) {
    w.i32(f.xMm);
    w.i32(f.yMm);
    w.u32(f.phiMdeg);
    w.u16(f.poseDetails ? 1 : 0);
    if (f.poseDetails) {
      w.u8(0);  // output mode
      w.u32(f.poseTimestampMs);
      w.i32(f.meanDevMm);
      w.u8(4);   // navigation mode
      w.u32(0);  // info state
      w.u8(f.usedReflectors);
    }
  }
  w.u16(f.landmarks ? 1 : 0);
  if (f.landmarks) {
    w.u8(1);  // filter
    w.u16(static_cast<std::uint32_t>(f.reflectors.size()));
    for (const auto& r : f.reflectors) {
      w.u16(1);
      w.i32(r.xMm);
      w.i32(r.yMm);
      w.u16(1);
      w.u32(r.distMm);
      w.u32(r.phiMdeg);
      w.u16(1);
      w.u16(r.localId);
      w.u16(r.globalId);
      w.u8(1);   // type
      w.u16(2);  // subtype
      w.u16(r.quality);
      w.u32(r.timestampMs);
      w.u16(r.sizeMm);
      w.u16(7);    // hit count
      w.u16(200);  // mean echo
      w.u16(10);   // start index
      w.u16(14);   // end index
    }
  }
  const std::uint16_t channels = static_cast<std::uint16_t>(f.scan ? (f.angleChannel ? 2 : 1) : 0);
  w.u16(channels);
  auto head = [&](const char* name, std::size_t n) {
    w.text(name);
    w.f32(f.scale);
    w.f32(f.offset);
    w.i32(f.startMdeg);
    w.u16(f.stepMdeg);
    w.u32(f.scanTimestampMs);
    w.u16(static_cast<std::uint32_t>(n));
  };
  if (f.scan && f.angleChannel) {
    head("ANGL1", f.distMm.size());
    for (std::size_t i = 0; i < f.distMm.size(); ++i) {
      w.u32(static_cast<std::uint32_t>(static_cast<std::int64_t>(f.startMdeg) * 10 +
                                       static_cast<std::int64_t>(i) * f.stepMdeg * 10));
    }
  }
  if (f.scan) {
    head("DIST1", f.distMm.size());
    for (std::uint32_t d : f.distMm) {
      w.u32(d);
    }
  }
  w.u16(f.remission ? 1 : 0);
  if (f.remission) {
    head("RSSI1", f.distMm.size());
    for (std::size_t i = 0; i < f.distMm.size(); ++i) {
      w.u16(static_cast<std::uint32_t>(100 + i % 50));
    }
  }
  return w.b;
}

/// A complete `sSN LMDscandata` telegram (STX .. ETX) with scan counter `scanCounter` and one DIST1
/// channel from -45 deg in 0.5 deg steps whose `count` ranges are `baseMm + i` millimetres
/// (`baseMm` for every beam when `increasing` is false).
inline std::vector<std::uint8_t> colaScanTelegram(std::uint32_t scanCounter, std::uint32_t baseMm,
                                                  std::uint32_t count = 10, bool increasing = true) {
  ColaScanFields f;
  f.scanCounter = scanCounter;
  ColaChannel c;
  c.startAngle = -450000;
  c.step = 5000;
  for (std::uint32_t i = 0; i < count; ++i) {
    c.values.push_back(increasing ? baseMm + i : baseMm);
  }
  f.channels16.push_back(c);
  return stxEtx(buildColaScan(f));
}

}  // namespace agv::test
