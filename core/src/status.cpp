#include "agv/core/status.hpp"

namespace agv {

const char* toString(Status status) noexcept {
  switch (status) {
    case Status::Ok:
      return "ok";
    case Status::InvalidArgument:
      return "invalid argument";
    case Status::NonFiniteInput:
      return "non-finite input";
    case Status::EmptyInput:
      return "empty input";
    case Status::CapacityExceeded:
      return "capacity exceeded";
    case Status::NotEnoughData:
      return "not enough data";
    case Status::Unobservable:
      return "unobservable";
    case Status::IllConditioned:
      return "ill-conditioned";
    case Status::NotConverged:
      return "not converged";
    case Status::NotFound:
      return "not found";
    case Status::OutOfRange:
      return "out of range";
    case Status::Timeout:
      return "timeout";
    case Status::Truncated:
      return "truncated";
    case Status::Malformed:
      return "malformed";
    case Status::Unsupported:
      return "unsupported";
    case Status::NotInitialized:
      return "not initialized";
    case Status::Rejected:
      return "rejected";
    case Status::Lost:
      return "lost";
    case Status::DeviceFault:
      return "device fault";
  }
  return "unknown status";
}

}  // namespace agv
