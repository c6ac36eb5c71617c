#include "gateway/runtime/status_stage.h"

namespace fleetgw::runtime {

std::optional<EngineTime> StatusStage::next_deadline() const {
  if (wanted_) return engine_.now();
  return refresh_at_;
}

StageRun StatusStage::run(EngineTime now) {
  if (!wanted_ && !(refresh_at_ && now >= *refresh_at_)) return {};
  wanted_ = false;
  status = build_();
  ++builds_;
  if (refresh_.count() > 0) {
    refresh_at_ = now + refresh_;
  } else {
    refresh_at_.reset();
  }
  return {.produced = 1, .status = {}};
}

}  // namespace fleetgw::runtime
