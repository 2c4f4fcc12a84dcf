#include "agv/report/text_file.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace agv::report {

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
