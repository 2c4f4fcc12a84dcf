#pragma once
/// @file json.hpp
/// The JSON documents the programs write (measurement summaries read by dashboards): built as
/// nlohmann-json values, keys kept in the order they were added, written in one way.

#include <nlohmann/json.hpp>
#include <string>

namespace agv::report {

/// A JSON value whose objects keep their keys in insertion order (the documented field order).
using Json = nlohmann::ordered_json;

/// The document as text: two-space indentation, a final newline; invalid UTF-8 in strings (a
/// file name, say) is replaced by U+FFFD instead of failing.
std::string dumpJson(const Json& doc);

/// Writes `dumpJson(doc)` to `path`; false with `error` ("cannot write PATH: reason").
bool writeJsonFile(const std::string& path, const Json& doc, std::string& error);

/// A float parameter as the double that prints as the float's shortest decimal form (0.2F -> 0.2,
/// not 0.20000000298023224): what the user typed, not the binary widening.
double shortestDouble(float v) noexcept;

}  // namespace agv::report
