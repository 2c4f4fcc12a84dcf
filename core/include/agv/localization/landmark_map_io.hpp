#pragma once
/// @file landmark_map_io.hpp
/// Text format of surveyed landmark maps, parsed from and written to caller-owned buffers (file
/// access stays outside the core).
///
/// Format (`agvnav-landmarks` version 2), one record per line, fields separated by spaces or tabs,
/// LF or CRLF line ends, `#` starts a comment that runs to the end of the line, blank lines ignored:
///
///     agvnav-landmarks 2
///     # kind      id   x [m]        y [m]        sigma [m]
///     reflector   1    12.345000    -3.210000    0.002000
///     corner      2    4.000000     7.500000     0.010000
///     end 2
///
/// - The first record is the header `agvnav-landmarks 2`.
/// - kind: `reflector` or `corner`; id: integer 1..4294967295, unique in the file and in the map;
///   x, y: world coordinates, |v| <= 1e6; sigma: isotropic position standard deviation, 0..1e6.
/// - The last record is `end <count>`, count = the number of landmark records (decimal). Nothing
///   but blank lines and comments may follow it. A file that ends before it (cut short by a copy,
///   a full disk, a power loss) is refused as `Truncated`, naming the line where the text ends; a
///   count that differs from the records read is refused (`Malformed`, or `Truncated` when the `end`
///   line itself is cut). The final LF may be missing (the only cut that loses nothing).
/// - Numbers are decimal: optional sign, digits, optional fraction, optional exponent (`1.5e-3`).
/// Every landmark read is added as surveyed (it never moves or dies).
///
/// Version 1 (header `agvnav-landmarks 1`, no `end` record) is still read, with the same records:
/// `LandmarkMapParseReport::version` tells the caller, who should warn that a cut in such a file
/// cannot be detected (docs/localization.md, "Surveyed map text format"). `formatLandmarkMap`
/// writes version 2 only. A larger version is refused as `Unsupported`.

#include <cstddef>
#include <cstdint>

#include "agv/core/result.hpp"
#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/localization/landmark_map.hpp"

namespace agv {

/// The format version `formatLandmarkMap` writes (and the largest `parseLandmarkMap` reads).
inline constexpr std::uint32_t kLandmarkMapFormatVersion = 2;

/// Outcome details of `parseLandmarkMap`.
struct LandmarkMapParseReport {
  std::size_t landmarks = 0;     ///< landmarks added (0 on failure)
  std::size_t errorLine = 0;     ///< 1-based line of the first error (0 when none)
  std::uint32_t version = 0;     ///< format version of the header (0: none read)
  std::size_t records = 0;       ///< landmark records read (up to the error)
  const char* detail = nullptr;  ///< what is wrong, when more than the status says (static text)
};

/// Parses `text` and adds its landmarks to `map` as surveyed landmarks. All or nothing: on any
/// error the map is left as it was. Errors: `Malformed` (bad header, kind, number or field count,
/// `end` count; see `report->errorLine`), `Truncated` (version 2 without its `end` line, or cut
/// inside its last line), `OutOfRange` (coordinate beyond 1e6 m, sigma outside 0..1e6 m, id 0),
/// `InvalidArgument` (duplicate id), `CapacityExceeded` (the map cannot take them all; counted
/// in the map's refusedFull), `EmptyInput` (no header), `Unsupported` (a newer version).
Status parseLandmarkMap(Span<const char> text, LandmarkMap& map, LandmarkMapParseReport* report = nullptr) noexcept;

/// Writes the map's landmarks (all, or only the surveyed ones) in the format above (version 2, with
/// its `end` line) into `out`.
/// Coordinates and sigma are written with 6 decimals (1 um). Returns the number of characters
/// written (no terminating NUL), or `Truncated` when `out` is too small (its content is then
/// unspecified). Landmarks are written in slot order.
Result<std::size_t> formatLandmarkMap(const LandmarkMap& map, Span<char> out, bool surveyedOnly = false) noexcept;

}  // namespace agv
