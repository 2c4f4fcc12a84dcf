#include "vcan_peer.hpp"

#include <net/if.h>
#include <spawn.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <ctime>
#include <vector>

extern char** environ;

namespace agv::test {

namespace {
std::string envOr(const char* name, const char* fallback) {
  const char* v = std::getenv(name);
  return (v != nullptr && v[0] != '\0') ? std::string(v) : std::string(fallback);
}
}  // namespace

std::string vcanInterface() {
  return envOr("AGV_VCAN_IF", "vcan0");
}
std::string vcanSpareInterface() {
  return envOr("AGV_VCAN_IF2", "vcan1");
}

int runPeer(std::initializer_list<std::string> args) {
  std::vector<std::string> storage(args);
  if (storage.empty())
    return -1;
  std::vector<char*> argv;
  for (std::string& a : storage)
    argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  if (posix_spawnp(&pid, argv[0], nullptr, nullptr, argv.data(), environ) != 0)
    return -1;
  int status = 0;
  if (waitpid(pid, &status, 0) != pid)
    return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

int cansend(const std::string& interface, const std::string& frame) {
  return runPeer({envOr("AGV_CANSEND", "cansend"), interface, frame});
}

bool setLinkUp(const std::string& interface, bool up) {
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0)
    return false;
  ifreq ifr{};
  std::strncpy(ifr.ifr_name, interface.c_str(), IFNAMSIZ - 1);
  bool ok = ::ioctl(fd, SIOCGIFFLAGS, &ifr) == 0;
  if (ok) {
    ifr.ifr_flags = static_cast<short>(up ? (ifr.ifr_flags | IFF_UP) : (ifr.ifr_flags & ~IFF_UP));
    ok = ::ioctl(fd, SIOCSIFFLAGS, &ifr) == 0;
  }
  ::close(fd);
  return ok;
}

Timestamp realtimeNow() {
  timespec t{};
  clock_gettime(CLOCK_REALTIME, &t);
  return Timestamp::fromNanoseconds(static_cast<std::int64_t>(t.tv_sec) * 1000000000LL + t.tv_nsec);
}

}  // namespace agv::test
