// StatusStage: the retained fleetgw.v1.Status of `fleetgw run`, built as a value and handed to
// the uplink by the pipeline's route (the uplink only publishes what it is given: uplink.h).
//
// Contract:
//  * run() builds one status (the `build` function: runtime/status_provider.h's
//    make_status_message over the live components) when it was asked to (want(): the uplink
//    connected or its refusals changed, or the bus state changed; the pipeline's uplink route
//    asks) or when the refresh interval passed since the last one ([mqtt] status_interval_ms;
//    zero: never refreshed on a timer). The status waits in `status` until the route moves it.
//  * It never calls another stage: what the status shows is read by `build`, which the
//    pipeline owns, and the route hands the result over.
#pragma once

#include <chrono>
#include <functional>
#include <optional>

#include "fleetgw/v1/status.pb.h"
#include "gateway/runtime/engine.h"
#include "gateway/runtime/stage.h"

namespace fleetgw::runtime {

class StatusStage final : public Stage {
 public:
  using Build = std::function<fleetgw::v1::Status()>;
  StatusStage(Build build, std::chrono::milliseconds refresh, const Engine& engine)
      : build_(std::move(build)), refresh_(refresh), engine_(engine) {}
  std::string_view name() const override { return "status"; }
  std::optional<EngineTime> next_deadline() const override;
  StageRun run(EngineTime now) override;

  // Input: a fresh status is needed now.
  void want() { wanted_ = true; }
  // Output: the status built, for the uplink.
  std::optional<fleetgw::v1::Status> status;
  std::uint64_t builds() const { return builds_; }

 private:
  Build build_;
  std::chrono::milliseconds refresh_;
  const Engine& engine_;
  bool wanted_ = false;
  std::optional<EngineTime> refresh_at_;  // none before the first status, or without refresh
  std::uint64_t builds_ = 0;
};

}  // namespace fleetgw::runtime
