#include "env/status.h"

namespace fleetgw {

std::string_view to_string(StatusCode code) {
  switch (code) {
    case StatusCode::kOk:
      return "ok";
    case StatusCode::kFull:
      return "full";
    case StatusCode::kIo:
      return "io";
    case StatusCode::kInvalid:
      return "invalid";
    case StatusCode::kUnavailable:
      return "unavailable";
    case StatusCode::kRefused:
      return "refused";
    case StatusCode::kOther:
      return "other";
  }
  return "other";
}

}  // namespace fleetgw
