#pragma once
/// @file text_file.hpp
/// Writing a whole text file with an error that says what went wrong.

#include <string>
#include <string_view>

namespace agv::report {

/// Writes `text` to `path` (created or truncated). False with `error` ("cannot write PATH: reason")
/// when the file cannot be opened or written completely.
bool writeTextFile(const std::string& path, std::string_view text, std::string& error);

}  // namespace agv::report
