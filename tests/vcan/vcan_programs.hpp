#pragma once
// The programs the vcan VM's tests start (docs/vcan-testing.md): looked up in
// $AGV_VCAN_PROGRAM_DIR (default /test, where run-vcan-vm.sh puts them), run with their output in
// a pipe, echoed line by line with their name, killed and reaped by the destructor if still
// running. Used by the safety-trigger cases (test_drive_processes_vm.cpp) and the whole routine
// with agvnav-vehicle and agvnav-sim-drives --vehicle (test_calibration_modbus_vm.cpp).
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "agv/core/timestamp.hpp"
#include "agv/drivers/linux/monotonic_clock.hpp"

extern char** environ;

namespace agv::test {

inline std::string programPath(const char* name) {
  const char* dir = std::getenv("AGV_VCAN_PROGRAM_DIR");
  return std::string(dir != nullptr && dir[0] != '\0' ? dir : "/test") + "/" + name;
}

/// A program run with its stdout in a pipe; killed and reaped by the destructor if still running.
class Child {
 public:
  /// `withStderr`: the program's stderr goes into the pipe too (agvnav-vehicle logs there).
  Child(const std::string& path, const std::vector<std::string>& args, bool withStderr = false) {
    int fds[2];
    if (pipe2(fds, O_CLOEXEC) != 0) {
      return;
    }
    std::vector<std::string> storage;
    storage.push_back(path);
    storage.insert(storage.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (std::string& a : storage) {
      argv.push_back(a.data());
    }
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, fds[1], 1);
    if (withStderr) {
      posix_spawn_file_actions_adddup2(&actions, fds[1], 2);
    }
    if (posix_spawn(&pid_, path.c_str(), &actions, nullptr, argv.data(), environ) != 0) {
      pid_ = -1;
    }
    posix_spawn_file_actions_destroy(&actions);
    ::close(fds[1]);
    out_ = fds[0];
    (void)fcntl(out_, F_SETFL, O_NONBLOCK);
    name_ = path.substr(path.rfind('/') + 1);
  }
  ~Child() {
    if (running()) {
      ::kill(pid_, SIGKILL);
      int status = 0;
      (void)waitpid(pid_, &status, 0);
    }
    if (out_ >= 0) {
      ::close(out_);
    }
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  bool started() const { return pid_ > 0; }
  bool running() const { return pid_ > 0 && !reaped_; }
  void signal(int sig) const {
    if (running()) {
      ::kill(pid_, sig);
    }
  }
  /// Reads what the program wrote (echoed with its name) and reaps it when it has exited.
  void poll() {
    char buf[4096];
    for (;;) {
      const ssize_t n = ::read(out_, buf, sizeof buf);
      if (n <= 0) {
        break;
      }
      partial_.append(buf, static_cast<std::size_t>(n));
    }
    for (std::size_t eol = partial_.find('\n'); eol != std::string::npos; eol = partial_.find('\n')) {
      lines_.push_back(partial_.substr(0, eol));
      std::printf("  [%s] %s\n", name_.c_str(), lines_.back().c_str());
      partial_.erase(0, eol + 1);
    }
    if (running()) {
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        reaped_ = true;
        reapedAt_ = drivers::monotonicNow();
        exitCode_ = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
      }
    }
  }
  /// The first line `<ns> WORD rest...` after `after`: its time and the rest.
  bool find(const std::string& word, Timestamp& t, std::string* rest = nullptr, Timestamp after = Timestamp{}) const {
    for (const std::string& line : lines_) {
      const std::size_t sp = line.find(' ');
      if (sp == std::string::npos || line.compare(sp + 1, word.size(), word) != 0) {
        continue;
      }
      const Timestamp stamp = Timestamp::fromNanoseconds(std::strtoll(line.c_str(), nullptr, 10));
      if (stamp < after) {
        continue;
      }
      t = stamp;
      if (rest != nullptr) {
        const std::size_t from = sp + 1 + word.size();
        *rest = from < line.size() ? line.substr(from + 1) : std::string();
      }
      return true;
    }
    return false;
  }
  Timestamp reapedAt() const { return reapedAt_; }
  int exitCode() const { return exitCode_; }
  /// The lines read so far.
  const std::vector<std::string>& lines() const { return lines_; }
  /// True when a line read so far contains `text`.
  bool said(const std::string& text) const {
    for (const std::string& l : lines_) {
      if (l.find(text) != std::string::npos) {
        return true;
      }
    }
    return false;
  }

 private:
  pid_t pid_ = -1;
  int out_ = -1;
  std::string name_;
  std::string partial_;
  std::vector<std::string> lines_;
  bool reaped_ = false;
  Timestamp reapedAt_{};
  int exitCode_ = -1;
};

}  // namespace agv::test
