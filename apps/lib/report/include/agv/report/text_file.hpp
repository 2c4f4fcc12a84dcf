#pragma once
/// @file text_file.hpp
/// Reading and writing a whole text file with an error that says what went wrong.

#include <cstddef>
#include <string>
#include <string_view>

namespace agv::report {

/// Largest file `readTextFile` reads by default (a configuration, calibration or map file).
inline constexpr std::size_t kMaxTextFileBytes = 16U * 1024U * 1024U;

/// Reads the whole regular file `path` into `out`, at most `maxBytes`. False with `error` naming the
/// file and the reason, without blocking and without reading a byte of anything but a regular file:
/// missing or unreadable, a directory, a device, FIFO or socket (/dev/zero, a pipe), or larger
/// than `maxBytes`.
bool readTextFile(const std::string& path, std::string& out, std::string& error,
                  std::size_t maxBytes = kMaxTextFileBytes);

/// Writes `text` to `path` (created or truncated). False with `error` ("cannot write PATH: reason")
/// when the file cannot be opened or written completely.
bool writeTextFile(const std::string& path, std::string_view text, std::string& error);

}  // namespace agv::report
