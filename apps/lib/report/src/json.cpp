#include "agv/report/json.hpp"

#include <charconv>
#include <cmath>

#include "agv/report/text_file.hpp"

namespace agv::report {

std::string dumpJson(const Json& doc) {
  return doc.dump(2, ' ', false, Json::error_handler_t::replace) + "\n";
}

bool writeJsonFile(const std::string& path, const Json& doc, std::string& error) {
  return writeTextFile(path, dumpJson(doc), error);
}

double shortestDouble(float v) noexcept {
  if (!std::isfinite(v)) {
    return static_cast<double>(v);
  }
  char buf[64];
  const std::to_chars_result w = std::to_chars(buf, buf + sizeof buf, v);
  double d = static_cast<double>(v);
  if (w.ec == std::errc()) {
    (void)std::from_chars(buf, w.ptr, d);
  }
  return d;
}

}  // namespace agv::report
