#include "agv/report/text_file.hpp"

#include <sys/stat.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>

namespace agv::report {

bool readTextFile(const std::string& path, std::string& out, std::string& error, std::size_t maxBytes) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    error = "cannot read " + path + ": " + std::strerror(errno);
    return false;
  }
  if (S_ISDIR(st.st_mode)) {
    error = "cannot read " + path + ": a directory, not a file";
    return false;
  }
  if (!S_ISREG(st.st_mode)) {
    error = "cannot read " + path + ": not a regular file (a device, FIFO or socket)";
    return false;
  }
  if (static_cast<std::uint64_t>(st.st_size) > maxBytes) {
    error = "cannot read " + path + ": " + std::to_string(st.st_size) + " bytes, more than the " +
            std::to_string(maxBytes) + " it may have";
    return false;
  }
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) {
    error = "cannot read " + path + ": " + std::strerror(errno);
    return false;
  }
  // Bounded even if the file grows meanwhile: one byte more than allowed tells it did.
  out.assign(static_cast<std::size_t>(st.st_size) + 1U, '\0');
  const std::size_t got = std::fread(out.data(), 1, out.size(), f);
  const bool failed = std::ferror(f) != 0;
  std::fclose(f);
  if (failed || got > maxBytes) {
    error = "cannot read " + path + (failed ? ": read error" : ": it grew beyond the size allowed while read");
    return false;
  }
  out.resize(got);
  return true;
}

bool writeTextFile(const std::string& path, std::string_view text, std::string& error) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) {
    error = "cannot write " + path + ": " + std::strerror(errno);
    return false;
  }
  const std::size_t written = std::fwrite(text.data(), 1, text.size(), f);
  const int writeErrno = errno;
  const bool closed = std::fclose(f) == 0;
  if (written != text.size() || !closed) {
    error = "cannot write " + path + ": " + std::strerror(written != text.size() ? writeErrno : errno);
    return false;
  }
  return true;
}

}  // namespace agv::report
