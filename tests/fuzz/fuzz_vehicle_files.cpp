// libFuzzer target fuzz_vehicle_files: the landmark map and calibration file parsers (core text
// formats, versions 1 and 2) on arbitrary text. Invariants: no crash or sanitizer report; all or
// nothing (a refused map leaves the map as it was, a refused calibration leaves the output
// untouched); a refusal names a line within the text (or 0); a version-2 map that loads (without
// comments) is refused when cut by its last character that is not a blank; what loads is written
// back and loads again, as version 2, to as many landmarks.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <new>

#include "agv/calib/calibration_file.hpp"
#include "agv/localization/landmark_map.hpp"
#include "agv/localization/landmark_map_io.hpp"
#include "fuzz_support.hpp"

using agv::fuzz::check;

namespace {

agv::LandmarkMap& freshMap(agv::LandmarkMap& storage) {
  storage.~LandmarkMap();
  new (&storage) agv::LandmarkMap(agv::LandmarkMapParams{});
  return storage;
}

std::size_t lineCount(const char* text, std::size_t size) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < size; ++i)
    n += text[i] == '\n' ? 1U : 0U;
  return n + (size > 0U && text[size - 1U] != '\n' ? 1U : 0U);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static agv::LandmarkMap map;
  static agv::LandmarkMap copy;
  static char written[1 << 20];
  const char* text = reinterpret_cast<const char*>(data);
  const std::size_t lines = lineCount(text, size);

  // Landmark map: into a map holding one landmark already (id 7).
  freshMap(map);
  check(map.addSurveyed(agv::LandmarkKind::Reflector, 1.0, 2.0, 0.01, 7U).ok());
  agv::LandmarkMapParseReport rep;
  const agv::Status s = agv::parseLandmarkMap(agv::Span<const char>(text, size), map, &rep);
  check(rep.errorLine <= lines);
  if (s != agv::Status::Ok) {
    check(map.size() == 1U && map.findById(7U) != agv::kNoLandmark);
    check(rep.landmarks == 0U);
  } else {
    check(rep.version == 1U || rep.version == 2U);
    check(map.size() == 1U + rep.landmarks && rep.records == rep.landmarks);
    if (rep.version == 2U && std::memchr(text, '#', size) == nullptr && std::memchr(text, '\r', size) == nullptr) {
      // Without comments: cut the last character that is not a blank or a line end (a character of
      // the `end` record): refused.
      std::size_t last = size;
      while (last > 0U && (text[last - 1U] == ' ' || text[last - 1U] == '\t' || text[last - 1U] == '\n'))
        --last;
      check(last > 0U);
      agv::LandmarkMap& other = freshMap(copy);
      check(agv::parseLandmarkMap(agv::Span<const char>(text, last - 1U), other) != agv::Status::Ok);
      check(other.size() == 0U);
    }
    const agv::Result<std::size_t> w = agv::formatLandmarkMap(map, agv::Span<char>(written, sizeof written));
    check(w.ok());
    agv::LandmarkMap& back = freshMap(copy);
    agv::LandmarkMapParseReport backRep;
    check(agv::parseLandmarkMap(agv::Span<const char>(written, w.value()), back, &backRep) == agv::Status::Ok);
    check(backRep.version == 2U && back.size() == map.size());
  }

  // Calibration file.
  agv::VehicleCalibration cal;
  cal.params.wheelbase = 7.0;
  agv::CalibrationFileReport crep;
  const agv::Status cs = agv::parseCalibrationFile(agv::Span<const char>(text, size), cal, &crep);
  check(crep.errorLine <= lines);
  if (cs != agv::Status::Ok) {
    check(cal.params.wheelbase == 7.0);
  } else {
    check(crep.version == 1U || crep.version == 2U);
    check(crep.records == 7U);
    const agv::Result<std::size_t> w = agv::formatCalibrationFile(cal, agv::Span<char>(written, sizeof written));
    check(w.ok());
    agv::VehicleCalibration back;
    check(agv::parseCalibrationFile(agv::Span<const char>(written, w.value()), back) == agv::Status::Ok);
  }
  return 0;
}
