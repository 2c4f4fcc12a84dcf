// The one number parser of the apps' text formats: decimal only, whole token, locale-free.
#include <clocale>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

#include "agv/report/number.hpp"
#include "agv_test.hpp"

using agv::report::NonFinite;
using agv::report::NumberError;
using agv::report::parseInteger;
using agv::report::parseIntegerOrHex;
using agv::report::parseReal;

namespace {

NumberError real(const char* text, double& v, NonFinite nf = NonFinite::Refuse) {
  return parseReal(text, v, nf);
}

}  // namespace

TEST_CASE("parseReal: decimal numbers with sign, fraction and exponent", "[report]") {
  double v = 0.0;
  CHECK(real("0", v) == NumberError::None);
  CHECK(v == 0.0);
  CHECK(real("010", v) == NumberError::None);  // leading zeros: decimal, not octal
  CHECK(v == 10.0);
  CHECK(real("0502", v) == NumberError::None);
  CHECK(v == 502.0);
  CHECK(real("-1.5", v) == NumberError::None);
  CHECK(v == -1.5);
  CHECK(real("+2.25", v) == NumberError::None);
  CHECK(v == 2.25);
  CHECK(real(".5", v) == NumberError::None);
  CHECK(v == 0.5);
  CHECK(real("5.", v) == NumberError::None);
  CHECK(v == 5.0);
  CHECK(real("1e3", v) == NumberError::None);
  CHECK(v == 1000.0);
  CHECK(real("1.5E-3", v) == NumberError::None);
  CHECK(v == 0.0015);
  CHECK(real("-2e+2", v) == NumberError::None);
  CHECK(v == -200.0);
  CHECK(real("0.1", v) == NumberError::None);
  CHECK(v == 0.1);  // correctly rounded, the same double as the literal
  CHECK(real("-0", v) == NumberError::None);
  CHECK(std::signbit(v));
}

TEST_CASE("parseReal: garbage, trailing characters and hexadecimal are refused", "[report]") {
  double v = 42.0;
  CHECK(real("", v) == NumberError::Empty);
  for (const char* bad :
       {"abc", "1.5m", "1,5", " 1",   "1 ",    "1e",    "1e+",   "e5",     ".",        "-",    "+",
        "--1", "+-1",  "-+1", "0x10", "0x1p3", "1.2.3", "1_000", "nan(1)", "infinite", "1e5x", "\t1"}) {
    INFO(bad);
    CHECK(real(bad, v) == NumberError::Malformed);
  }
  CHECK(v == 42.0);  // unchanged on failure
}

TEST_CASE("parseReal: out of range and non-finite values", "[report]") {
  double v = 42.0;
  CHECK(real("1e400", v) == NumberError::OutOfRange);
  CHECK(real("-1e400", v) == NumberError::OutOfRange);
  CHECK(real("1e-400", v) == NumberError::OutOfRange);  // underflow: not silently zero
  CHECK(v == 42.0);
  CHECK(real("1e308", v) == NumberError::None);
  for (const char* word : {"inf", "-inf", "+inf", "Infinity", "nan", "NaN", "-nan"}) {
    INFO(word);
    CHECK(real(word, v) == NumberError::NotFinite);
  }
  CHECK(v == 1e308);
  CHECK(real("inf", v, NonFinite::Allow) == NumberError::None);
  CHECK(v == std::numeric_limits<double>::infinity());
  CHECK(real("-Infinity", v, NonFinite::Allow) == NumberError::None);
  CHECK(v == -std::numeric_limits<double>::infinity());
  CHECK(real("nan", v, NonFinite::Allow) == NumberError::None);
  CHECK(std::isnan(v));
  CHECK(real("nanx", v, NonFinite::Allow) == NumberError::Malformed);
}

TEST_CASE("parseReal does not depend on the C locale", "[report]") {
  // A locale with a decimal comma, when the machine has one (strtod would stop at the '.').
  const char* old = std::setlocale(LC_NUMERIC, nullptr);
  const std::string saved = old != nullptr ? old : "C";
  const bool switched = std::setlocale(LC_NUMERIC, "de_DE.UTF-8") != nullptr;
  double v = 0.0;
  CHECK(real("0.5", v) == NumberError::None);
  CHECK(v == 0.5);
  CHECK(real("0,5", v) == NumberError::Malformed);
  std::setlocale(LC_NUMERIC, saved.c_str());
  if (!switched) {
    WARN("de_DE.UTF-8 not installed: checked in the C locale only");
  }
}

TEST_CASE("parseInteger: decimal only, leading zeros, signs, range", "[report]") {
  std::int64_t v = 0;
  CHECK(parseInteger("010", v) == NumberError::None);
  CHECK(v == 10);
  CHECK(parseInteger("0502", v) == NumberError::None);
  CHECK(v == 502);
  CHECK(parseInteger("-7", v) == NumberError::None);
  CHECK(v == -7);
  CHECK(parseInteger("+7", v) == NumberError::None);
  CHECK(v == 7);
  CHECK(parseInteger("9223372036854775807", v) == NumberError::None);
  CHECK(v == std::numeric_limits<std::int64_t>::max());
  CHECK(parseInteger("-9223372036854775808", v) == NumberError::None);
  CHECK(v == std::numeric_limits<std::int64_t>::min());
  CHECK(parseInteger("9223372036854775808", v) == NumberError::OutOfRange);
  CHECK(parseInteger("-9223372036854775809", v) == NumberError::OutOfRange);
  CHECK(parseInteger("99999999999999999999999", v) == NumberError::OutOfRange);
  CHECK(parseInteger("", v) == NumberError::Empty);
  for (const char* bad : {"0x10", "1.0", "1e3", "12a", " 1", "1 ", "-", "+-1", "--1", "inf", "nan", "0b1"}) {
    INFO(bad);
    CHECK(parseInteger(bad, v) == NumberError::Malformed);
  }
  CHECK(v == std::numeric_limits<std::int64_t>::min());  // unchanged since the last success
}

TEST_CASE("parseIntegerOrHex: 0x prefix is hexadecimal, a leading zero is not octal", "[report]") {
  std::int64_t v = 0;
  CHECK(parseIntegerOrHex("0x181", v) == NumberError::None);
  CHECK(v == 0x181);
  CHECK(parseIntegerOrHex("0X7fF", v) == NumberError::None);
  CHECK(v == 0x7FF);
  CHECK(parseIntegerOrHex("010", v) == NumberError::None);
  CHECK(v == 10);
  CHECK(parseIntegerOrHex("-0x10", v) == NumberError::None);
  CHECK(v == -16);
  for (const char* bad : {"0x", "0x-1", "0x+1", "0xg", "x10", "0x1.8", "00x10"}) {
    INFO(bad);
    CHECK(parseIntegerOrHex(bad, v) == NumberError::Malformed);
  }
  CHECK(parseIntegerOrHex("0x10000000000000000", v) == NumberError::OutOfRange);
}
