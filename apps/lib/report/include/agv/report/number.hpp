#pragma once
/// @file number.hpp
/// The one number parser of the text formats read in apps/ (vehicle configuration, CARMEN logs,
/// keypoint tables): std::from_chars underneath, so it does not depend on the C locale (a German
/// locale does not turn "0.5" into 0), and decimal only: "010" is ten, never octal eight; "0x1p3"
/// and "1e" are not numbers. The whole token must be the number: no blanks, no trailing text.

#include <cstdint>
#include <string_view>

namespace agv::report {

/// Why a token is not the number asked for.
enum class NumberError : std::uint8_t {
  None,        ///< parsed
  Empty,       ///< no characters
  Malformed,   ///< not a decimal number, or characters after it
  OutOfRange,  ///< beyond the type's range (or, for reals, below the smallest normal magnitude)
  NotFinite,   ///< inf or nan where the format wants a finite number
};

/// Short English reason ("not a number", ...).
const char* describe(NumberError e) noexcept;

/// Whether a real may be infinite or not a number ("inf", "nan", any case).
enum class NonFinite : std::uint8_t { Refuse, Allow };

/// Decimal real: optional sign (+ or -), digits with an optional fraction (".5" and "5." are
/// numbers), optional exponent (e or E, optional sign, digits). `out` is unchanged on failure.
NumberError parseReal(std::string_view text, double& out, NonFinite nonFinite = NonFinite::Refuse) noexcept;

/// Decimal integer with an optional sign, leading zeros allowed ("010" is 10).
NumberError parseInteger(std::string_view text, std::int64_t& out) noexcept;

/// Like `parseInteger`, and also "0x" / "0X" followed by hexadecimal digits (CAN COB-IDs are
/// written that way); a leading zero alone still means decimal.
NumberError parseIntegerOrHex(std::string_view text, std::int64_t& out) noexcept;

/// `parseReal` / `parseInteger` as a plain yes or no.
inline bool toReal(std::string_view text, double& out, NonFinite nonFinite = NonFinite::Refuse) noexcept {
  return parseReal(text, out, nonFinite) == NumberError::None;
}
inline bool toInteger(std::string_view text, std::int64_t& out) noexcept {
  return parseInteger(text, out) == NumberError::None;
}

}  // namespace agv::report
