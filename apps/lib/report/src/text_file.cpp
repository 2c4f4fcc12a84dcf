#include "agv/report/text_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

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
  // Opened without blocking (a FIFO swapped in after the stat would block an open for reading),
  // then checked again on the descriptor: what is read is the regular file that was checked.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    error = "cannot read " + path + ": " + std::strerror(errno);
    return false;
  }
  struct stat opened {};
  if (::fstat(fd, &opened) != 0 || !S_ISREG(opened.st_mode) || opened.st_ino != st.st_ino ||
      opened.st_dev != st.st_dev) {
    ::close(fd);
    error = "cannot read " + path + ": replaced while opened (not the regular file checked)";
    return false;
  }
  // Bounded even if the file grows meanwhile: one byte more than allowed tells it did.
  out.assign(static_cast<std::size_t>(opened.st_size) + 1U, '\0');
  std::size_t got = 0;
  bool failed = false;
  while (got < out.size()) {
    const ssize_t n = ::read(fd, out.data() + got, out.size() - got);
    if (n < 0 && errno == EINTR) {
      continue;
    }
    if (n <= 0) {
      failed = n < 0;
      break;
    }
    got += static_cast<std::size_t>(n);
  }
  ::close(fd);
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
